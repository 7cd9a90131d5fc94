//! Intel Open Image Denoise (the `oidn` cargo feature): its `RT` filter on
//! an HDR image with the camera's first-hit albedo and normal as auxiliary
//! images (`cleanAux`: the buffers come from exact first hits, so OIDN
//! need not denoise them). The error bar of what it returns is not its
//! business: `integrator::progressive` measures it from two independent
//! halves of the passes (docs/math.md §16.7).
//!
//! One device per process, created on first use and shared behind a lock
//! (an OIDN device is `Send` but not `Sync`; it runs its own worker
//! threads, so calls queue rather than oversubscribe the cores).

use std::sync::{Mutex, OnceLock};

use super::{GuideBuffers, Image, ImageError};

/// The process's OIDN device, or why there is none.
fn device() -> Result<&'static Mutex<oidn::Device>, ImageError> {
    static DEVICE: OnceLock<Result<Mutex<oidn::Device>, String>> = OnceLock::new();
    DEVICE
        .get_or_init(|| {
            oidn::Device::cpu()
                .map(Mutex::new)
                .map_err(|e| format!("{e:?}"))
        })
        .as_ref()
        .map_err(|e| ImageError::invalid("denoise", format!("no OIDN device: {e}")))
}

/// `rgb` (row-major, `guides`' size, linear radiance) through OIDN's `RT`
/// filter with the guides' albedo and normal. A pixel whose first hit has
/// no Lambertian part (metal, glass, an emitter, the background) keeps
/// albedo 0, as Mitsuba's `albedo` AOV has it (albedo 1 there denoised the
/// tutorials' box 10 % worse at 64 spp: 3.10 % against 2.82 %, trimmed per
/// pixel); the normal is the rays' mean shading normal.
pub fn filter(rgb: &[[f32; 3]], guides: &GuideBuffers) -> Result<Vec<[f32; 3]>, ImageError> {
    let (width, height) = (guides.width as usize, guides.height as usize);
    if rgb.len() != width * height {
        return Err(ImageError::invalid(
            "guides",
            format!("{width}×{height} guides for {} pixels", rgb.len()),
        ));
    }
    let colour: Vec<f32> = rgb.iter().flatten().copied().collect();
    let mut albedo = Vec::with_capacity(colour.len());
    let mut normal = Vec::with_capacity(colour.len());
    for g in &guides.pixels {
        albedo.extend(g.albedo.map(|a| a as f32));
        let n = g.mean_normal;
        normal.extend([n.x as f32, n.y as f32, n.z as f32]);
    }
    let mut output = vec![0.0f32; colour.len()];
    let device = device()?
        .lock()
        .map_err(|_| ImageError::invalid("denoise", "the OIDN device's lock is poisoned"))?;
    oidn::RayTracing::try_new(&device)
        .map_err(|e| ImageError::invalid("denoise", format!("OIDN filter: {e:?}")))?
        .hdr(true)
        .srgb(false)
        .clean_aux(true)
        .image_dimensions(width, height)
        .albedo_normal(&albedo, &normal)
        .filter(&colour, &mut output)
        .map_err(|e| ImageError::invalid("denoise", format!("OIDN: {e:?}")))?;
    Ok(output.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Radius in pixels of the window over which the squared differences of
/// [`denoise_with_halves`] are averaged into an error (a 7×7 box).
pub const BAR_RADIUS: usize = 3;

/// `full` (the mean of a render's passes) denoised by [`filter`], with each
/// pixel's variance measured from `halves`, the means of two disjoint halves
/// of the same passes with their own variances, each denoised apart
/// (docs/math.md §16.7): the denoised halves' difference gives the noise the
/// denoiser leaves, `scale · E(D(a) − D(b))²` (`scale` per pixel, 1/4 for
/// halves of equal rays), and each denoised half against the other raw
/// half, an unbiased image of the truth, gives its whole squared error, so
/// the part that is not noise (the denoiser's bias) is
/// `½[E(D(a) − b)² − v_b + E(D(b) − a)² − v_a − E(D(a) − D(b))²]`, at least
/// 0. Expectations are means over the channels and a [`BAR_RADIUS`] box
/// around the pixel, within the image.
pub fn denoise_with_halves(
    full: &Image,
    halves: [&Image; 2],
    scale: &[f64],
    guides: &GuideBuffers,
) -> Result<Image, ImageError> {
    let (width, height) = (full.width(), full.height());
    let [ha, hb] = halves;
    let (Some(va), Some(vb)) = (ha.variance(), hb.variance()) else {
        return Err(ImageError::invalid(
            "halves",
            "the halves need their variances",
        ));
    };
    if scale.len() != full.rgb().len()
        || halves
            .iter()
            .any(|h| (h.width(), h.height()) != (width, height))
    {
        return Err(ImageError::invalid(
            "halves",
            "the halves of a render and the render differ in size",
        ));
    }
    let [da, db] = [filter(ha.rgb(), guides)?, filter(hb.rgb(), guides)?];
    // The full mean denoised, not the mean of the denoised halves: 1–5 %
    // lower error on the studio and the tutorials' box, the same coverage.
    let clean = filter(full.rgb(), guides)?;
    let squared = |p: &[f32; 3], q: &[f32; 3]| -> f64 {
        (0..3)
            .map(|c| (f64::from(p[c]) - f64::from(q[c])).powi(2))
            .sum::<f64>()
            / 3.0
    };
    let (w, h) = (width as usize, height as usize);
    let between: Vec<f64> = (0..da.len()).map(|i| squared(&da[i], &db[i])).collect();
    let against: Vec<f64> = (0..da.len())
        .map(|i| {
            squared(&da[i], &hb.rgb()[i]) - f64::from(vb[i]) + squared(&db[i], &ha.rgb()[i])
                - f64::from(va[i])
        })
        .collect();
    let between = box_mean(&between, w, h, BAR_RADIUS);
    let against = box_mean(&against, w, h, BAR_RADIUS);
    let variance = (0..between.len())
        .map(|i| {
            let bias2 = (0.5 * (against[i] - between[i])).max(0.0);
            (scale[i] * between[i] + bias2) as f32
        })
        .collect();
    Image::from_parts(width, height, clean, Some(variance))
}

/// The mean of `values` (row-major, `width` wide) over the
/// `(2 radius + 1)²` box around each pixel, clipped to the image.
fn box_mean(values: &[f64], width: usize, height: usize, radius: usize) -> Vec<f64> {
    // Along the rows, then along the columns.
    let pass = |input: &[f64], along_rows: bool| -> Vec<f64> {
        let (n, lines) = if along_rows {
            (width, height)
        } else {
            (height, width)
        };
        let index = |line: usize, k: usize| {
            if along_rows {
                line * width + k
            } else {
                k * width + line
            }
        };
        let mut out = vec![0.0; input.len()];
        for line in 0..lines {
            for k in 0..n {
                let (lo, hi) = (k.saturating_sub(radius), (k + radius).min(n - 1));
                let sum: f64 = (lo..=hi).map(|j| input[index(line, j)]).sum();
                out[index(line, k)] = sum / (hi - lo + 1) as f64;
            }
        }
        out
    };
    pass(&pass(values, true), false)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;
    use crate::image::GuidePixel;

    #[test]
    fn box_means_stop_at_the_image_edge() {
        let values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let means = box_mean(&values, 3, 2, 1);
        assert_eq!(means[0], (1.0 + 2.0 + 4.0 + 5.0) / 4.0);
        assert_eq!(means[1], 21.0 / 6.0);
        assert_eq!(box_mean(&values, 3, 2, 0), values);
    }

    /// A flat grey wall under uniform light, rendered as two noisy halves:
    /// the denoised image is close to the truth and its error bars cover
    /// it about as often as a normal's ±2σ do, where the raw image's own
    /// bars would be far too wide.
    #[test]
    fn halves_measure_the_denoised_error() {
        let (width, height) = (64u32, 64u32);
        let n = (width * height) as usize;
        let truth = 0.4f32;
        let per_ray_sd = 0.5f32;
        let mut rng = Pcg64::seed_from_u64(7);
        let mut half = |rays: f32| -> Image {
            let sd = per_ray_sd / rays.sqrt();
            let rgb = (0..n)
                .map(|_| {
                    // Sum of uniforms: noise of the right spread, no normal sampler needed.
                    let u: f32 = (0..12).map(|_| rng.random::<f32>()).sum::<f32>() - 6.0;
                    [truth + sd * u; 3]
                })
                .collect();
            Image::from_parts(width, height, rgb, Some(vec![sd * sd; n])).expect("valid")
        };
        let (a, b) = (half(4.0), half(4.0));
        let full = Image::from_parts(
            width,
            height,
            a.rgb()
                .iter()
                .zip(b.rgb())
                .map(|(p, q)| [0, 1, 2].map(|c| 0.5 * (p[c] + q[c])))
                .collect(),
            Some(vec![per_ray_sd * per_ray_sd / 8.0; n]),
        )
        .expect("valid");
        let guides = GuideBuffers {
            width,
            height,
            pixels: vec![
                GuidePixel {
                    normal: Some(DVec3::Z),
                    mean_normal: DVec3::Z,
                    position: DVec3::ZERO,
                    footprint: 0.01,
                    albedo: [0.5; 3],
                };
                n
            ],
        };
        let clean =
            denoise_with_halves(&full, [&a, &b], &vec![0.25; n], &guides).expect("denoised");
        let variance = clean.variance().expect("measured");
        let (mut covered, mut squared) = (0usize, 0.0f64);
        for (p, &v) in clean.rgb().iter().zip(variance) {
            let error = f64::from(p[0] - truth);
            squared += error * error;
            covered += usize::from(error.abs() <= 2.0 * f64::from(v).sqrt());
        }
        let rmse = (squared / n as f64).sqrt();
        let raw_sd = f64::from(per_ray_sd) / 8f64.sqrt();
        assert!(
            rmse < 0.3 * raw_sd,
            "denoised error {rmse} against raw {raw_sd}"
        );
        let coverage = covered as f64 / n as f64;
        assert!((0.85..=0.995).contains(&coverage), "coverage {coverage}");
    }
}

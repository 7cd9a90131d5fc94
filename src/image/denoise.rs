//! An edge-avoiding à-trous filter for a rendered tile (docs/math.md
//! §16.6), guided by what the camera's first hits saw in each pixel (their
//! shading normal, position and diffuse albedo) and by the pixel's own
//! standard error, whose interval then bounds how far a value may move.
//!
//! The filter works on the image divided by the albedo (the light that
//! reaches the surface), so textures are not blurred; its weights stop at
//! a change of normal, at a neighbour off the pixel's tangent plane (an
//! occluding edge), between surfaces with and without a Lambertian part,
//! and at luminance differences large against the standard error
//! (Dammertz et al. 2010; Schied et al. 2017, SVGF). Each output channel
//! is clipped to the pixel's own value ± [`CLIP_SIGMAS`] standard errors
//! and keeps the pixel's standard error as its error bar.
//!
//! The filter sees one tile only, so a tile's value does not depend on
//! which other tiles were rendered (the GET tiles' reproducibility); a
//! pixel near the tile's edge has fewer neighbours to average.

use glam::DVec3;
use rayon::prelude::*;

use super::{Image, ImageError};

/// À-trous levels: steps 1, 2, 4 pixels, so a pixel reaches 14 pixels away.
pub const LEVELS: u32 = 3;
/// Luminance differences are compared with this many (filtered) standard
/// errors of the pixel's demodulated value (SVGF's `σ_l`).
pub const SIGMA_LUMINANCE: f64 = 1.0;
/// Exponent of the normal weight `max(0, n_p·n_q)^σ_n` (SVGF uses 128): at
/// 10° between normals the weight is 0.38, at 30° 10⁻⁴.
pub const SIGMA_NORMAL: i32 = 64;
/// Distance off the pixel's tangent plane, in pixel footprints per pixel of
/// offset, at which a neighbour's weight falls by `e`.
pub const SIGMA_PLANE: f64 = 1.0;
/// The denoised value stays within this many of the pixel's own standard
/// errors of its own value (docs/math.md §16.6).
pub const CLIP_SIGMAS: f64 = 1.0;
/// Albedos below this (in every channel) are not divided out: the surface
/// has no Lambertian part to speak of (a metal, glass).
const MIN_ALBEDO: f64 = 0.02;
/// The B3-spline taps of one à-trous level.
const TAPS: [f64; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// What the camera's first hits saw in each pixel, row-major like the
/// image it guides.
#[derive(Clone, Debug, PartialEq)]
pub struct GuideBuffers {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<GuidePixel>,
}

/// One pixel's guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuidePixel {
    /// The first hits' shading normal (unit, world frame), or `None` where
    /// the pixel sees no one smooth surface (an edge, the background, an
    /// emitter): such a pixel weighs its neighbours by value alone and lends
    /// nothing to pixels with a normal.
    pub normal: Option<DVec3>,
    /// The mean of the rays' shading normals, zero where none hit a
    /// surface: the normal image a path tracer hands OIDN (which weighs
    /// it itself at edges), where the filter here wants `normal`'s test.
    pub mean_normal: DVec3,
    /// The first hits' mean position, world units.
    pub position: DVec3,
    /// World length one pixel spans at the hit's depth.
    pub footprint: f64,
    /// The Lambertian reflectance `ρ(ω_o)` towards the camera, per channel
    /// (zero where the pixel sees no surface).
    pub albedo: [f64; 3],
}

/// A pixel's working state: demodulated radiance and its variance.
#[derive(Clone, Copy)]
struct Working {
    value: [f64; 3],
    variance: f64,
}

/// The filtered `image` (module docs); its variance channel is the
/// input's. Errors if the image has no variance or the guides another size.
pub fn denoise(image: &Image, guides: &GuideBuffers) -> Result<Image, ImageError> {
    let (width, height) = (image.width(), image.height());
    if (guides.width, guides.height) != (width, height) {
        return Err(ImageError::invalid(
            "guides",
            format!(
                "{}×{} guides for a {width}×{height} image",
                guides.width, guides.height
            ),
        ));
    }
    let Some(variance) = image.variance() else {
        return Err(ImageError::invalid(
            "variance",
            "denoising needs each pixel's variance",
        ));
    };
    let demodulate = |g: &GuidePixel| -> [f64; 3] {
        if g.albedo.iter().all(|&a| a < MIN_ALBEDO) {
            [1.0; 3]
        } else {
            g.albedo.map(|a| a.max(MIN_ALBEDO))
        }
    };
    let divisors: Vec<[f64; 3]> = guides.pixels.iter().map(demodulate).collect();
    let mut state: Vec<Working> = image
        .rgb()
        .iter()
        .zip(variance)
        .zip(&divisors)
        .map(|((c, &v), a)| {
            let mean_albedo = (a[0] + a[1] + a[2]) / 3.0;
            Working {
                value: [0, 1, 2].map(|k| f64::from(c[k]) / a[k]),
                variance: f64::from(v) / (mean_albedo * mean_albedo),
            }
        })
        .collect();
    for level in 0..LEVELS {
        state = a_trous_level(&state, guides, 1 << level);
    }
    let rgb = image
        .rgb()
        .iter()
        .zip(variance)
        .zip(state.iter().zip(&divisors))
        .map(|((c, &v), (s, a))| {
            let sigma = CLIP_SIGMAS * f64::from(v).sqrt();
            [0, 1, 2].map(|k| {
                let own = f64::from(c[k]);
                (s.value[k] * a[k]).clamp(own - sigma, own + sigma) as f32
            })
        })
        .collect();
    Image::from_parts(width, height, rgb, Some(variance.to_vec()))
}

/// One à-trous level with taps `step` pixels apart: each pixel's weighted
/// mean of its 5×5 taps and, for the next level's luminance weight, the
/// variance of that mean `Σ w² v / (Σ w)²` (SVGF).
fn a_trous_level(state: &[Working], guides: &GuideBuffers, step: i64) -> Vec<Working> {
    let (width, height) = (i64::from(guides.width), i64::from(guides.height));
    (0..state.len())
        .into_par_iter()
        .map(|i| {
            let p = &guides.pixels[i];
            let (x, y) = (i as i64 % width, i as i64 / width);
            let centre = state[i];
            let luminance = |w: &Working| (w.value[0] + w.value[1] + w.value[2]) / 3.0;
            let l_p = luminance(&centre);
            let luminance_scale = SIGMA_LUMINANCE * centre.variance.sqrt() + 1e-12;
            let (mut sum, mut weights, mut variance) = ([0.0; 3], 0.0, 0.0);
            for (dy, ty) in (-2i64..=2).zip(TAPS) {
                for (dx, tx) in (-2i64..=2).zip(TAPS) {
                    let (qx, qy) = (x + dx * step, y + dy * step);
                    if !(0..width).contains(&qx) || !(0..height).contains(&qy) {
                        continue;
                    }
                    let j = (qy * width + qx) as usize;
                    let neighbour = state[j];
                    let offset = ((dx * dx + dy * dy) as f64).sqrt() * step as f64;
                    let geometry = if j == i {
                        1.0
                    } else {
                        geometric_weight(p, &guides.pixels[j], offset)
                    };
                    if geometry == 0.0 {
                        continue;
                    }
                    let w = tx
                        * ty
                        * geometry
                        * (-(l_p - luminance(&neighbour)).abs() / luminance_scale).exp();
                    for (s, v) in sum.iter_mut().zip(neighbour.value) {
                        *s += w * v;
                    }
                    weights += w;
                    variance += w * w * neighbour.variance;
                }
            }
            // The centre's own weight is `(3/8)²` (its geometric and
            // luminance terms are 1), so `weights > 0`.
            Working {
                value: sum.map(|s| s / weights),
                variance: variance / (weights * weights),
            }
        })
        .collect()
}

/// The guides' part of the weight of neighbour `q` of pixel `p`, `offset`
/// pixels away: zero between surfaces with and without a Lambertian part
/// or for a neighbour without a normal (it mixes surfaces); else
/// `max(0, n_p·n_q)^σ_n` times `exp(−d/(σ_p f offset))`, `d` the
/// neighbour's distance off `p`'s tangent plane and `f` `p`'s footprint. A
/// pixel without a normal weighs every neighbour by value alone.
fn geometric_weight(p: &GuidePixel, q: &GuidePixel, offset: f64) -> f64 {
    let Some(n_p) = p.normal else {
        return 1.0;
    };
    let Some(n_q) = q.normal else {
        return 0.0;
    };
    let diffuse = |g: &GuidePixel| g.albedo.iter().any(|&a| a >= MIN_ALBEDO);
    if diffuse(p) != diffuse(q) {
        return 0.0;
    }
    let plane = n_p.dot(q.position - p.position).abs() / (SIGMA_PLANE * p.footprint * offset);
    n_p.dot(n_q).max(0.0).powi(SIGMA_NORMAL) * (-plane).exp()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    const SIDE: u32 = 32;

    /// A flat grey floor facing the camera, one pixel per world unit.
    fn floor(albedo: f64) -> GuideBuffers {
        let pixels = (0..SIDE * SIDE)
            .map(|i| GuidePixel {
                normal: Some(DVec3::Z),
                mean_normal: DVec3::Z,
                position: DVec3::new(f64::from(i % SIDE), f64::from(i / SIDE), 0.0),
                footprint: 1.0,
                albedo: [albedo; 3],
            })
            .collect();
        GuideBuffers {
            width: SIDE,
            height: SIDE,
            pixels,
        }
    }

    /// `truth` plus Gaussian noise of standard error `sigma` per pixel.
    fn noisy(truth: impl Fn(u32) -> f64, sigma: f64, seed: u64) -> Image {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut gauss = || crate::testing::standard_normal(&mut rng);
        let rgb = (0..SIDE * SIDE)
            .map(|i| [0; 3].map(|_| (truth(i) + sigma * gauss()) as f32))
            .collect();
        let variance = vec![(sigma * sigma) as f32; (SIDE * SIDE) as usize];
        Image::from_parts(SIDE, SIDE, rgb, Some(variance)).unwrap()
    }

    fn rmse(image: &Image, truth: impl Fn(u32) -> f64) -> f64 {
        let sum: f64 = (0..SIDE * SIDE)
            .map(|i| {
                let c = image.rgb()[i as usize];
                c.iter()
                    .map(|&v| (f64::from(v) - truth(i)).powi(2))
                    .sum::<f64>()
            })
            .sum();
        (sum / f64::from(3 * SIDE * SIDE)).sqrt()
    }

    #[test]
    fn a_constant_image_is_unchanged() {
        let image = noisy(|_| 0.7, 0.0, 1);
        let image = Image::from_parts(SIDE, SIDE, image.rgb().to_vec(), Some(vec![0.01; 1024]));
        let image = image.unwrap();
        assert_eq!(denoise(&image, &floor(0.5)).unwrap(), image);
    }

    #[test]
    fn noise_on_a_flat_floor_shrinks_and_stays_within_the_interval() {
        let truth = |_| 1.0;
        let image = noisy(truth, 0.1, 2);
        let clean = denoise(&image, &floor(0.5)).unwrap();
        let (before, after) = (rmse(&image, truth), rmse(&clean, truth));
        assert!(after < 0.6 * before, "rmse {before} -> {after}");
        assert_eq!(clean.variance(), image.variance(), "the error bar is kept");
        for (c, d) in image.rgb().iter().zip(clean.rgb()) {
            for k in 0..3 {
                assert!((c[k] - d[k]).abs() <= 0.1 * CLIP_SIGMAS as f32 + 1e-6);
            }
        }
    }

    #[test]
    fn an_edge_of_normals_is_not_blurred() {
        // Left half faces +z at 1.0, right half faces +x at 3.0: no weight
        // crosses the crease, so a noiseless step stays a step.
        let mut guides = floor(0.5);
        for (i, g) in guides.pixels.iter_mut().enumerate() {
            if i as u32 % SIDE >= SIDE / 2 {
                g.normal = Some(DVec3::X);
            }
        }
        let truth = |i: u32| if i % SIDE >= SIDE / 2 { 3.0 } else { 1.0 };
        let rgb = (0..SIDE * SIDE).map(|i| [truth(i) as f32; 3]).collect();
        // Error bars as wide as the step: only the guides keep it sharp.
        let image = Image::from_parts(SIDE, SIDE, rgb, Some(vec![4.0; 1024])).unwrap();
        assert_eq!(denoise(&image, &guides).unwrap(), image);
    }

    #[test]
    fn a_texture_is_divided_out_and_kept() {
        // A checkerboard albedo under even light of 2: the value is the
        // albedo times 2 plus noise; the filter averages the light, not
        // the albedo, so the checkerboard survives (and gets cleaner).
        let mut guides = floor(0.2);
        let albedo = |i: u32| {
            if (i % SIDE + i / SIDE).is_multiple_of(2) {
                0.8
            } else {
                0.2
            }
        };
        for (i, g) in guides.pixels.iter_mut().enumerate() {
            g.albedo = [albedo(i as u32); 3];
        }
        let truth = |i| 2.0 * albedo(i);
        let image = noisy(truth, 0.1, 3);
        let clean = denoise(&image, &guides).unwrap();
        assert!(rmse(&clean, truth) < 0.6 * rmse(&image, truth));
    }

    #[test]
    fn pixels_without_a_normal_lend_nothing_to_guided_ones() {
        let mut guides = floor(0.5);
        // The left column sees the bright background.
        for g in guides.pixels.iter_mut().step_by(SIDE as usize) {
            g.normal = None;
            g.albedo = [0.0; 3];
        }
        let truth = |i: u32| if i.is_multiple_of(SIDE) { 50.0 } else { 1.0 };
        let noisy = noisy(truth, 0.1, 4);
        // The background is exact: no error bar to move within.
        let variance = (0..SIDE * SIDE)
            .map(|i| if i.is_multiple_of(SIDE) { 0.0 } else { 0.01 })
            .collect();
        let image = Image::from_parts(SIDE, SIDE, noisy.rgb().to_vec(), Some(variance)).unwrap();
        let clean = denoise(&image, &guides).unwrap();
        for i in 0..SIDE * SIDE {
            let (c, d) = (image.rgb()[i as usize], clean.rgb()[i as usize]);
            if i.is_multiple_of(SIDE) {
                assert_eq!(c, d);
            } else {
                assert!(d.iter().all(|&v| v < 1.5), "background leaked: {d:?}");
            }
        }
    }

    #[test]
    fn mismatched_guides_or_no_variance_are_refused() {
        let image = noisy(|_| 1.0, 0.1, 5);
        let mut small = floor(0.5);
        small.width = 16;
        assert!(matches!(
            denoise(&image, &small),
            Err(ImageError::Invalid {
                field: "guides",
                ..
            })
        ));
        let bare = Image::from_parts(SIDE, SIDE, image.rgb().to_vec(), None).unwrap();
        assert!(matches!(
            denoise(&bare, &floor(0.5)),
            Err(ImageError::Invalid {
                field: "variance",
                ..
            })
        ));
    }
}

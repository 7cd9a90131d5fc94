//! Tiles of the scene camera's image: the camera/pixel loop, written once
//! for every way of shading a camera ray (pbrt-v4's `ImageTileIntegrator`
//! idea: the loop over pixels and samples is shared, the radiance along a
//! camera ray is pluggable).
//!
//! A pixel's value is the box-filtered average of radiance over its area:
//! `spp` camera rays, each shaded by a [`CameraRayShader`], averaged with
//! Welford's method ([`MeanEstimate`]). The first `s²` rays (`s = ⌊√spp⌋`)
//! pass through positions jittered within the cells of an `s × s` grid over
//! the pixel, the rest uniformly: every ray is uniform over the pixel on its
//! own, so the mean is unbiased, and stratification cuts the noise of
//! edges inside the pixel (anti-aliasing) from `O(spp^-1/2)` towards
//! `O(spp^-3/4)` (Mitchell 1996). Each ray also learns which of the pixel's
//! rays it is ([`PixelSample`]), so a shader can stratify other dimensions
//! over all of them (the irradiance cache's light samples and the path
//! tracer's first-vertex samples, [`crate::render::strata::SharedStrata`]). The image stores the mean and
//! the sample variance / spp, averaged over RGB (see [`Image`]): the
//! variance of the mean for independent rays, an upper bound for
//! stratified ones. A shader may report a variance of its own for a ray
//! (the irradiance cache's glossy fallback, docs/math.md §13.3); the pixel
//! then reports at least the mean of those over spp
//! ([`MeanEstimate::of_evaluations`]), so a pixel of one ray is not
//! reported exact where its shader knows otherwise.
//!
//! Reproducibility: pixel (px, py) draws every random number from
//! [`pixel_rng`]`(seed, px, py)`, so a pixel's value does not depend on the
//! tile it belongs to, on the other pixels, or on the thread count.

use rand::RngExt;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::cancel::Cancel;
use super::error::RenderError;
use super::mean::{Evaluation, MeanEstimate};
use super::path::{PathDepth, TraceStats};
use super::seed::point_rng;
use crate::image::Image;
use crate::scene::{Camera, Ray, Scene};

/// Largest tile, in pixels (2048²): bounds one request's memory and time.
pub const MAX_TILE_PIXELS: u64 = 1 << 22;
/// Largest accepted samples per pixel.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 20;

/// A rectangle of the camera image and the work to spend on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileRequest {
    /// Column of the tile's left edge, pixels from the image's left.
    pub x: u32,
    /// Row of the tile's top edge, pixels from the image's top.
    pub y: u32,
    pub width: u32,
    pub height: u32,
    /// Camera rays per pixel, jittered over the pixel area.
    pub samples_per_pixel: u32,
    /// Longest path counted, in segments from the camera (1 = emitters seen
    /// directly only).
    pub max_depth: PathDepth,
    /// Seed of every random stream of the request.
    pub seed: u64,
    /// Which of the seed's disjoint sets of camera samples (0 = the first):
    /// pixels draw from [`pixel_rng`]`(`[`pass_seed`]`(seed, pass), px, py)`,
    /// so passes `0..k` are independent renders whose mean is a render of
    /// `k · samples_per_pixel` rays ([`crate::image::Image::mean_of`]).
    /// Whatever else the request seeds (the irradiance cache's records) uses
    /// `seed` alone, so every pass shares it.
    pub pass: u32,
}

/// The seed of pass `pass`'s camera samples: `seed` itself for pass 0 (so a
/// single-pass render is unchanged), a SplitMix64 mix of both otherwise
/// (docs/math.md §16.1).
pub fn pass_seed(seed: u64, pass: u32) -> u64 {
    if pass == 0 {
        seed
    } else {
        super::seed::mix(seed ^ super::seed::mix(u64::from(pass)))
    }
}

impl TileRequest {
    /// Checks the request against an image of `resolution` (width, height);
    /// its depth is valid by construction.
    pub fn validate(&self, resolution: (u32, u32)) -> Result<(), RenderError> {
        let bad =
            |field: &'static str, reason: String| RenderError::InvalidOption { field, reason };
        for (field, start, len, side) in [
            ("x", self.x, self.width, resolution.0),
            ("y", self.y, self.height, resolution.1),
        ] {
            let size_field = if field == "x" { "width" } else { "height" };
            if len == 0 {
                return Err(bad(size_field, "must be at least 1".into()));
            }
            if start >= side {
                return Err(bad(
                    field,
                    format!("{start} is outside the image (0..{side})"),
                ));
            }
            if u64::from(start) + u64::from(len) > u64::from(side) {
                return Err(bad(
                    size_field,
                    format!(
                        "tile {start}..{} extends past the image side {side}",
                        u64::from(start) + u64::from(len)
                    ),
                ));
            }
        }
        let area = u64::from(self.width) * u64::from(self.height);
        if area > MAX_TILE_PIXELS {
            return Err(bad(
                "width",
                format!(
                    "{}×{} = {area} pixels exceeds the tile limit {MAX_TILE_PIXELS}",
                    self.width, self.height
                ),
            ));
        }
        if self.samples_per_pixel == 0 || self.samples_per_pixel > MAX_SAMPLES_PER_PIXEL {
            return Err(bad(
                "samples_per_pixel",
                format!(
                    "{} is not in 1..={MAX_SAMPLES_PER_PIXEL}",
                    self.samples_per_pixel
                ),
            ));
        }
        Ok(())
    }
}

/// A rendered tile: its image (the tile's own size) and the work it took.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedTile {
    /// Position of the tile's top-left pixel in the camera image.
    pub x: u32,
    pub y: u32,
    pub image: Image,
    /// Closest-hit plus shadow rays traced, camera rays included.
    pub rays: u64,
}

/// Which of its pixel's camera rays a ray is: shaders may spread samples
/// over all rays of the pixel (e.g. light samples on one
/// stratified pattern, as the irradiance cache's light samples do).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSample {
    /// Index of the ray among the pixel's `count` rays.
    pub index: u32,
    pub count: u32,
    /// Two uniform words drawn once per pixel from its generator, the same
    /// for all its rays: the seeds of a shared pattern.
    pub pattern: [u64; 2],
}

/// Radiance arriving at the camera along a camera ray, W/(m²·sr), with the
/// variance the shader knows of for it ((W/(m²·sr))², zero if none). The
/// tile loop calls it `spp` times per pixel with that pixel's generator.
pub trait CameraRayShader: Sync {
    /// The scene the camera rays are traced in.
    fn scene(&self) -> &Scene;

    fn radiance(
        &self,
        ray: Ray,
        sample: PixelSample,
        rng: &mut Pcg64,
        stats: &mut TraceStats,
    ) -> Evaluation;
}

/// Most emitters a camera ray is moved past (more is a degenerate scene).
const MAX_HIDDEN_EMITTERS: usize = 64;

/// The camera ray as the scene's `hide_emitters` leaves it: unchanged when
/// emitters are shown; otherwise moved past the area emitters it meets
/// first, as if they were not there, and `None` (black) when it then leaves
/// the scene, the environment being hidden too (Mitsuba 3's path tracer).
fn visible(scene: &Scene, mut ray: Ray, stats: &mut TraceStats) -> Option<Ray> {
    if !scene.hide_emitters {
        return Some(ray);
    }
    for _ in 0..MAX_HIDDEN_EMITTERS {
        stats.rays += 1;
        let hit = scene.intersect(&ray)?;
        if hit.emitter.is_none() {
            return Some(ray);
        }
        ray = scene.spawn_ray(hit.position, hit.normal, ray.dir);
    }
    None
}

/// Generator of pixel (px, py) for a request seeded with `seed`: a function
/// of these three numbers only (the stream index packs px and py, so it
/// does not depend on the image width either).
pub fn pixel_rng(seed: u64, px: u32, py: u32) -> Pcg64 {
    point_rng(seed, (u64::from(py) << 32) | u64::from(px))
}

/// The camera/pixel loop shared by every [`CameraRayShader`]; validates
/// `request` against `camera` and checks `cancel` before each pixel.
pub fn render_tile_with(
    camera: &Camera,
    shader: &impl CameraRayShader,
    request: &TileRequest,
    cancel: &Cancel,
) -> Result<RenderedTile, RenderError> {
    request.validate(camera.resolution())?;
    let width = request.width as usize;
    let pixels: Option<Vec<(MeanEstimate, u64)>> = (0..width * request.height as usize)
        .into_par_iter()
        .map(|i| {
            if cancel.is_cancelled() {
                return None;
            }
            let px = request.x + (i % width) as u32;
            let py = request.y + (i / width) as u32;
            let mut rng = pixel_rng(pass_seed(request.seed, request.pass), px, py);
            let mut stats = TraceStats::default();
            let side = f64::from(request.samples_per_pixel).sqrt().floor() as u32;
            let pattern = [rng.random(), rng.random()];
            let samples = (0..request.samples_per_pixel).map(|k| {
                let (mut u, mut v): (f64, f64) = (rng.random(), rng.random());
                if k < side * side {
                    u = (f64::from(k % side) + u) / f64::from(side);
                    v = (f64::from(k / side) + v) / f64::from(side);
                }
                let (x, y) = (f64::from(px) + u, f64::from(py) + v);
                // A pinhole draws no lens sample, so its images keep their bits.
                let ray = match camera.has_lens() {
                    true => camera.generate_ray_through_lens(x, y, [rng.random(), rng.random()]),
                    false => camera.generate_ray(x, y),
                };
                let sample = PixelSample {
                    index: k,
                    count: request.samples_per_pixel,
                    pattern,
                };
                match visible(shader.scene(), ray, &mut stats) {
                    Some(ray) => shader.radiance(ray, sample, &mut rng, &mut stats),
                    None => Evaluation::of(super::rgb::Rgb::BLACK),
                }
            });
            Some((MeanEstimate::of_evaluations(samples), stats.rays))
        })
        .collect();
    let pixels = pixels.ok_or(RenderError::Cancelled)?;
    let rays = pixels.iter().map(|(_, r)| r).sum();
    let rgb = pixels
        .iter()
        .map(|(e, _)| e.mean.to_array().map(|c| c as f32))
        .collect();
    let variance = pixels
        .iter()
        .map(|(e, _)| {
            let v = e.variance_of_mean;
            ((v.r + v.g + v.b) / 3.0) as f32
        })
        .collect();
    let image =
        Image::from_parts(request.width, request.height, rgb, Some(variance)).map_err(|e| {
            RenderError::InvalidOption {
                field: "width",
                reason: e.to_string(),
            }
        })?;
    Ok(RenderedTile {
        x: request.x,
        y: request.y,
        image,
        rays,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn request(x: u32, y: u32, width: u32, height: u32) -> TileRequest {
        TileRequest {
            x,
            y,
            width,
            height,
            samples_per_pixel: 2,
            max_depth: PathDepth::constant(6),
            seed: 7,
            pass: 0,
        }
    }

    #[test]
    fn pixel_streams_depend_only_on_seed_and_position() {
        use rand::Rng;
        assert_eq!(pixel_rng(3, 5, 9).next_u64(), pixel_rng(3, 5, 9).next_u64());
        assert_ne!(pixel_rng(3, 5, 9).next_u64(), pixel_rng(3, 9, 5).next_u64());
        assert_ne!(pixel_rng(3, 5, 9).next_u64(), pixel_rng(4, 5, 9).next_u64());
    }
}

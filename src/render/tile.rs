//! Tiles of the scene camera's image: the camera/pixel loop, written once
//! for every way of shading a camera ray (pbrt-v4's `ImageTileIntegrator`
//! idea: the loop over pixels and samples is shared, the radiance along a
//! camera ray is pluggable).
//!
//! A pixel's value is the box-filtered average of radiance over its area:
//! `spp` camera rays, each shaded by a [`CameraRayShader`], averaged with
//! Welford's method ([`MeanEstimate`]). The rays pass through positions
//! spread over the pixel by a progressive pattern of all the pixel's rays
//! over every pass ([`SharedStrata`], docs/math.md §16): every ray is
//! uniform over the pixel on its own, so the mean is unbiased, and
//! stratification cuts the noise of edges inside the pixel
//! (anti-aliasing) from `O(spp^-1/2)` towards `O(spp^-3/4)` (Mitchell
//! 1996), for each pass and for the passes together. Each ray also learns
//! which of the pixel's rays it is ([`PixelSample`]), so a shader can
//! stratify other dimensions over all of them (the irradiance cache's light
//! samples and the path tracer's first-vertex samples). The image stores the mean and
//! the sample variance / spp, averaged over RGB (see [`Image`]) and pooled
//! with the pixel's neighbours' in the tile ([`PixelVariances`]): the
//! variance of the mean for independent rays, an upper bound for
//! stratified ones. A shader may report a variance of its own for a ray
//! (the irradiance cache's glossy fallback, docs/math.md §13.3); the pixel
//! then reports at least the mean of those over spp, plus the mean of the
//! variances its rays share (the records they interpolate, docs/math.md
//! §16.3; [`MeanEstimate::of_evaluations`]), so a pixel of one ray is not
//! reported exact where its shader knows otherwise.
//!
//! Reproducibility: pixel (px, py) draws every random number from
//! [`pixel_rng`]`(pass_seed(seed, pass), px, py)` and [`pixel_pattern`]`(seed,
//! px, py)`, so a pixel's value does not depend on the tile it belongs to,
//! on the other pixels, or on the thread count; with a [`SamplePlan`] (an
//! adaptive pass) its ray count comes from the plan, which its caller
//! derives from the tile's first pass, so there the tile's rectangle
//! matters (the service's GET tiles have one grid).

use rand::RngExt;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::cancel::Cancel;
use super::error::RenderError;
use super::mean::{Evaluation, MeanEstimate};
use super::path::{PathDepth, TraceStats};
use super::pixel_variance::PixelVariances;
use super::sample_plan::SamplePlan;
use super::seed::{mix, point_rng};
use super::strata::SharedStrata;
use crate::image::Image;
use crate::scene::{Camera, Ray, Scene};

/// Largest tile, in pixels (2048²): bounds one request's memory and time.
pub const MAX_TILE_PIXELS: u64 = 1 << 22;
/// Largest accepted samples per pixel.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 20;

/// A rectangle of the camera image and the work to spend on it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
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
    /// Which of the `passes` disjoint sets of camera samples (0 = the
    /// first): pixels draw their jitter from
    /// [`pixel_rng`]`(`[`pass_seed`]`(seed, pass), px, py)` and take rays
    /// `pass · spp .. (pass + 1) · spp` of one pattern of `passes · spp`
    /// ([`pixel_pattern`]), so the mean of passes `0..=k` is a render of
    /// `(k + 1) · spp` rays stratified as one (docs/math.md §16.1; a preset's
    /// later passes take the rays of a [`SamplePlan`] instead, §16.5). Whatever else the request seeds (the irradiance
    /// cache's records) uses `seed` alone, so every pass shares it.
    pub pass: u32,
    /// Passes the pixel's pattern is spread over (1: a single render).
    pub passes: u32,
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
        if self.pass >= self.passes {
            return Err(bad(
                "pass",
                format!("{} is not in 0..{} passes", self.pass, self.passes),
            ));
        }
        let total = u64::from(self.samples_per_pixel) * u64::from(self.passes);
        if total > u64::from(MAX_SAMPLES_PER_PIXEL) {
            return Err(bad(
                "samples_per_pixel",
                format!(
                    "{} over {} passes is {total} rays per pixel, more than {MAX_SAMPLES_PER_PIXEL}",
                    self.samples_per_pixel, self.passes
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
    /// Per pixel, the part of the image's variance that the pixel's rays
    /// share ([`PixelVariances::shared`]): passes over the same records
    /// do not average it out.
    pub shared: Vec<f32>,
    /// Closest-hit plus shadow rays traced, camera rays included.
    pub rays: u64,
}

/// Which of its pixel's camera rays a ray is, over all passes: shaders may
/// spread samples over all rays of the pixel (e.g. light samples on one
/// stratified pattern, as the irradiance cache's light samples do).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSample {
    /// Index of the ray among the pixel's `count` rays (`count` over all
    /// passes; pass `p` holds indices `p · spp .. (p + 1) · spp`).
    pub index: u32,
    pub count: u32,
    /// Two uniform words per pixel ([`pixel_pattern`]), the same for all
    /// its rays in every pass: the seeds of its shared patterns.
    pub pattern: [u64; 2],
    /// The pixel: column and row in the image.
    pub pixel: [u32; 2],
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
    point_rng(seed, pixel_index(px, py))
}

fn pixel_index(px: u32, py: u32) -> u64 {
    (u64::from(py) << 32) | u64::from(px)
}

/// The two seed words of pixel (px, py)'s patterns ([`PixelSample::pattern`]):
/// a hash of the request's seed and the position, the same for every pass
/// (so the passes share the patterns) and apart from every pass's stream.
pub fn pixel_pattern(seed: u64, px: u32, py: u32) -> [u64; 2] {
    let word = mix(mix(seed ^ PATTERN_STREAM) ^ pixel_index(px, py));
    [word, mix(word)]
}

/// Distinguishes the pattern words from the pixel streams' seeds.
const PATTERN_STREAM: u64 = 0xA076_1D64_78BD_642F;
/// Distinguishes the camera positions' pattern from the light samples'.
const CAMERA_PATTERN: u64 = 0xE703_7ED1_A0B4_28DB;

/// The camera/pixel loop shared by every [`CameraRayShader`]; validates
/// `request` against `camera` and checks `cancel` before each pixel. With a
/// `plan` (an adaptive pass, [`SamplePlan`]) pixel `i` of the tile takes
/// `plan.counts[i]` rays from index `plan.firsts[i]` of a pattern of
/// `plan.pattern`; without, every pixel takes `samples_per_pixel` rays of
/// pass `pass` of a pattern of `samples_per_pixel · passes`.
pub fn render_tile_with(
    camera: &Camera,
    shader: &impl CameraRayShader,
    request: &TileRequest,
    plan: Option<&SamplePlan>,
    cancel: &Cancel,
) -> Result<RenderedTile, RenderError> {
    request.validate(camera.resolution())?;
    let width = request.width as usize;
    let area = width * request.height as usize;
    if let Some(plan) = plan
        && (plan.counts.len() != area || plan.firsts.len() != area)
    {
        return Err(RenderError::InvalidOption {
            field: "plan",
            reason: format!("needs {area} pixels, got {}", plan.counts.len()),
        });
    }
    let pixels: Option<Vec<(MeanEstimate, u64)>> = (0..area)
        .into_par_iter()
        .map(|i| {
            if cancel.is_cancelled() {
                return None;
            }
            let px = request.x + (i % width) as u32;
            let py = request.y + (i / width) as u32;
            let mut rng = pixel_rng(pass_seed(request.seed, request.pass), px, py);
            let mut stats = TraceStats::default();
            let pattern = pixel_pattern(request.seed, px, py);
            let (count, first, rays) = match plan {
                Some(plan) => (plan.pattern, plan.firsts[i], plan.counts[i]),
                None => (
                    request.samples_per_pixel * request.passes,
                    request.pass * request.samples_per_pixel,
                    request.samples_per_pixel,
                ),
            };
            let positions =
                SharedStrata::new(u64::from(count), pattern.map(|w| mix(w ^ CAMERA_PATTERN)));
            let samples = (0..rays).map(|k| {
                let index = first + k;
                let u = positions.sample(u64::from(index), [rng.random(), rng.random()]);
                let (x, y) = camera.pixel_position(px, py, u);
                // A pinhole draws no lens sample, so its images keep their bits.
                let ray = match camera.has_lens() {
                    true => camera.generate_ray_through_lens(x, y, [rng.random(), rng.random()]),
                    false => camera.generate_ray(x, y),
                };
                let sample = PixelSample {
                    index,
                    count,
                    pattern,
                    pixel: [px, py],
                };
                match visible(shader.scene(), ray, &mut stats) {
                    Some(ray) => shader.radiance(ray, sample, &mut rng, &mut stats),
                    None => Evaluation::of(crate::color::Rgb::BLACK),
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
    let estimates: Vec<MeanEstimate> = pixels.iter().map(|(e, _)| *e).collect();
    let PixelVariances { variance, shared } = PixelVariances::of_tile(width, &estimates);
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
        shared,
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
            passes: 1,
        }
    }

    /// `tiled` is `whole` rendered in tiles of `tile` pixels: the same
    /// values everywhere, the same variances wherever a pixel's 3×3
    /// neighbourhood lies in one tile (elsewhere it pools over fewer
    /// neighbours, [`PixelVariances::of_tile`]).
    pub(crate) fn assert_tiling_keeps_the_image(tiled: &Image, whole: &Image, tile: u32) {
        assert_eq!(tiled.rgb(), whole.rgb());
        let (w, h) = (whole.width(), whole.height());
        let inside = |c: u32, size: u32| {
            (!c.is_multiple_of(tile) || c == 0) && (!(c + 1).is_multiple_of(tile) || c + 1 == size)
        };
        let (a, b) = (
            tiled.variance().expect("variance"),
            whole.variance().expect("variance"),
        );
        let mut compared = 0;
        for y in (0..h).filter(|&y| inside(y, h)) {
            for x in (0..w).filter(|&x| inside(x, w)) {
                let i = (y * w + x) as usize;
                assert_eq!(a[i], b[i], "pixel ({x}, {y})");
                compared += 1;
            }
        }
        assert!(compared > 0);
    }

    /// Records every ray's pixel sample and film position.
    struct Recorder<'a> {
        scene: &'a Scene,
        camera: &'a Camera,
        seen: std::sync::Mutex<Vec<(PixelSample, [f64; 2])>>,
    }

    impl CameraRayShader for Recorder<'_> {
        fn scene(&self) -> &Scene {
            self.scene
        }

        fn radiance(
            &self,
            ray: Ray,
            sample: PixelSample,
            _: &mut Pcg64,
            _: &mut TraceStats,
        ) -> Evaluation {
            let (x, y, _) = self.camera.raster(ray.at(1.0)).expect("in view");
            self.seen.lock().unwrap().push((sample, [x, y]));
            Evaluation::of(crate::color::Rgb::BLACK)
        }
    }

    /// The passes of a pixel take disjoint index ranges of one pattern
    /// whose seeds they share, and their camera positions are stratified
    /// over the pixel as one: each pass over the 2 × 2 quarters, all four
    /// over the 4 × 4 sixteenths.
    #[test]
    fn passes_share_one_stratified_pattern() {
        let transport = crate::testing::cornell(8);
        let scene = transport.scene();
        let recorder = Recorder {
            scene,
            camera: &scene.camera,
            seen: Default::default(),
        };
        let (passes, spp) = (4, 4);
        for pass in 0..passes {
            let request = TileRequest {
                samples_per_pixel: spp,
                pass,
                passes,
                ..request(3, 5, 1, 1)
            };
            render_tile_with(&scene.camera, &recorder, &request, None, &Cancel::never()).unwrap();
        }
        let seen = recorder.seen.into_inner().unwrap();
        assert_eq!(seen.len(), 16);
        let mut fine = [0; 16];
        for (pass, rays) in seen.chunks(spp as usize).enumerate() {
            let mut quarters = [0; 4];
            for (k, (sample, [x, y])) in rays.iter().enumerate() {
                assert_eq!(sample.index, pass as u32 * spp + k as u32);
                assert_eq!(sample.count, 16);
                assert_eq!(sample.pattern, seen[0].0.pattern);
                let (u, v) = (x - 3.0, y - 5.0);
                assert!(
                    (0.0..1.0).contains(&u) && (0.0..1.0).contains(&v),
                    "{x} {y}"
                );
                quarters[(2.0 * v) as usize * 2 + (2.0 * u) as usize] += 1;
                fine[(4.0 * v) as usize * 4 + (4.0 * u) as usize] += 1;
            }
            assert_eq!(quarters, [1; 4], "pass {pass}");
        }
        assert_eq!(fine, [1; 16]);
    }

    #[test]
    fn pixel_streams_depend_only_on_seed_and_position() {
        use rand::Rng;
        assert_eq!(pixel_rng(3, 5, 9).next_u64(), pixel_rng(3, 5, 9).next_u64());
        assert_ne!(pixel_rng(3, 5, 9).next_u64(), pixel_rng(3, 9, 5).next_u64());
        assert_ne!(pixel_rng(3, 5, 9).next_u64(), pixel_rng(4, 5, 9).next_u64());
    }
}

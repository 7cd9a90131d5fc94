//! Camera tiles as both tile routes render them: the passes of a preset
//! (or of explicit knobs) up to a requested one, averaged, with the work a
//! reproducible tile has done kept for the next request.
//!
//! What a reproducible tile keeps for the next request: `tile_store`; its
//! records serve point queries from there (`tile_priors`).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

use super::config::Limits;
use super::error::ApiError;
use super::integrator::{CachedSetup, cached_setup, resolve_integrator};
use super::scenes::LoadedScene;
use super::state::AppState;
use super::tile_store::{Key, RenderedPass, TileRecords};
use crate::image::Image;
use crate::integrator::{Integrator, IntegratorSpec, Preset};
use crate::render::{Cancel, PathDepth, TileRequest};
use crate::scene::Scene;

/// A tile as either route names it, before any check: the rectangle, the
/// preset and the knobs that override it.
#[derive(Clone, Copy, Debug)]
pub struct TileParams {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
    pub preset: Preset,
    /// Camera rays per pixel of one pass; `None`: the preset's passes.
    pub samples_per_pixel: Option<u32>,
    /// The last pass averaged; `None`: the last of them.
    pub pass: Option<u32>,
    /// Longest path in segments; `None`: the scene's, else the preset's.
    pub max_depth: Option<u32>,
    pub seed: u64,
    /// The integrator's knobs over the preset's.
    pub estimator: IntegratorSpec,
}

impl TileParams {
    /// The job on `scene`, every field checked against its camera's
    /// resolution and the limits (errors name the field), all before any
    /// work; the work budget is [`TileJob::check_work`]. The depth is the
    /// request's, else the scene's (what the scene's author rendered it
    /// with), else the preset's.
    pub fn job(&self, scene: &Scene, limits: &Limits) -> Result<TileJob, ApiError> {
        let area = u64::from(self.width) * u64::from(self.height);
        ApiError::check_limit("width*height", area, limits.max_tile_area as u64)?;
        let settings = self.preset.settings();
        let samples_per_pixel = self.samples_per_pixel.unwrap_or(settings.samples_per_pixel);
        ApiError::check_limit(
            "samples_per_pixel",
            u64::from(samples_per_pixel),
            limits.max_samples as u64,
        )?;
        // An explicit sample count is one pass of that many rays; otherwise
        // the preset's passes, up to `pass`.
        let passes = match self.samples_per_pixel {
            Some(_) => 1,
            None => settings.passes,
        };
        let rectangle = TileRequest {
            x: self.x,
            y: self.y,
            width: self.width,
            height: self.height,
            samples_per_pixel,
            max_depth: settings.max_depth,
            seed: self.seed,
            pass: self.pass.unwrap_or(passes - 1),
            passes,
        };
        // The rectangle first, so a request with several bad fields is told of it.
        rectangle.validate(scene.camera.resolution())?;
        let default_depth = PathDepth::for_camera(scene, settings.max_depth);
        let request = TileRequest {
            max_depth: self.max_depth.map_or(Ok(default_depth), PathDepth::new)?,
            ..rectangle
        };
        Ok(TileJob {
            request,
            integrator: resolve_integrator(self.estimator.over(settings.integrator), limits)?,
        })
    }
}

/// One progressive tile request, resolved and checked.
#[derive(Clone, Copy, Debug)]
pub struct TileJob {
    /// The rectangle, depth, seed and samples per pixel of each pass;
    /// `pass` is the last pass averaged (passes `0..=pass` are rendered) of
    /// `passes`, the preset's (1 with explicit samples per pixel).
    pub request: TileRequest,
    pub integrator: Integrator,
}

impl TileJob {
    /// Whether the output depends only on the scene's content and the job.
    pub fn reproducible(&self) -> bool {
        self.integrator.reproducible()
    }

    /// Refuses a job whose estimated paths exceed the work budget: camera
    /// paths of every pass, plus at most one record per pixel.
    pub fn check_work(&self, limits: &Limits) -> Result<(), ApiError> {
        let r = &self.request;
        let area = u64::from(r.width) * u64::from(r.height);
        let camera = area
            .saturating_mul(u64::from(r.samples_per_pixel))
            .saturating_mul(u64::from(r.pass) + 1);
        limits.check_work(self.integrator.estimated_paths(camera, area))
    }

    /// The content key of the tile's records: everything they depend on,
    /// the release included (a new release may compute them differently,
    /// so it never reads an older release's entries from the tile log).
    fn records_key(&self, scene: &LoadedScene) -> Key {
        let r = &self.request;
        let text = format!(
            "records\0{}\0{}\0{}\0{} {} {} {} {} {}",
            env!("CARGO_PKG_VERSION"),
            scene.transport.scene().digest,
            self.integrator.content_key(),
            r.x,
            r.y,
            r.width,
            r.height,
            r.max_depth,
            r.seed
        );
        *blake3::hash(text.as_bytes()).as_bytes()
    }

    /// The content key of pass `pass`.
    fn pass_key(&self, records: &Key, pass: u32) -> Key {
        let mut hasher = blake3::Hasher::new();
        hasher.update(b"pass\0");
        hasher.update(records);
        hasher.update(&self.request.samples_per_pixel.to_le_bytes());
        hasher.update(&self.request.passes.to_le_bytes());
        hasher.update(&pass.to_le_bytes());
        *hasher.finalize().as_bytes()
    }
}

/// A progressive tile and the work this request did for it.
pub struct ProgressiveTile {
    /// The mean of passes `0..=pass`.
    pub image: Image,
    /// The tile's own records (reproducible cache tiles only).
    pub records: Option<Arc<TileRecords>>,
    /// Rays traced by this request (memoised parts cost none).
    pub rays: u64,
    /// Records this request placed.
    pub records_created: u64,
    /// Diffuse shading points served by records, over the passes.
    pub cache_hits: u64,
    /// Passes this request rendered (the rest were memoised).
    pub passes_rendered: u32,
}

/// Renders `job` on the calling (pool) thread; stops once `cancel` is set.
pub fn render_progressive(
    state: &AppState,
    scene: &LoadedScene,
    job: &TileJob,
    cancel: &Cancel,
) -> Result<ProgressiveTile, ApiError> {
    let transport = &scene.transport;
    let store = &state.tiles;
    let setup = cached_setup(state, scene, &job.integrator, job.request.max_depth)?;
    let bound = job
        .integrator
        .bind(transport, setup.as_ref().map(CachedSetup::binding))?;
    let (mut rays, mut cache_hits, mut passes_rendered) = (0, 0, 0);
    let reproducible = job.reproducible();
    let records_key = job.records_key(scene);
    // Atomics, as the closures that set them may run on a pool of their own.
    let created = AtomicU64::new(0);
    // The tile's records, once for every pass.
    let records = match (bound.cached(), reproducible) {
        (Some(integrator), true) => {
            let tile_records = store.records_or(records_key, || {
                let (records, report) = integrator.tile_records(&job.request, cancel)?;
                rays += report.placement.rays + report.secondary.rays;
                created.store(report.placement.records_created, Relaxed);
                Ok::<_, ApiError>(TileRecords {
                    scene: *transport.scene().digest.as_bytes(),
                    max_depth: job.request.max_depth,
                    records,
                    report,
                })
            })?;
            Some(tile_records)
        }
        _ => None,
    };
    let mut passes = Vec::with_capacity(job.request.pass as usize + 1);
    for pass in 0..=job.request.pass {
        let request = TileRequest {
            pass,
            ..job.request
        };
        let rendered = AtomicBool::new(false);
        let render = || -> Result<RenderedPass, ApiError> {
            rendered.store(true, Relaxed);
            let (tile, cache_hits) = match (bound.cached(), &records) {
                (Some(i), Some(records)) => {
                    let dense = records.report.dense();
                    let (tile, stats) =
                        i.render_tile_from_records(&request, &records.records, dense, cancel)?;
                    (tile, stats.cache_hits)
                }
                _ => {
                    let (tile, report) = bound.render_tile(&request, cancel)?;
                    created.fetch_add(report.placement.records_created, Relaxed);
                    (tile, report.shading.cache_hits)
                }
            };
            Ok(RenderedPass {
                image: tile.image,
                shared: tile.shared,
                rays: tile.rays,
                cache_hits,
            })
        };
        let pass_image = if reproducible {
            let key = job.pass_key(&records_key, pass);
            store.pass_or(key, render)?
        } else {
            Arc::new(render()?)
        };
        if rendered.load(Relaxed) {
            rays += pass_image.rays;
            passes_rendered += 1;
        }
        cache_hits += pass_image.cache_hits;
        passes.push(pass_image);
    }
    // A reproducible tile's records stay out of the shared cache: point
    // queries meet them through the tile store (`tile_priors`), the same
    // on every replica whichever of them rendered the tile.
    let records_created = created.into_inner();
    Ok(ProgressiveTile {
        image: mean_of_passes(&passes)?,
        records,
        rays,
        records_created,
        cache_hits,
        passes_rendered,
    })
}

/// The mean of the passes' images, with its variance: their own noise
/// averages out ([`Image::mean_of`] divides the sum of the variances by
/// `n²`), the records' error they share does not, so its mean over the
/// passes is the shared part's variance of the mean (docs/math.md §16.3).
fn mean_of_passes(passes: &[Arc<RenderedPass>]) -> Result<Image, ApiError> {
    let images: Vec<&Image> = passes.iter().map(|p| &p.image).collect();
    let mean = Image::mean_of(&images)?;
    let n = passes.len() as f64;
    let Some(variance) = mean.variance() else {
        return Ok(mean);
    };
    let variance = variance
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let shared: f64 = passes
                .iter()
                .filter_map(|p| p.shared.get(i))
                .map(|&s| f64::from(s))
                .sum();
            (f64::from(v) + shared * (n - 1.0) / (n * n)) as f32
        })
        .collect();
    Ok(Image::from_parts(
        mean.width(),
        mean.height(),
        mean.rgb().to_vec(),
        Some(variance),
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneError;
    use crate::service::config::Config;

    /// The Cornell box, with `max_depth` in its document when given.
    fn cornell(max_depth: Option<u32>) -> Result<Scene, SceneError> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let text = std::fs::read_to_string(dir.join("cornell-box.json")).expect("bundled scene");
        let mut doc: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        if let Some(d) = max_depth {
            doc["max_depth"] = d.into();
        }
        Scene::from_json_str(&doc.to_string(), &dir, &dir)
    }

    #[test]
    fn the_depth_is_the_requests_else_the_scenes_else_the_presets() {
        let limits = Config::default_config().limits;
        let depth = |scene: &Scene, max_depth| {
            let params = TileParams {
                x: 0,
                y: 0,
                width: 8,
                height: 8,
                preset: Preset::Draft,
                samples_per_pixel: None,
                pass: None,
                max_depth,
                seed: 1,
                estimator: IntegratorSpec::default(),
            };
            params
                .job(scene, &limits)
                .expect("valid")
                .request
                .max_depth
                .get()
        };
        let (plain, deep) = (cornell(None).unwrap(), cornell(Some(3)).unwrap());
        assert_eq!(
            depth(&plain, None),
            Preset::Draft.settings().max_depth.get()
        );
        assert_eq!(depth(&deep, None), 3);
        assert_eq!(depth(&deep, Some(5)), 5);
        let refused = cornell(Some(0)).err().expect("depth 0 refused");
        assert_eq!(refused.field(), Some("max_depth"));
    }

    /// Two passes of one pixel, each of variance 3 of which 2 is shared:
    /// the mean's own part halves (1 → 0.5), the shared part stays 2.
    #[test]
    fn passes_average_their_own_noise_but_not_the_records_error() {
        let pass = |value: f32| {
            Arc::new(RenderedPass {
                image: Image::from_parts(1, 1, vec![[value; 3]], Some(vec![3.0])).unwrap(),
                shared: vec![2.0],
                rays: 1,
                cache_hits: 0,
            })
        };
        let mean = mean_of_passes(&[pass(1.0), pass(3.0)]).unwrap();
        assert_eq!(mean.pixel(0, 0), Some([2.0; 3]));
        assert_eq!(mean.variance(), Some(&[2.5][..]));
        let one = mean_of_passes(&[pass(1.0)]).unwrap();
        assert_eq!(one.variance(), Some(&[3.0][..]));
    }
}

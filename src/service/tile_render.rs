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
use crate::image::{Image, ImageError, denoise};
use crate::integrator::{Integrator, IntegratorSpec, Preset};
use crate::render::{Cancel, PathDepth, SamplePlan, TileRequest};
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
    /// Filter the averaged passes with the tile's guides (docs/math.md §16.6).
    pub denoise: bool,
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
            denoise: self.denoise,
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
    /// Whether the averaged passes are denoised ([`crate::image::denoise`]).
    pub denoise: bool,
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

    /// The rays per pixel of the pass after `before` (docs/math.md §16.5):
    /// none for a single pass (every pixel its `samples_per_pixel`); for a
    /// preset's ladder of passes, `samples_per_pixel` each in the first,
    /// then as the first pass's standard errors around each pixel ask.
    fn plan(&self, before: &[Arc<RenderedPass>]) -> Result<Option<SamplePlan>, ApiError> {
        let r = &self.request;
        if r.passes < 2 {
            return Ok(None);
        }
        let area = r.width as usize * r.height as usize;
        if before.is_empty() {
            return Ok(Some(SamplePlan::uniform(
                area,
                r.samples_per_pixel,
                r.passes,
            )));
        }
        let first = mean_of_passes(&before[..1], r.samples_per_pixel)?;
        let rays = mean_of_passes(before, r.samples_per_pixel)?.rays;
        Ok(Some(SamplePlan::adaptive(
            r.samples_per_pixel,
            r.passes,
            r.width as usize,
            &first.own_variance,
            &rays,
        )))
    }

    /// The content key of pass `pass`.
    fn pass_key(&self, records: &Key, pass: u32) -> Key {
        let mut hasher = blake3::Hasher::new();
        // Passes of a ladder take their rays per pixel from the passes
        // before (`Self::plan`), which older entries did not.
        hasher.update(b"adaptive pass\0");
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
            let plan = job.plan(&passes)?;
            let plan = plan.as_ref();
            let (tile, cache_hits) = match (bound.cached(), &records) {
                (Some(i), Some(records)) => {
                    let dense = records.report.dense();
                    let (tile, stats) = i.render_tile_from_records(
                        &request,
                        plan,
                        &records.records,
                        dense,
                        cancel,
                    )?;
                    (tile, stats.cache_hits)
                }
                _ => {
                    let (tile, report) = bound.render_tile(&request, plan, cancel)?;
                    created.fetch_add(report.placement.records_created, Relaxed);
                    (tile, report.shading.cache_hits)
                }
            };
            Ok(RenderedPass {
                image: tile.image,
                shared: tile.shared,
                counts: plan.map(|p| p.counts.clone()).unwrap_or_default(),
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
    let mut image = mean_of_passes(&passes, job.request.samples_per_pixel)?.image;
    if job.denoise {
        cancel.check()?;
        let r = &job.request;
        let (guides, guide_rays) = transport.guide_buffers(r.x, r.y, r.width, r.height);
        rays += guide_rays;
        image = denoise(&image, &guides)?;
    }
    Ok(ProgressiveTile {
        image,
        records,
        rays,
        records_created,
        cache_hits,
        passes_rendered,
    })
}

/// The mean of a tile's passes: each pixel's rays over all of them
/// averaged (passes weighted by the rays they gave the pixel), its own noise
/// averaging out as `Σ_k n_k² own_k / N²` but at least the per-ray variance
/// of its passes of two rays or more over `N` (an adaptive pass's one-ray
/// pixels measure no spread of their own), and the records' error the
/// passes share weighted as `Σ_k n_k shared_k / N` (it does not average
/// out, docs/math.md §16.3, §16.5). Equal rays give the plain mean of the
/// images.
struct PassesMean {
    image: Image,
    /// Per pixel, the variance of the mean's own noise (its shared part
    /// left out), what more rays lower.
    own_variance: Vec<f32>,
    /// Per pixel, the rays over all passes.
    rays: Vec<u32>,
}

/// [`PassesMean`] of `passes`, a pass without per-pixel counts having
/// `spp` rays in every pixel.
fn mean_of_passes(passes: &[Arc<RenderedPass>], spp: u32) -> Result<PassesMean, ApiError> {
    let Some(first) = passes.first() else {
        return Err(ApiError::invalid("pass", "no pass to average"));
    };
    let (width, height) = (first.image.width(), first.image.height());
    // Passes of one tile share its size; a pass read from elsewhere (the
    // log, another replica) that does not is refused, not indexed past.
    if let Some(other) = passes
        .iter()
        .find(|p| (p.image.width(), p.image.height()) != (width, height))
    {
        return Err(ImageError::invalid(
            "images",
            format!(
                "passes of {width}×{height} and {}×{} differ",
                other.image.width(),
                other.image.height()
            ),
        )
        .into());
    }
    let area = first.image.rgb().len();
    let rays_of = |p: &RenderedPass, i: usize| f64::from(p.counts.get(i).copied().unwrap_or(spp));
    let mut rgb = Vec::with_capacity(area);
    let mut variance = Vec::with_capacity(area);
    let mut own_variance = Vec::with_capacity(area);
    let mut rays = Vec::with_capacity(area);
    for i in 0..area {
        let total: f64 = passes.iter().map(|p| rays_of(p, i)).sum();
        let mut value = [0.0f64; 3];
        let (mut own, mut shared) = (0.0f64, 0.0f64);
        // The per-ray variance over the passes of two rays or more, weighted
        // by their degrees of freedom: a pass of one ray measures none.
        let (mut per_ray, mut dof) = (0.0f64, 0.0f64);
        for p in passes {
            let n = rays_of(p, i);
            for (c, v) in value.iter_mut().enumerate() {
                *v += n * f64::from(p.image.rgb()[i][c]);
            }
            let s = f64::from(p.shared.get(i).copied().unwrap_or(0.0));
            let v = p.image.variance().map_or(0.0, |v| f64::from(v[i]));
            own += n * n * (v - s).max(0.0);
            shared += n * s;
            if n >= 2.0 {
                per_ray += (n - 1.0) * n * (v - s).max(0.0);
                dof += n - 1.0;
            }
        }
        rgb.push(value.map(|v| (v / total) as f32));
        own /= total * total;
        if dof > 0.0 {
            own = own.max(per_ray / dof / total);
        }
        shared /= total;
        variance.push((own + shared) as f32);
        own_variance.push(own as f32);
        rays.push(total as u32);
    }
    let has_variance = passes.iter().all(|p| p.image.variance().is_some());
    let image = Image::from_parts(width, height, rgb, has_variance.then_some(variance))?;
    Ok(PassesMean {
        image,
        own_variance,
        rays,
    })
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
                denoise: false,
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
    /// with equal rays the mean's own part halves (1 → 0.5) and the shared
    /// part stays 2; with 1 and 3 rays the values weigh 1 : 3, the own part
    /// is (1 + 9) / 16 and the shared part still 2.
    #[test]
    fn passes_average_their_own_noise_but_not_the_records_error() {
        let pass = |value: f32, counts: Vec<u32>| {
            Arc::new(RenderedPass {
                image: Image::from_parts(1, 1, vec![[value; 3]], Some(vec![3.0])).unwrap(),
                shared: vec![2.0],
                counts,
                rays: 1,
                cache_hits: 0,
            })
        };
        let mean = mean_of_passes(&[pass(1.0, vec![]), pass(3.0, vec![])], 4).unwrap();
        assert_eq!(mean.image.pixel(0, 0), Some([2.0; 3]));
        assert_eq!(mean.image.variance(), Some(&[2.5][..]));
        assert_eq!((mean.own_variance, mean.rays), (vec![0.5], vec![8]));
        let one = mean_of_passes(&[pass(1.0, vec![])], 4).unwrap();
        assert_eq!(one.image.variance(), Some(&[3.0][..]));
        let weighted = mean_of_passes(&[pass(1.0, vec![1]), pass(3.0, vec![3])], 4).unwrap();
        assert_eq!(weighted.image.pixel(0, 0), Some([2.5; 3]));
        // Own: (1 + 9) / 16 = 0.625 against the 3-ray pass's per-ray 3 over
        // 4 rays, 0.75; plus the shared 2.
        assert_eq!(weighted.image.variance(), Some(&[2.75][..]));
        assert_eq!(weighted.rays, [4]);
    }

    /// A preset's ladder: the first pass uniform, the next one's rays where
    /// the first pass was noisy two pixels away, adding up to the pass's
    /// rays; a single pass has no plan.
    #[test]
    fn a_ladder_plans_its_passes_from_the_first() {
        let limits = Config::default_config().limits;
        let scene = cornell(None).unwrap();
        let params = TileParams {
            x: 0,
            y: 0,
            width: 8,
            height: 8,
            preset: Preset::Preview,
            samples_per_pixel: None,
            pass: None,
            max_depth: None,
            seed: 1,
            estimator: IntegratorSpec::default(),
            denoise: false,
        };
        let job = params.job(&scene, &limits).unwrap();
        let spp = job.request.samples_per_pixel;
        let first = job.plan(&[]).unwrap().expect("a ladder");
        assert_eq!(first.counts, vec![spp; 64]);
        // Noise only in columns 6 and 7.
        let variance = (0..64)
            .map(|i| if i % 8 >= 6 { 1.0 } else { 0.0 })
            .collect();
        let pass = Arc::new(RenderedPass {
            image: Image::from_parts(8, 8, vec![[1.0; 3]; 64], Some(variance)).unwrap(),
            shared: vec![],
            counts: vec![],
            rays: 0,
            cache_hits: 0,
        });
        let next = job.plan(&[pass]).unwrap().expect("a ladder");
        assert_eq!(next.counts.iter().sum::<u32>(), 64 * spp);
        assert_eq!(next.firsts, vec![spp; 64]);
        for (i, &n) in next.counts.iter().enumerate() {
            match i % 8 {
                // Two or more columns from the noise: one ray.
                0..=3 => assert_eq!(n, 1, "pixel {i}"),
                _ => assert!(n > spp && n <= 4 * spp, "pixel {i}: {n}"),
            }
        }
        let single = TileParams {
            samples_per_pixel: Some(4),
            ..params
        };
        assert!(
            single
                .job(&scene, &limits)
                .unwrap()
                .plan(&[])
                .unwrap()
                .is_none()
        );
    }
}

//! Progressive tiles: the passes of a preset (or of explicit knobs) up to a
//! requested one, averaged (docs/math.md §16.5), the same for the service's
//! tile routes and the command line's `render --preset`.
//!
//! A reproducible tile's records are those of the record blocks around it
//! (`integrator::cached::tiles`, "Record blocks"), placed once per block and
//! shared by its passes and by the tiles around; what a caller keeps of
//! them and of the passes between requests (the service's tile store) is a
//! [`PassMemo`]; [`HeldBlocks`] keeps the blocks for one render.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

use super::{BoundIntegrator, Integrator, IntegratorSpec, Preset};
use crate::cache::Record;
use crate::image::{Image, denoise};
use crate::integrator::cached::{CachedTileReport, RecordBlock, block_margin, record_blocks};
use crate::render::{
    Cancel, PathDepth, RenderError, RenderedTile, SamplePlan, TileRequest, Transport,
};
use crate::scene::Scene;

/// A tile as a caller names it, before any check: the rectangle, the
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
    /// Denoise the averaged passes with the tile's guides (docs/math.md
    /// §16.6, §16.7); `None`: as the preset does on the scene.
    pub denoise: Option<bool>,
}

impl TileParams {
    /// The rectangle, samples and passes on `scene`, checked against its
    /// camera's resolution (errors name the field). An explicit sample
    /// count is one pass of that many rays, otherwise the preset's passes
    /// up to `pass`. The depth is the request's, else the scene's (what the
    /// scene's author rendered it with), else the preset's.
    pub fn request(&self, scene: &Scene) -> Result<TileRequest, RenderError> {
        let settings = self.preset.settings_on(scene);
        let passes = match self.samples_per_pixel {
            Some(_) => 1,
            None => settings.passes,
        };
        let rectangle = TileRequest {
            x: self.x,
            y: self.y,
            width: self.width,
            height: self.height,
            samples_per_pixel: self.samples_per_pixel.unwrap_or(settings.samples_per_pixel),
            max_depth: settings.max_depth,
            seed: self.seed,
            pass: self.pass.unwrap_or(passes - 1),
            passes,
        };
        // The rectangle first, so a request with several bad fields is told of it.
        rectangle.validate(scene.camera.resolution())?;
        let default_depth = PathDepth::for_camera(scene, settings.max_depth);
        Ok(TileRequest {
            max_depth: self.max_depth.map_or(Ok(default_depth), PathDepth::new)?,
            ..rectangle
        })
    }

    /// The integrator's knobs on `scene`: the request's over the preset's.
    /// Cache knobs named on a scene the preset path traces are taken over
    /// the preset's cache settings; none named leaves the preset's choice.
    pub fn integrator_spec(&self, scene: &Scene) -> IntegratorSpec {
        match self.estimator {
            IntegratorSpec::Cache(knobs) if knobs == Default::default() => {
                self.preset.settings_on(scene).integrator
            }
            named => named.over(self.preset.settings().integrator),
        }
    }

    /// Whether the tile is denoised on `scene`: as asked, else as the
    /// preset does there.
    pub fn denoise(&self, scene: &Scene) -> bool {
        self.denoise
            .unwrap_or_else(|| self.preset.settings_on(scene).denoise)
    }

    /// The job on `scene`, every field checked (errors name the field).
    pub fn job(&self, scene: &Scene) -> Result<TileJob, RenderError> {
        Ok(TileJob {
            request: self.request(scene)?,
            integrator: self.integrator_spec(scene).resolve()?,
            denoise: self.denoise(scene),
        })
    }
}

/// One progressive tile, resolved and checked.
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

    /// Whether the tile is denoised by a filter that sees beyond it (OIDN,
    /// in a build with the `oidn` feature; [`TileJob::context`]).
    fn denoised_in_context(&self) -> bool {
        self.denoise && cfg!(feature = "oidn")
    }

    /// The passes that make the tile on an image of `resolution`: the
    /// request itself, or for a tile denoised by a filter that sees far,
    /// the tile and [`DENOISER_MARGIN`] within the image (so
    /// a pixel near the tile's edge is denoised with the pixels around it
    /// as in the whole image: no tile seams), each pass of an even number
    /// of rays rendered as two passes of half as many (so even the first
    /// has two independent halves to measure the denoised error from,
    /// docs/math.md §16.7; the rays per pixel are the request's).
    pub fn context(&self, resolution: (u32, u32)) -> TileRequest {
        let r = self.request;
        if !self.denoised_in_context() {
            return r;
        }
        let r = if r.samples_per_pixel.is_multiple_of(2) {
            TileRequest {
                samples_per_pixel: r.samples_per_pixel / 2,
                passes: 2 * r.passes,
                pass: 2 * r.pass + 1,
                ..r
            }
        } else {
            r
        };
        let (x0, y0) = (
            r.x.saturating_sub(DENOISER_MARGIN),
            r.y.saturating_sub(DENOISER_MARGIN),
        );
        let x1 = (r.x + r.width + DENOISER_MARGIN).min(resolution.0.max(r.x + r.width));
        let y1 = (r.y + r.height + DENOISER_MARGIN).min(resolution.1.max(r.y + r.height));
        TileRequest {
            x: x0,
            y: y0,
            width: x1 - x0,
            height: y1 - y0,
            ..r
        }
    }

    /// Camera paths of every pass plus at most one record per pixel of
    /// the record blocks it may place (on an image of `resolution`): what a
    /// work budget weighs.
    pub fn estimated_paths(&self, resolution: (u32, u32)) -> u64 {
        let r = &self.context(resolution);
        let area = u64::from(r.width) * u64::from(r.height);
        let camera = area
            .saturating_mul(u64::from(r.samples_per_pixel))
            .saturating_mul(u64::from(r.pass) + 1);
        // A reproducible tile may place the records of every block around it.
        let records = match self.integrator.cached() {
            Some(c) if self.reproducible() => {
                let blocks = record_blocks(r, block_margin(c.options.max_pixels), resolution);
                blocks
                    .iter()
                    .map(|b| u64::from(b.width) * u64::from(b.height))
                    .sum()
            }
            _ => area,
        };
        self.integrator.estimated_paths(camera, records)
    }

    /// The rays per pixel of the pass after `before` (docs/math.md §16.5):
    /// none for a single pass or a tile OIDN denoises (every pixel its
    /// `samples_per_pixel`); for a preset's ladder of passes,
    /// `samples_per_pixel` each in the first,
    /// then as the first pass's standard errors around each pixel ask.
    /// The passes cover `rect` (the tile or its [`TileJob::context`]).
    pub fn plan(
        &self,
        rect: &TileRequest,
        before: &[Arc<RenderedPass>],
    ) -> Result<Option<SamplePlan>, RenderError> {
        let r = rect;
        // OIDN denoises images of even noise better than images whose rays
        // went where the first pass was noisiest (docs/math.md §16.7).
        if r.passes < 2 || self.denoised_in_context() {
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
}

/// The records of one record block (or of a tile placing its own), and
/// what placing them took.
pub struct TileRecords {
    /// The content digest of the scene they belong to (`scene::SceneDigest`).
    pub scene: [u8; 32],
    /// Path segments the records' camera paths had, the camera's included
    /// (what point queries need to know to use them as a prior).
    pub max_depth: PathDepth,
    pub records: Vec<Record>,
    pub report: CachedTileReport,
}

/// One rendered pass of a tile.
pub struct RenderedPass {
    pub image: Image,
    /// Per pixel, the part of the image's variance its rays share
    /// (`render::RenderedTile::shared`); empty for an image without one.
    pub shared: Vec<f32>,
    /// Per pixel, the rays of an adaptive pass (`render::SamplePlan`);
    /// empty when every pixel took the request's `samples_per_pixel`.
    pub counts: Vec<u32>,
    /// Rays the pass traced (camera and shading rays).
    pub rays: u64,
    /// Diffuse shading points served by records.
    pub cache_hits: u64,
}

/// What a caller keeps of a reproducible tile's work between requests:
/// its records and each pass, computed by the closure given when not kept.
/// Only reproducible jobs consult it (their output is a function of the
/// scene and the job).
pub trait PassMemo {
    /// The records of `block` (a rectangle of the block grid with the job's
    /// depth and seed), placed by `place` unless kept.
    fn records_or(
        &self,
        block: &TileRequest,
        place: impl FnOnce() -> Result<TileRecords, RenderError> + Send,
    ) -> Result<Arc<TileRecords>, RenderError>;

    /// The pass `request` names (its rectangle and `pass`), rendered by
    /// `render` unless kept.
    fn pass_or(
        &self,
        request: &TileRequest,
        render: impl FnOnce() -> Result<RenderedPass, RenderError> + Send,
    ) -> Result<Arc<RenderedPass>, RenderError>;
}

/// Keeps the record blocks' records in memory, passes not: the memo of one
/// render of an image with one job's settings (the blocks are told apart
/// by their corner only).
pub struct HeldBlocks {
    records: moka::sync::Cache<[u32; 2], Arc<TileRecords>>,
}

impl Default for HeldBlocks {
    fn default() -> Self {
        Self {
            records: moka::sync::Cache::new(u64::MAX),
        }
    }
}

impl HeldBlocks {
    /// What placing the held blocks took, each counted once.
    pub fn report(&self) -> CachedTileReport {
        let mut report = CachedTileReport::default();
        for (_, block) in self.records.iter() {
            report.add(&block.report);
        }
        report
    }
}

impl PassMemo for HeldBlocks {
    fn records_or(
        &self,
        block: &TileRequest,
        place: impl FnOnce() -> Result<TileRecords, RenderError> + Send,
    ) -> Result<Arc<TileRecords>, RenderError> {
        // Tiles rendered in parallel wait for a block another is placing.
        crate::isolated::try_get_with(&self.records, [block.x, block.y], || place().map(Arc::new))
            .map_err(|e: Arc<RenderError>| (*e).clone())
    }

    fn pass_or(
        &self,
        _request: &TileRequest,
        render: impl FnOnce() -> Result<RenderedPass, RenderError> + Send,
    ) -> Result<Arc<RenderedPass>, RenderError> {
        render().map(Arc::new)
    }
}

/// A progressive tile and the work this call did for it.
pub struct ProgressiveTile {
    /// The mean of passes `0..=pass`.
    pub image: Image,
    /// The records of the blocks that shaded it (reproducible cache tiles
    /// only), row-major.
    pub records: Vec<Arc<TileRecords>>,
    /// Rays traced by this call (kept parts cost none).
    pub rays: u64,
    /// Records this call placed.
    pub records_created: u64,
    /// Diffuse shading points served by records, over the passes.
    pub cache_hits: u64,
    /// Passes this call rendered (the rest were kept by `memo`).
    pub passes_rendered: u32,
}

impl ProgressiveTile {
    /// The tile as a rendered tile of `request`'s corner (its image and rays).
    pub fn into_rendered(self, request: &TileRequest) -> RenderedTile {
        RenderedTile {
            x: request.x,
            y: request.y,
            image: self.image,
            shared: Vec::new(),
            rays: self.rays,
        }
    }
}

/// Renders `job` with `bound` (its integrator bound to `transport`) on the
/// calling thread, consulting `memo` for a reproducible job's records and
/// passes; stops once `cancel` is set.
pub fn render_progressive(
    transport: &Transport,
    bound: &BoundIntegrator,
    job: &TileJob,
    memo: &impl PassMemo,
    cancel: &Cancel,
) -> Result<ProgressiveTile, RenderError> {
    let (mut rays, mut cache_hits, mut passes_rendered) = (0, 0, 0u32);
    let reproducible = job.reproducible();
    // The passes as rendered: the tile's, or for a denoiser that needs to
    // see around it, over the tile and a margin (cropped at the end), each
    // split in two halves (`TileJob::context`).
    let context = job.context(transport.scene().camera.resolution());
    // Atomics, as the closures that set them may run on a pool of their own.
    let created = AtomicU64::new(0);
    // The records of the blocks around the tile, once for every pass.
    let mut records = Vec::new();
    let mut rects = Vec::new();
    if let (Some(integrator), true) = (bound.cached(), reproducible) {
        for block in integrator.record_blocks(&context) {
            rects.push([block.x, block.y, block.width, block.height]);
            records.push(memo.records_or(&block, || {
                let (records, report) = integrator.tile_records(&block, cancel)?;
                rays += report.placement.rays + report.secondary.rays;
                created.fetch_add(report.placement.records_created, Relaxed);
                Ok(TileRecords {
                    scene: *transport.scene().digest.as_bytes(),
                    max_depth: block.max_depth,
                    records,
                    report,
                })
            })?);
        }
    }
    let blocks: Vec<RecordBlock> = records
        .iter()
        .zip(rects)
        .map(|(b, rect)| RecordBlock {
            rect,
            records: &b.records,
            dense: b.report.dense(),
        })
        .collect();
    let mut passes = Vec::with_capacity(context.pass as usize + 1);
    for pass in 0..=context.pass {
        let request = TileRequest { pass, ..context };
        let rendered = AtomicBool::new(false);
        let render = || -> Result<RenderedPass, RenderError> {
            rendered.store(true, Relaxed);
            let plan = job.plan(&context, &passes)?;
            let plan = plan.as_ref();
            let (tile, cache_hits) = match (bound.cached(), reproducible) {
                (Some(i), true) => {
                    let (tile, stats) =
                        i.render_tile_from_blocks(&request, plan, &blocks, cancel)?;
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
            memo.pass_or(&request, render)?
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
    let records_created = created.into_inner();
    // Passes counted as the request counts them (a pass split in two is one).
    let passes_rendered = passes_rendered.div_ceil(context.passes / job.request.passes);
    let spp = context.samples_per_pixel;
    let mut image = mean_of_passes(&passes, spp)?.image;
    if job.denoise {
        cancel.check()?;
        let c = &context;
        let (guides, guide_rays) = transport.guide_buffers(c.x, c.y, c.width, c.height);
        rays += guide_rays;
        image = denoised(image, &passes, spp, &guides)?;
        let r = &job.request;
        image = image.crop(r.x - c.x, r.y - c.y, r.width, r.height)?;
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

/// Pixels of context a tile OIDN denoises is rendered with on each side:
/// its network sees far beyond a pixel's neighbours (the guided filter of
/// docs/math.md §16.6 sees its tile only).
pub const DENOISER_MARGIN: u32 = 16;

/// `image`, the mean of `passes` (`spp` rays per pixel where a pass has no
/// counts), denoised with `guides`: by OIDN when the build has it and there
/// are two passes or more to measure its error from (docs/math.md §16.7),
/// else by the guided filter that keeps each pixel's own error bar (§16.6).
fn denoised(
    image: Image,
    passes: &[Arc<RenderedPass>],
    spp: u32,
    guides: &crate::image::GuideBuffers,
) -> Result<Image, RenderError> {
    #[cfg(feature = "oidn")]
    if passes.len() >= 2 {
        // Even and odd passes: two independent renders of the same pixels.
        let half = |first: usize| {
            let own: Vec<_> = passes.iter().skip(first).step_by(2).cloned().collect();
            mean_of_passes(&own, spp)
        };
        let (a, b) = (half(0)?, half(1)?);
        // Var(F) = n_a n_b / (n_a + n_b)² · Var(A − B) for the mean F of
        // halves of n_a and n_b rays (docs/math.md §16.7).
        let scale: Vec<f64> = a
            .rays
            .iter()
            .zip(&b.rays)
            .map(|(&na, &nb)| {
                let (na, nb) = (f64::from(na), f64::from(nb));
                na * nb / ((na + nb) * (na + nb))
            })
            .collect();
        return Ok(crate::image::oidn::denoise_with_halves(
            &image,
            [&a.image, &b.image],
            &scale,
            guides,
        )?);
    }
    let _ = (passes, spp);
    Ok(denoise(&image, guides)?)
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
fn mean_of_passes(passes: &[Arc<RenderedPass>], spp: u32) -> Result<PassesMean, RenderError> {
    let Some(first) = passes.first() else {
        return Err(RenderError::InvalidOption {
            field: "pass",
            reason: "no pass to average".into(),
        });
    };
    let (width, height) = (first.image.width(), first.image.height());
    // Passes of one tile share its size; a pass read from elsewhere (the
    // log, another replica) that does not is refused, not indexed past.
    if let Some(other) = passes
        .iter()
        .find(|p| (p.image.width(), p.image.height()) != (width, height))
    {
        return Err(RenderError::Image {
            reason: format!(
                "passes of {width}×{height} and {}×{} differ",
                other.image.width(),
                other.image.height()
            ),
        });
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
mod tests;

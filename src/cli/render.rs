//! The `render` and `compare` subcommands: the scene camera's image to EXR
//! (and optionally PNG), and the relative RMSE between two EXR images.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use super::in_thread_pool;
use super::scene_args::SceneArgs;
use crate::bmc::cache::QuadratureCache;
use crate::cache::{CacheConfig, IrradianceCache};
use crate::image::exr_io::{read_exr, write_exr};
use crate::image::png_io::write_png;
use crate::image::{ToneMap, relative_rmse};
use crate::integrator::cached::{CachedSpec, CachedTileReport};
use crate::integrator::progressive::{HeldBlocks, TileJob, TileParams, render_progressive};
use crate::integrator::{Integrator, IntegratorSpec, Method, Preset};
use crate::render::{Cancel, ImageSettings, PathDepth, RenderError, TileRequest, Transport};
use crate::scene::Scene;

/// Command-line arguments of `bmc-irradiance render`.
#[derive(Clone, Debug, clap::Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub output: ImageOutput,
    /// How camera rays are shaded.
    #[arg(long, value_enum, default_value_t = Method::Path)]
    pub method: Method,
    /// Render every tile as the service's tiles of this preset are (the
    /// cache integrator, the preset's passes averaged; with the same
    /// `--tile` as the tiles' `size`, the same image as `GET …/tiles` of
    /// the preset). `--spp`, `--max-depth` and the cache settings override
    /// the preset's, as they do on a tile request.
    #[arg(long, value_enum, conflicts_with_all = ["method", "repeat"])]
    pub preset: Option<Preset>,
    /// Denoise each tile (`true`) or not (`false`) as the tiles' `denoise`
    /// does (with `--preset`): OIDN in a build with the `oidn` feature, else
    /// the guided filter of docs/math.md §16.6. Default: as the preset does
    /// on the scene.
    #[arg(long, requires = "preset")]
    pub denoise: Option<bool>,
    /// Camera rays per pixel (default 64; with `--preset`, the preset's
    /// passes, or one pass of this many rays).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Longest light path in segments (1 = emitters seen directly only);
    /// default: the scene's (its Mitsuba integrator's `max_depth`), else the
    /// service's (16).
    #[arg(long, value_parser = super::max_depth_parser())]
    pub max_depth: Option<PathDepth>,
    /// Seed of all random streams; same seed, same image.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Tile side in pixels. The image does not depend on it with `--method
    /// path` (nor with `--method cache --reproducible`).
    #[arg(long, default_value_t = 64)]
    pub tile: u32,
    /// Irradiance cache settings (`--method cache`).
    #[command(flatten)]
    pub cache: CachedSpec,
    /// Render the image this many times on the same cache (2 times the
    /// warm cache); the first render's image is written.
    #[arg(long, default_value_t = 1, alias = "passes")]
    pub repeat: u32,
}

/// Camera rays per pixel without `--spp` or `--preset`.
const DEFAULT_SPP: u32 = 64;

/// Byte bound of the CLI's glossy quadrature cache.
const QUADRATURE_BYTES: u64 = 256 << 20;

impl RenderArgs {
    /// The image settings on `scene`.
    pub fn settings(&self, scene: &Scene) -> ImageSettings {
        ImageSettings {
            samples_per_pixel: self.spp.unwrap_or(DEFAULT_SPP),
            max_depth: self
                .max_depth
                .unwrap_or_else(|| PathDepth::for_camera(scene, PathDepth::default())),
            seed: self.seed,
        }
    }
}

/// Runs `render`: progress on stderr (hidden when it is not a terminal),
/// a one-line summary (time, rays, rays/s) on `out`.
pub fn run_render(args: &RenderArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let loading = Instant::now();
    let scene = args.scene.load(&mut std::io::stderr())?;
    let (width, height) = scene.camera.resolution();
    let settings = args.settings(&scene);
    let triangles = scene.triangle_count();
    let transport = Transport::new(Arc::new(scene));
    writeln!(
        out,
        "loaded {triangles} triangles in {:.2} s",
        loading.elapsed().as_secs_f64()
    )?;
    // Fail on a bad request before any work (the first tile would too).
    settings
        .tile(0, 0, width, height)
        .validate((width, height))?;

    let progress = ProgressBar::new(u64::from(width) * u64::from(height));
    progress.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} pixels, {elapsed} elapsed, ETA {eta}")
            .context("progress bar template")?,
    );
    let start = Instant::now();
    // With a preset, each tile is its progressive job (the preset's knobs
    // under the arguments'), all of one integrator.
    let tile_params = args.preset.map(|preset| TileParams {
        x: 0,
        y: 0,
        width,
        height,
        preset,
        samples_per_pixel: args.spp,
        pass: None,
        max_depth: args.max_depth.map(PathDepth::get),
        seed: args.seed,
        estimator: IntegratorSpec::Cache(args.cache),
        denoise: args.denoise,
    });
    let (integrator, spp) = match &tile_params {
        Some(params) => {
            let job = params.job(transport.scene())?;
            let r = job.request;
            (job.integrator, r.samples_per_pixel * (r.pass + 1))
        }
        None => (
            IntegratorSpec::with_knobs(args.method, args.cache)?.resolve()?,
            settings.samples_per_pixel,
        ),
    };
    let cache = IrradianceCache::new(CacheConfig::default())?;
    let quadratures = Arc::new(QuadratureCache::new(QUADRATURE_BYTES));
    let shading = integrator
        .cached()
        .map(|c| c.shading(quadratures))
        .transpose()?;
    let bound = integrator.bind(&transport, shading.as_ref().map(|s| (&cache, s)))?;
    let mut first = None;
    for pass in 1..=args.repeat.max(1) {
        progress.reset();
        let pass_start = Instant::now();
        let report = Mutex::new(CachedTileReport::default());
        // A preset's record blocks, each placed once for the tiles around it.
        let blocks = HeldBlocks::default();
        let render = || {
            transport.render_image_by(&settings, args.tile, &|request| {
                let (tile, r) = match &tile_params {
                    Some(params) => {
                        let job = preset_job(&transport, integrator, params, request)?;
                        let tile = render_progressive(
                            &transport,
                            &bound,
                            &job,
                            &blocks,
                            &Cancel::never(),
                        )?;
                        (tile.into_rendered(request), CachedTileReport::default())
                    }
                    None => bound.render_tile(request, None, &Cancel::never())?,
                };
                report.lock().unwrap_or_else(|e| e.into_inner()).add(&r);
                progress.inc(u64::from(tile.image.width()) * u64::from(tile.image.height()));
                Ok(tile)
            })
        };
        let rendered = in_thread_pool(args.threads, render)??;
        let seconds = pass_start.elapsed().as_secs_f64();
        let mut r = report.into_inner().unwrap_or_else(|e| e.into_inner());
        r.add(&blocks.report());
        if bound.cached().is_some() {
            let stats = cache.stats();
            progress.suspend(|| {
                writeln!(
                    out,
                    "pass {pass}: {seconds:.2} s, {} rays; {} records created ({} at ambient \
                     bounces; {} placement rays, {} records' rays fell back to a path), \
                     {} in the secondary cache ({} rays), {} in cache; shading: {} hits ({} relaxed), {} path-traced fallbacks, \
                     {} glossy BMC ({} lobe-sampled by the negative-weight guard), \
                     {} glossy path-traced; {} tiles too dense for records ({} probe rays)",
                    rendered.rays,
                    r.placement.records_created,
                    r.placement.ambient_records,
                    r.placement.rays,
                    r.placement.fallbacks,
                    r.secondary.records_created,
                    r.secondary.rays,
                    stats.records,
                    r.shading.cache_hits,
                    r.shading.relaxed_hits,
                    r.shading.fallbacks,
                    r.shading.glossy_bmc,
                    r.shading.glossy_fallbacks,
                    r.shading.glossy_path_traced,
                    r.dense_tiles,
                    r.probe_rays,
                )
            })?;
        }
        first.get_or_insert(rendered);
    }
    let rendered = first.context("no pass rendered")?;
    let seconds = start.elapsed().as_secs_f64();
    progress.finish_and_clear();

    args.output.write(&rendered.image)?;
    writeln!(
        out,
        "rendered {width}×{height} at {} spp in {seconds:.2} s: {} rays, {:.3} Mrays/s",
        spp,
        rendered.rays,
        rendered.rays as f64 / seconds / 1e6
    )?;
    Ok(())
}

/// The progressive job of `params` for the tile `request` names (its
/// rectangle), with `integrator` (`params`' resolved once).
fn preset_job(
    transport: &Transport,
    integrator: Integrator,
    params: &TileParams,
    request: &TileRequest,
) -> Result<TileJob, RenderError> {
    let tile_params = TileParams {
        x: request.x,
        y: request.y,
        width: request.width,
        height: request.height,
        ..*params
    };
    Ok(TileJob {
        request: tile_params.request(transport.scene())?,
        integrator,
        denoise: params.denoise(transport.scene()),
    })
}

/// Where a rendered image goes: an EXR or a PNG (by `--out`'s extension),
/// and optionally a PNG beside it.
#[derive(Clone, Debug, clap::Args)]
pub struct ImageOutput {
    /// Output image: `.exr` (channels R, G, B and the per-pixel variance
    /// `variance`) or `.png` (tone-mapped sRGB); other extensions are refused.
    #[arg(long, value_parser = image_path(&["exr", "png"]))]
    pub out: PathBuf,
    /// Also write a tone-mapped sRGB PNG here.
    #[arg(long, value_parser = image_path(&["png"]))]
    pub png: Option<PathBuf>,
    /// PNG exposure in stops (values scaled by 2^exposure, then clamped).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
}

/// Parses an output path whose extension is one of `allowed` (any case),
/// so a wrong one is refused before any work rather than written wrongly.
fn image_path(
    allowed: &'static [&'static str],
) -> impl clap::builder::TypedValueParser<Value = PathBuf> {
    move |text: &str| -> Result<PathBuf, String> {
        let path = PathBuf::from(text);
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match extension {
            Some(e) if allowed.contains(&e.as_str()) => Ok(path),
            _ => Err(format!(
                "the file name must end in .{}",
                allowed.join(" or .")
            )),
        }
    }
}

impl ImageOutput {
    /// Writes `--out` in the format its extension names, and the PNG when one
    /// is asked for.
    pub fn write(&self, image: &crate::image::Image) -> anyhow::Result<()> {
        let tone_map = ToneMap {
            exposure: self.exposure,
        };
        let is_png = |p: &Path| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if is_png(&self.out) {
            write_png(image, tone_map, &self.out)?;
        } else {
            write_exr(image, &self.out)?;
        }
        if let Some(png) = &self.png {
            write_png(image, tone_map, png)?;
        }
        Ok(())
    }
}

/// Command-line arguments of `bmc-irradiance compare`.
#[derive(Clone, Debug, clap::Args)]
pub struct CompareArgs {
    /// The image to assess (EXR).
    pub image: PathBuf,
    /// The reference (EXR).
    pub reference: PathBuf,
    /// Leave out pixels whose reference value exceeds this in any channel
    /// (e.g. emitters seen directly), to measure the lit surfaces only.
    #[arg(long)]
    pub exclude_above: Option<f32>,
    /// With `--exclude-above`, also leave out pixels within this many pixels
    /// (8-neighbourhood steps) of an excluded one: pixels partly covering
    /// an emitter, whose anti-aliasing noise would otherwise dominate.
    #[arg(long, default_value_t = 0)]
    pub exclude_margin: u32,
    /// Also write a PNG of `|image − reference|` per channel relative to the
    /// reference's mean over the compared pixels, white at 10 % (left-out
    /// pixels black): where the error lives.
    #[arg(long)]
    pub diff: Option<PathBuf>,
}

/// `keep` (row-major, `width` wide) without the pixels within `margin`
/// 8-neighbourhood steps of a pixel it leaves out.
fn shrink(keep: &[bool], width: usize, margin: usize) -> Vec<bool> {
    if margin == 0 || width == 0 {
        return keep.to_vec();
    }
    let height = keep.len() / width;
    let m = margin as isize;
    (0..keep.len())
        .map(|i| {
            let (x, y) = ((i % width) as isize, (i / width) as isize);
            (-m..=m).all(|dy| {
                (-m..=m).all(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    nx < 0
                        || ny < 0
                        || nx >= width as isize
                        || ny >= height as isize
                        || keep[ny as usize * width + nx as usize]
                })
            })
        })
        .collect()
}

/// Runs `compare`: relative RMSE (overall and per channel) on `out`.
pub fn run_compare(args: &CompareArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let image = read_exr(&args.image)?;
    let reference = read_exr(&args.reference)?;
    let mask: Option<Vec<bool>> = args.exclude_above.map(|limit| {
        let keep: Vec<bool> = reference
            .rgb()
            .iter()
            .map(|p| p.iter().all(|&c| c <= limit))
            .collect();
        shrink(
            &keep,
            reference.width() as usize,
            args.exclude_margin as usize,
        )
    });
    let e = relative_rmse(&image, &reference, mask.as_deref())?;
    if let Some(path) = &args.diff {
        let mean = e.reference_mean as f32;
        let rgb = (image.rgb().iter().zip(reference.rgb()).enumerate())
            .map(|(i, (a, b))| {
                let keep = mask.as_ref().is_none_or(|m| m[i]);
                [0, 1, 2].map(|c| {
                    if keep {
                        (a[c] - b[c]).abs() / (0.1 * mean)
                    } else {
                        0.0
                    }
                })
            })
            .collect();
        let diff = crate::image::Image::from_parts(image.width(), image.height(), rgb, None)?;
        write_png(&diff, ToneMap::default(), path)?;
    }
    // A channel the reference is black in has no relative error: "-".
    let [r, g, b] = e
        .per_channel
        .map(|c| c.map_or_else(|| "-".to_owned(), |c| format!("{c:.5}")));
    writeln!(
        out,
        "relative RMSE {:.5} (R {r}, G {g}, B {b}) over {} pixels; mean ratio {:.5}",
        e.overall, e.pixels, e.mean_ratio
    )?;
    if let Some(expected) = e.expected_from_variance {
        writeln!(
            out,
            "expected from the image's variance channel alone: {expected:.5}"
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(subcommand)]
        command: Sub,
    }

    #[derive(clap::Subcommand)]
    enum Sub {
        Render(Box<RenderArgs>),
        Compare(CompareArgs),
    }

    fn parse(line: &str) -> Result<Sub, clap::Error> {
        let words = std::iter::once("bmc").chain(line.split_whitespace());
        Cli::try_parse_from(words).map(|cli| cli.command)
    }

    #[test]
    fn render_then_compare_end_to_end() {
        let dir = std::env::temp_dir().join(format!("bmc-render-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let scene = dir.join("quad.json");
        std::fs::write(
            &scene,
            r#"{"materials": [{"id": "m", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
                "shapes": [{"type": "rectangle", "material": "m", "to_world": {"scale": [10, 10, 1]},
                            "emitter": {"type": "area", "radiance": [2, 1, 0.5]}}],
                "camera": {"fov": 40, "width": 5, "height": 3,
                           "origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}}"#,
        )
        .expect("scene written");
        let (exr, png) = (dir.join("out.exr"), dir.join("out.png"));
        let line = format!(
            "render --scene {} --out {} --png {} --spp 3 --max-depth 4 --tile 2 --threads 1 --exposure -1",
            scene.display(),
            exr.display(),
            png.display()
        );
        let Ok(Sub::Render(args)) = parse(&line) else {
            panic!("render arguments rejected")
        };
        assert_eq!(
            args.settings(crate::testing::cornell(1).scene())
                .samples_per_pixel,
            3
        );
        let mut summary = Vec::new();
        let rendered = run_render(&args, &mut summary);
        let image = read_exr(&exr);
        let png_size = image::image_dimensions(&png);
        let compare_line = format!("compare {} {}", exr.display(), exr.display());
        let mut compared = Vec::new();
        let compare = match parse(&compare_line) {
            Ok(Sub::Compare(c)) => run_compare(&c, &mut compared),
            _ => panic!("compare arguments rejected"),
        };
        let _ = std::fs::remove_dir_all(&dir);

        rendered.expect("renders");
        assert!(String::from_utf8_lossy(&summary).contains("rendered 5×3 at 3 spp"));
        let image = image.expect("EXR readable");
        assert!(image.rgb().iter().all(|p| *p == [2.0, 1.0, 0.5]));
        assert_eq!(png_size.expect("PNG readable"), (5, 3));
        compare.expect("compares");
        assert!(String::from_utf8_lossy(&compared).starts_with("relative RMSE 0.00000"));
    }

    /// `--method cache` through the same path: EXR and PNG written, and a
    /// second pass on the warm cache creates no records.
    #[test]
    fn render_through_the_cache_end_to_end() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let text = std::fs::read_to_string(root.join("cornell-box.json")).expect("bundled");
        let mut doc: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        doc["camera"]["width"] = 8.into();
        doc["camera"]["height"] = 8.into();
        let dir = std::env::temp_dir().join(format!("bmc-render-cache-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let scene = dir.join("cornell8.json");
        std::fs::write(&scene, doc.to_string()).expect("scene written");
        let (exr, png) = (dir.join("c.exr"), dir.join("c.png"));
        let line = format!(
            "render --scene {} --out {} --png {} --method cache --spp 1 --light-samples 2 \
             --samples 16 --max-depth 4 --repeat 2 --threads 1 --tile 4",
            scene.display(),
            exr.display(),
            png.display()
        );
        let Ok(Sub::Render(args)) = parse(&line) else {
            panic!("render arguments rejected")
        };
        let mut summary = Vec::new();
        let rendered = run_render(&args, &mut summary);
        let image = read_exr(&exr);
        let png_size = image::image_dimensions(&png);
        let _ = std::fs::remove_dir_all(&dir);
        rendered.expect("renders");
        let summary = String::from_utf8_lossy(&summary);
        assert!(summary.contains("pass 1: "), "{summary}");
        assert!(summary.contains("pass 2: ") && summary.contains(" 0 records created"));
        let image = image.expect("EXR readable");
        assert_eq!((image.width(), image.height()), (8, 8));
        assert!(image.rgb().iter().any(|p| p[1] > 0.0));
        assert_eq!(png_size.expect("PNG readable"), (8, 8));
    }

    #[test]
    fn margins_grow_the_excluded_region() {
        let mut keep = vec![true; 25];
        keep[12] = false;
        let out = shrink(&keep, 5, 1);
        assert_eq!(out.iter().filter(|k| !**k).count(), 9);
        assert!(out[0] && !out[6] && !out[18] && out[4]);
        assert_eq!(shrink(&keep, 5, 0), keep);
    }

    #[test]
    fn bad_arguments_are_rejected() {
        assert!(parse("render --scene s.json --out o.exr --method bogus").is_err());
        assert!(parse("render --scene s.json --out o.exr --method cache --accuracy 2").is_ok());
        let Ok(Sub::Render(args)) = parse("render --scene s.json --out o.exr --accuracy 2") else {
            panic!("parses")
        };
        assert!(args.cache.resolve().is_err());
        assert!(parse("render --scene s.json").is_err());
        let Ok(Sub::Render(args)) = parse("render --scene /nonexistent.json --out o.exr --spp 0")
        else {
            panic!("parses")
        };
        assert!(run_render(&args, &mut Vec::new()).is_err());
    }
}

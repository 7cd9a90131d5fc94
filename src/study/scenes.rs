//! The real-scene study: error and calibration of the point estimators (MC,
//! QMC, QMC with the prior mean as a control variate, BMC) on a scene, as a
//! user gets them through `POST /v1/scenes/{id}/irradiance`, against a
//! converged reference (docs/math.md §10.3, §17.4).
//!
//! Points are what a camera sees: the first surfaces hit by camera rays
//! through a jittered grid over the image, front sides only, emitters
//! excluded. Each point's reference is plain Monte Carlo irradiance with
//! [`SceneStudyOptions::reference_samples`] samples (its standard error enters
//! every `z`). Each estimator then runs at every `N` with `seeds` request
//! seeds; its errors over points, seeds and RGB channels are pooled into the
//! relative RMSE of §17.4, the ±2σ coverage and the rms `z` of §10.3.

mod target_study;

use std::sync::Arc;

use serde::Serialize;

use crate::bmc::Kernel;
use crate::bmc::cache::QuadratureCache;
use crate::cache::{Accuracy, CacheConfig, IrradianceCache, TwinCaches};
use crate::estimators::calibration::Calibrations;
use crate::estimators::lengthscale::FittedKernels;
use crate::estimators::sample_points::camera_points;
use crate::estimators::{AmortisedRays, IntegralPrior};
use crate::estimators::{
    EstimatorCaches, EstimatorError, EstimatorMethod, EstimatorSpec, KernelSpec, RecordsPriorMode,
};
use crate::integrator::Preset;
use crate::integrator::cached::{
    CachedIntegrator, CachedShading, CachedSpec, RecordSource, TwinRule, direct_records,
    point_priors,
};
use crate::render::environment_prior::PriorChoice;
use crate::render::{
    Cancel, Decomposition, ImageSettings, IrradianceEstimate, IrradianceMethod, IrradianceOptions,
    PathDepth, QueryPoint, RenderError, Transport,
};
use crate::stats::standard_score;
pub use target_study::{TargetStudyRow, run_target, target_markdown_table};

/// What to run on one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneStudyOptions {
    /// Query points (camera-visible surface points).
    pub points: usize,
    /// Request seeds per estimator and `N`.
    pub seeds: u64,
    /// Hemisphere samples per point `N`.
    pub sample_counts: Vec<u32>,
    pub decomposition: IrradianceMethod,
    /// Longest path in segments (1 = direct light only).
    pub max_depth: PathDepth,
    /// Samples of each point's reference.
    pub reference_samples: u32,
    /// Seed of the points and the reference.
    pub seed: u64,
    /// The kernel of the `bmc` rows (`None`: the defaults).
    pub bmc_kernel: Option<KernelSpec>,
    /// Also run `qmc` and `bmc` with the records prior (docs/math.md §10.7),
    /// the records placed by rendering the camera image once (1 spp) with
    /// this preset's cache settings at the study's depth plus the camera
    /// segment, on one shared cache.
    pub records_from: Option<Preset>,
    /// With `records_from` under the hemisphere decomposition: also run
    /// `qmc` and `bmc` with the records' direct-light twins as a prior on
    /// the direct part (docs/math.md §10.8).
    pub direct_records: bool,
}

impl Default for SceneStudyOptions {
    fn default() -> Self {
        Self {
            points: 200,
            seeds: 6,
            sample_counts: vec![16, 64, 256],
            decomposition: IrradianceMethod::Auto,
            max_depth: PathDepth::default(),
            reference_samples: 16_384,
            seed: 2026,
            bmc_kernel: None,
            records_from: None,
            direct_records: false,
        }
    }
}

/// One estimator at one `N` on one scene.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneStudyRow {
    pub scene: String,
    pub decomposition: Decomposition,
    pub max_depth: u32,
    pub samples: u32,
    /// `mc`, `qmc`, `qmc+prior` (control variate) or `bmc` (defaults).
    pub estimator: String,
    /// Relative RMSE against the reference (§17.4).
    pub nrmse: f64,
    /// The same with the reference's own noise removed (§17.3).
    pub nrmse_vs_truth: f64,
    /// Fraction of `|z| ≤ 2` (§10.3), calibrated error bars (§10.5).
    pub coverage: f64,
    /// `sqrt(mean z²)` (§10.3), calibrated error bars.
    pub rms_z: f64,
    /// The same two with the estimator's own error model.
    pub model_coverage: f64,
    pub model_rms_z: f64,
    /// Rays per point, mean over points and seeds.
    pub rays_per_point: f64,
    /// `bmc` rows: the kernel used (family and hyperparameters selected by
    /// marginal likelihood unless named).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kernel: Option<Kernel>,
}

/// Errors of the study.
#[derive(Debug, thiserror::Error)]
pub enum SceneStudyError {
    #[error(transparent)]
    Estimator(#[from] EstimatorError),
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
    #[error("the camera sees no surface to put points on")]
    NoPoints,
}

/// What every study of a scene starts from: its points, their references
/// and fresh estimator caches.
struct Setup {
    points: Vec<QueryPoint>,
    reference: Vec<IrradianceEstimate>,
    /// The request options every run starts from (seed and samples replaced).
    base: IrradianceOptions,
    kernels: FittedKernels,
    quadratures: QuadratureCache,
    calibrations: Calibrations,
    /// Rays of the kept work (fits, calibrations); a study does not report them.
    amortised: AmortisedRays,
}

/// The study's query points: up to `options.points` camera-visible points,
/// deterministic in `options.seed`.
pub fn study_points(transport: &Transport, options: &SceneStudyOptions) -> Vec<QueryPoint> {
    camera_points(transport, options.points, options.seed)
}

impl Setup {
    fn new(transport: &Transport, options: &SceneStudyOptions) -> Result<Self, SceneStudyError> {
        let points = study_points(transport, options);
        if points.is_empty() {
            return Err(SceneStudyError::NoPoints);
        }
        let base = IrradianceOptions {
            samples: options.reference_samples,
            light_samples: None,
            max_depth: options.max_depth,
            direct_only: false,
            method: options.decomposition,
            seed: options.seed,
        };
        // The reference: plain MC, split, many samples (any unbiased
        // estimator of the same E would do; split has the smallest variance
        // on area lights).
        let reference = transport.irradiance_at_points(
            &points,
            &IrradianceOptions {
                method: IrradianceMethod::Split,
                ..base
            },
            &|| {},
            &Cancel::never(),
        )?;
        Ok(Self {
            points,
            reference,
            base,
            kernels: FittedKernels::default(),
            quadratures: QuadratureCache::new(256 << 20),
            calibrations: Calibrations::default(),
            amortised: AmortisedRays::default(),
        })
    }

    fn caches<'a>(
        &'a self,
        records: Option<&'a dyn IntegralPrior>,
        direct: Option<&'a dyn IntegralPrior>,
    ) -> EstimatorCaches<'a> {
        EstimatorCaches {
            kernels: &self.kernels,
            quadratures: &self.quadratures,
            calibrations: &self.calibrations,
            records,
            direct,
            amortised: &self.amortised,
        }
    }
}

/// Records over what the camera sees (`SceneStudyOptions::records_from`),
/// with the rules they were computed with.
fn camera_records(
    transport: &Transport,
    preset: Preset,
    max_depth: PathDepth,
) -> Result<(IrradianceCache, CachedShading), SceneStudyError> {
    // The preset's knobs, on one cache shared by every tile.
    let knobs = CachedSpec {
        reproducible: Some(false),
        ..CachedSpec::default()
    };
    let spec = knobs.over(
        preset
            .settings()
            .integrator
            .cached()
            .copied()
            .unwrap_or_default(),
    );
    let config = spec.resolve().map_err(RenderError::from)?;
    let shading = config
        .shading(Arc::new(QuadratureCache::new(256 << 20)))
        .map_err(RenderError::from)?;
    let cache = IrradianceCache::new(CacheConfig::default()).map_err(RenderError::from)?;
    let integrator = CachedIntegrator::new(transport, &cache, &shading);
    let settings = ImageSettings {
        samples_per_pixel: 1,
        max_depth: PathDepth::new(max_depth.get() + 1)?,
        seed: RECORDS_SEED,
    };
    transport.render_image_by(&settings, 64, &|request| {
        integrator
            .render_tile(request, None, &Cancel::never())
            .map(|(tile, _)| tile)
    })?;
    Ok((cache, shading))
}

/// Direct-light twins (docs/math.md §10.8) of `records`, or, for a study
/// of direct light only, of the records a render one segment deeper leaves
/// (`records` then holds none: there is no indirect light to record).
fn camera_direct_records(
    transport: &Transport,
    preset: Preset,
    max_depth: PathDepth,
    decomposition: Decomposition,
    (records, shading): &(IrradianceCache, CachedShading),
) -> Result<TwinCaches, SceneStudyError> {
    let deeper;
    let places = if max_depth.has_reflections() {
        records
    } else {
        deeper = camera_records(transport, preset, PathDepth::new(2)?)?.0;
        &deeper
    };
    let twins = TwinCaches::new(CacheConfig::default()).map_err(RenderError::from)?;
    direct_records(
        transport,
        &places.records(),
        TwinRule::for_queries(decomposition, &shading.rule),
        &twins,
        RECORDS_SEED,
        &Cancel::never(),
    )?;
    Ok(twins)
}

/// The study's records as a prior source: made by a camera render one
/// segment deeper than the points' paths, so they sum paths as long as the
/// points' from their own point, with their direct-light twins if the study
/// asks for them.
struct StudyRecords {
    cache: IrradianceCache,
    shading: CachedShading,
    depth_from_point: PathDepth,
    twins: Option<TwinCaches>,
}

impl RecordSource for StudyRecords {
    fn records(&self) -> (&IrradianceCache, Accuracy) {
        (&self.cache, self.shading.accuracy())
    }

    fn origin(&self) -> &'static str {
        "study"
    }

    fn depth_from_point(&self) -> Option<PathDepth> {
        Some(self.depth_from_point)
    }

    fn direct_twins(
        &self,
        _: &Transport,
        _: Decomposition,
        _: &Cancel,
    ) -> Result<Option<(&TwinCaches, u64)>, RenderError> {
        Ok(self.twins.as_ref().map(|twins| (twins, 0)))
    }
}

/// Seed of the records of [`camera_records`] (shared with no request).
const RECORDS_SEED: u64 = 0x05EC_04D5;

/// Runs every estimator of the study at every `N` on `transport`'s scene.
pub fn run(
    transport: &Transport,
    scene: &str,
    options: &SceneStudyOptions,
) -> Result<Vec<SceneStudyRow>, SceneStudyError> {
    let setup = Setup::new(transport, options)?;
    let decomposition = transport.decomposition(options.decomposition);
    let sources = match options.records_from {
        Some(preset) => {
            let records = camera_records(transport, preset, options.max_depth)?;
            let twins = options
                .direct_records
                .then(|| {
                    camera_direct_records(
                        transport,
                        preset,
                        options.max_depth,
                        decomposition,
                        &records,
                    )
                })
                .transpose()?;
            let (cache, shading) = records;
            vec![StudyRecords {
                cache,
                shading,
                depth_from_point: options.max_depth,
                twins,
            }]
        }
        None => Vec::new(),
    };
    let priors = point_priors(
        &sources,
        transport,
        options.max_depth,
        options.decomposition,
        &Cancel::never(),
    )?;
    let (points, reference, base) = (&setup.points, &setup.reference, setup.base);
    let records_known = (!sources.is_empty()).then_some(&priors.records as &dyn IntegralPrior);
    let direct_known = sources
        .iter()
        .any(|s| s.twins.is_some())
        .then_some(&priors.direct as &dyn IntegralPrior);
    let never = Cancel::never();
    let estimators = [
        ("mc", EstimatorMethod::Mc, None, false),
        ("qmc", EstimatorMethod::Qmc, None, false),
        (
            "qmc+prior",
            EstimatorMethod::Qmc,
            Some(PriorChoice::Environment),
            false,
        ),
        ("bmc", EstimatorMethod::Bmc, None, false),
        ("qmc+records", EstimatorMethod::Qmc, None, true),
        ("bmc+records", EstimatorMethod::Bmc, None, true),
        ("qmc+records+direct", EstimatorMethod::Qmc, None, true),
        ("bmc+records+direct", EstimatorMethod::Bmc, None, true),
    ];
    let prior_applies = transport
        .hemisphere_prior(PriorChoice::Environment, decomposition)
        .is_some();
    let mut rows = Vec::new();
    for &samples in &options.sample_counts {
        for (name, method, prior, records_prior) in estimators {
            if prior.is_some() && !prior_applies {
                continue; // The control variate would be plain QMC again.
            }
            if records_prior && records_known.is_none() {
                continue;
            }
            let direct_row = name.ends_with("+direct");
            if direct_row && direct_known.is_none() {
                continue;
            }
            let caches = setup.caches(records_known, direct_known.filter(|_| direct_row));
            // The same estimates twice: with the model's error bars and
            // with calibrated ones (§10.5); only the error bars differ,
            // except with the records prior, which weighs the records
            // against the rule's error bars of each kind (§10.7).
            let mut runs = [Vec::new(), Vec::new()];
            let mut kernel = None;
            for (calibrate, runs) in [false, true].into_iter().zip(&mut runs) {
                let spec = EstimatorSpec {
                    method: Some(method),
                    samples: Some(samples),
                    kernel: options
                        .bmc_kernel
                        .filter(|_| method == EstimatorMethod::Bmc),
                    prior,
                    calibrate: Some(calibrate),
                    records_prior: RecordsPriorMode::Set(records_prior),
                    ..EstimatorSpec::default()
                };
                let estimator = spec.resolve()?;
                for s in 0..options.seeds {
                    let request = IrradianceOptions {
                        samples,
                        seed: options.seed ^ (0x9E37_79B9 + s),
                        ..base
                    };
                    let estimates =
                        estimator.estimate(transport, caches, points, &request, &|| {}, &never)?;
                    kernel = estimates.kernel;
                    runs.push(estimates.estimates);
                }
            }
            let model = score(reference, &runs[0]);
            rows.push(SceneStudyRow {
                scene: scene.to_owned(),
                decomposition,
                max_depth: options.max_depth.get(),
                samples,
                estimator: name.to_owned(),
                model_coverage: model.coverage,
                model_rms_z: model.rms_z,
                kernel,
                ..score(reference, &runs[1])
            });
        }
    }
    Ok(rows)
}

/// The pooled measures of §17.4 and §10.3 for `runs[seed][point]` against
/// `reference[point]`; the identifying fields are left empty.
fn score(reference: &[IrradianceEstimate], runs: &[Vec<IrradianceEstimate>]) -> SceneStudyRow {
    let (mut squared, mut reference_variance, mut count) = (0.0, 0.0, 0usize);
    let (mut covered, mut z_squared, mut rays) = (0usize, 0.0, 0u64);
    for run in runs {
        for (estimate, truth) in run.iter().zip(reference) {
            rays += estimate.rays;
            let (e, s) = (
                estimate.irradiance.to_array(),
                estimate.std_error.to_array(),
            );
            let (t, r) = (truth.irradiance.to_array(), truth.std_error.to_array());
            for c in 0..3 {
                let error = e[c] - t[c];
                squared += error * error;
                reference_variance += r[c] * r[c];
                count += 1;
                let z = standard_score(error, s[c] * s[c], r[c] * r[c]);
                covered += usize::from(z.abs() <= 2.0);
                z_squared += z * z;
            }
        }
    }
    let mean_reference = reference
        .iter()
        .map(|r| r.irradiance.to_array().iter().sum::<f64>())
        .sum::<f64>()
        / (3 * reference.len()) as f64;
    let n = count.max(1) as f64;
    let nrmse = (squared / n).sqrt() / mean_reference;
    let reference_nrmse = (reference_variance / n).sqrt() / mean_reference;
    SceneStudyRow {
        scene: String::new(),
        decomposition: Decomposition::Split,
        max_depth: 0,
        samples: 0,
        estimator: String::new(),
        nrmse,
        nrmse_vs_truth: (nrmse * nrmse - reference_nrmse * reference_nrmse)
            .max(0.0)
            .sqrt(),
        coverage: covered as f64 / n,
        rms_z: (z_squared / n).sqrt(),
        model_coverage: 0.0,
        model_rms_z: 0.0,
        rays_per_point: rays as f64 / (runs.len() * reference.len()).max(1) as f64,
        kernel: None,
    }
}

/// The rows as a Markdown table, BMC/QMC ratio beside each BMC row.
pub fn markdown_table(rows: &[SceneStudyRow]) -> String {
    let mut out = String::from(
        "| scene | decomposition | max depth | N | estimator | nrmse | vs truth | BMC/QMC | coverage, model σ | rms z, model σ | coverage, calibrated | rms z, calibrated | rays/point |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in rows {
        let ratio = if row.estimator == "bmc" {
            rows.iter()
                .find(|q| q.estimator == "qmc" && q.samples == row.samples && q.scene == row.scene)
                .map_or(String::from("–"), |q| {
                    format!("{:.2}", row.nrmse_vs_truth / q.nrmse_vs_truth)
                })
        } else {
            String::from("–")
        };
        out.push_str(&format!(
            "| {} | {:?} | {} | {} | {} | {:.4} | {:.4} | {} | {:.3} | {:.2} | {:.3} | {:.2} | {:.0} |\n",
            row.scene,
            row.decomposition,
            row.max_depth,
            row.samples,
            row.estimator,
            row.nrmse,
            row.nrmse_vs_truth,
            ratio,
            row.model_coverage,
            row.model_rms_z,
            row.coverage,
            row.rms_z,
            row.rays_per_point,
        ));
    }
    for row in rows {
        if let Some(k) = &row.kernel {
            out.push_str(&format!(
                "\n{} {:?} depth {} N = {}, bmc kernel: {:?}, ℓ = {:.3}, σ_n²/σ² = {:.3e}",
                row.scene,
                row.decomposition,
                row.max_depth,
                row.samples,
                k.kind,
                k.lengthscale,
                k.noise / k.variance,
            ));
        }
    }
    out
}

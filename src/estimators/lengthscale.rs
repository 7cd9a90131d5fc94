//! The kernel lengthscale of a scene's incident radiance, fitted by
//! marginal likelihood (docs/math.md §7) — what `"lengthscale": "auto"` means.
//!
//! Training data: [`FIT_POINTS`] points spread over the scene's non-emitting
//! surfaces by area (shape by area, then uniform on the shape), each with a
//! random rotation about its normal; at each, the incident radiance along the
//! estimator's sample directions, traced with a short [`FIT_MAX_DEPTH`] and
//! the same path lengths as the estimator's hemisphere part (indirect only in
//! split mode), reduced to luminance. The pooled likelihood is maximised over
//! `ℓ` and the noise ratio `η = σ_n²/σ²` by [`hyperparameters::fit`]; the
//! noise ratio matters as much as `ℓ`, because with a tiny jitter the smooth
//! SE kernel gives oscillating weights on path-traced (noisy, discontinuous)
//! radiance. Sets larger than [`FIT_MAX_SAMPLES`] are fitted on a set of the
//! same kind with that many directions: `ℓ` describes the radiance field, not
//! the sample count, and it keeps the fit cheap (each likelihood evaluation
//! factorises an `N × N` matrix).
//!
//! Everything is seeded by [`FIT_SEED`], so a scene and configuration always
//! give the same fit. [`FittedKernels`] caches fits per configuration, each
//! computed at most once even under concurrent first requests.

use rand::RngExt;
use serde::Serialize;

use super::amortised::AmortisedRays;
use super::sample_points::training_points;
use crate::bmc::KernelKind;
use crate::bmc::hyperparameters::{self, FitError, FitOptions};
use crate::render::Decomposition;
use crate::render::Transport;
use crate::render::environment_prior::PriorChoice;
use crate::render::seed::point_rng;
use crate::render::{PathDepth, PathLengths, PathLimits, TraceStats};
use crate::sphere::{Frame, SampleSet, SampleSetSpec};

/// Training points per fit.
pub const FIT_POINTS: usize = 32;
/// Path length bound of the training rays: the first bounces shape the
/// radiance field's smoothness; deeper ones only add a smooth ambient term.
pub const FIT_MAX_DEPTH: PathDepth = PathDepth::constant(3);
/// Largest sample set fitted directly (module docs).
pub const FIT_MAX_SAMPLES: usize = 64;
/// Seed of the training points and their paths.
pub const FIT_SEED: u64 = 0x05EE_DF17;
/// Search range of `ℓ` (chordal distance) and of `η = σ_n²/σ²`. The noise
/// ratio may reach 10: values of one path each are noisy enough that the
/// likelihood wants `η` of order one on the Cornell box (2.6), and a cap
/// below it (it was 0.1) kept BMC 2 % worse than QMC's equal weights, which
/// BMC approaches as `η` grows (docs/math.md §10.2).
pub const LENGTHSCALE_BOUNDS: (f64, f64) = (0.05, 5.0);
pub const NOISE_RATIO_BOUNDS: (f64, f64) = (1e-5, 10.0);
/// Used when every training vector is constant, or the scene has no
/// non-emitting surface to train on (`ℓ` is then not identified, and any
/// value integrates constants exactly under the GLS mean).
pub const FALLBACK_LENGTHSCALE: f64 = 1.0;
pub const FALLBACK_NOISE_RATIO: f64 = 1e-3;

/// One estimator configuration whose lengthscale is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct FitConfig {
    pub kernel: KernelKind,
    pub sample_set: SampleSetSpec,
    pub decomposition: Decomposition,
    /// The prior mean the estimator subtracts: the fit is on the residual
    /// the GP models (docs/math.md §10.4).
    pub prior: PriorChoice,
}

/// A fitted lengthscale with what the likelihood said about it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FittedKernel {
    #[serde(flatten)]
    pub config: FitConfig,
    /// `ℓ` (chordal distance).
    pub lengthscale: f64,
    /// `η = σ_n²/σ²`; the estimator uses `σ² = 1`, `σ_n² = η` (the weights
    /// depend on the ratio only).
    pub noise_ratio: f64,
    /// Pooled log marginal likelihood at the optimum; `None` when there was
    /// nothing to fit and the fallback values are used.
    pub log_marginal_likelihood: Option<f64>,
    /// `ℓ` or `η` ended at a search bound ([`hyperparameters::Fit::at_bound`]),
    /// or nothing was identified at all (the fallback values).
    pub at_bound: bool,
    /// Directions per training point actually fitted.
    pub fit_samples: usize,
    /// Training points.
    pub points: usize,
    /// Rays the training paths traced.
    pub rays: u64,
}

/// Fits the lengthscale for `config` on `transport`'s scene (module docs).
pub fn fit_lengthscale(transport: &Transport, config: FitConfig) -> Result<FittedKernel, FitError> {
    let set = SampleSet::generate(SampleSetSpec {
        count: config.sample_set.count.min(FIT_MAX_SAMPLES),
        ..config.sample_set
    })?;
    let points = training_points(transport, FIT_POINTS, FIT_SEED);
    let limits = PathLimits {
        max_depth: FIT_MAX_DEPTH,
        lengths: match config.decomposition {
            Decomposition::Split => PathLengths::Indirect,
            Decomposition::Hemisphere => PathLengths::All,
        },
    };
    let prior = transport.hemisphere_prior(config.prior, config.decomposition);
    let mut stats = TraceStats::default();
    let observations: Vec<Vec<f64>> = points
        .iter()
        .enumerate()
        .map(|(i, point)| {
            let mut rng = point_rng(FIT_SEED, i as u64);
            let frame = Frame::from_normal(point.normal())
                .rotated_about_normal(std::f64::consts::TAU * rng.random::<f64>());
            transport
                .hemisphere_samples(point, &frame, &set.directions, limits, &mut rng, &mut stats)
                .iter()
                .zip(&set.directions)
                .map(|(s, d)| {
                    let mean = prior.map_or(0.0, |p| p.radiance(frame.to_world(*d)).luminance());
                    s.radiance.luminance() - mean
                })
                .collect()
        })
        .collect();
    let options = FitOptions {
        lengthscale_bounds: LENGTHSCALE_BOUNDS,
        noise_ratio_bounds: NOISE_RATIO_BOUNDS,
        grid_points: 13,
    };
    let fitted = |lengthscale, noise_ratio, log_marginal_likelihood, at_bound| FittedKernel {
        config,
        lengthscale,
        noise_ratio,
        log_marginal_likelihood,
        at_bound,
        fit_samples: set.len(),
        points: points.len(),
        rays: stats.rays,
    };
    match hyperparameters::fit(&set, config.kernel, &observations, &options) {
        Ok(fit) => Ok(fitted(
            fit.lengthscale,
            fit.noise / fit.variance,
            Some(fit.log_likelihood),
            fit.at_bound(),
        )),
        Err(FitError::ConstantData) => Ok(fitted(
            FALLBACK_LENGTHSCALE,
            FALLBACK_NOISE_RATIO,
            None,
            true,
        )),
        Err(err) => Err(err),
    }
}

/// Most fitted configurations kept per scene: every request may name a new
/// configuration (kernel, sample set, count, decomposition), so without a
/// bound the fits grew with the number of requests.
pub const MAX_FITS: u64 = 64;

/// Fitted kernels of one scene by configuration; each fit runs at most once
/// while kept (concurrent first requests wait for the one computing it).
/// Errors are kept too: the fit is deterministic, so retrying would fail the
/// same way. At most [`MAX_FITS`] are kept; beyond, the least used go first
/// (and are fitted again, identically, if asked for again).
pub struct FittedKernels {
    fits: moka::sync::Cache<FitConfig, Result<FittedKernel, String>>,
}

impl Default for FittedKernels {
    fn default() -> Self {
        Self {
            fits: moka::sync::Cache::new(MAX_FITS),
        }
    }
}

impl FittedKernels {
    /// The fit for `config`, computing it on first use (its rays counted
    /// in `amortised` then).
    pub fn get_or_fit(
        &self,
        transport: &Transport,
        config: FitConfig,
        amortised: &AmortisedRays,
    ) -> Result<FittedKernel, String> {
        let config = FitConfig {
            sample_set: config.sample_set.canonical(),
            ..config
        };
        self.fits.get_with(config, || {
            crate::isolated::isolated(|| {
                let fit = fit_lengthscale(transport, config);
                if let Ok(fit) = &fit {
                    amortised.add(fit.rays);
                }
                fit.map_err(|e| e.to_string())
            })
        })
    }

    /// The family of largest pooled marginal likelihood with its fit:
    /// `config.kernel` is ignored, each of [`KernelKind::ALL`] is fitted
    /// (and kept) on the same training values, and the best one is returned
    /// (docs/math.md §7.5). The families have the same two fitted
    /// hyperparameters, so their maximised likelihoods compare directly. When
    /// the values are constant, nothing is identified and the first family
    /// (the default) is kept.
    pub fn get_or_select(
        &self,
        transport: &Transport,
        config: FitConfig,
        amortised: &AmortisedRays,
    ) -> Result<FittedKernel, String> {
        let mut best: Option<FittedKernel> = None;
        for kernel in KernelKind::ALL {
            let fit = self.get_or_fit(transport, FitConfig { kernel, ..config }, amortised)?;
            let better = match (&best, fit.log_marginal_likelihood) {
                (None, _) => true,
                (Some(b), Some(l)) => b.log_marginal_likelihood.is_some_and(|bl| l > bl),
                (Some(_), None) => false,
            };
            if better {
                best = Some(fit);
            }
        }
        best.ok_or_else(|| "no kernel family to fit".to_owned())
    }

    /// Every successful fit kept, in a stable order.
    pub fn list(&self) -> Vec<FittedKernel> {
        let mut out: Vec<FittedKernel> = self.fits.iter().filter_map(|(_, fit)| fit.ok()).collect();
        out.sort_by_key(|f| format!("{:?}", f.config));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::SampleSetKind;
    use crate::testing::cornell;
    use std::sync::Arc;

    fn config(decomposition: Decomposition) -> FitConfig {
        FitConfig {
            kernel: KernelKind::SquaredExponential,
            sample_set: SampleSetSpec {
                kind: SampleSetKind::FibonacciCosine,
                count: 32,
                seed: 0,
            },
            decomposition,
            prior: PriorChoice::None,
        }
    }

    /// Split mode (the default): the indirect radiance is smooth enough for
    /// the likelihood to pick an interior lengthscale. In hemisphere mode the
    /// light source's edges make it prefer the shortest `ℓ` allowed. The
    /// path-traced training radiance is noisy: the noise ratio comes out of
    /// order one, inside its range (it sat at the old upper bound of 0.1).
    #[test]
    fn cornell_box_fit_is_deterministic_with_lengthscale_inside_its_bounds() {
        let transport = cornell(8);
        let split = fit_lengthscale(&transport, config(Decomposition::Split)).unwrap();
        assert_eq!(
            split,
            fit_lengthscale(&transport, config(Decomposition::Split)).unwrap()
        );
        assert!(split.log_marginal_likelihood.is_some());
        let (lo, hi) = LENGTHSCALE_BOUNDS;
        assert!(
            lo < split.lengthscale && split.lengthscale < hi,
            "{split:?}"
        );
        let (eta_lo, eta_hi) = NOISE_RATIO_BOUNDS;
        assert!(
            0.1 < split.noise_ratio && split.noise_ratio < eta_hi && eta_lo < split.noise_ratio,
            "{split:?}"
        );
        assert!(!split.at_bound, "{split:?}");
        assert_eq!(split.points, FIT_POINTS);
        let hemisphere = fit_lengthscale(&transport, config(Decomposition::Hemisphere)).unwrap();
        assert!(hemisphere.lengthscale < split.lengthscale, "{hemisphere:?}");
    }

    /// A lone disk under a constant sky: in split mode its points see
    /// no indirect light at all, so nothing can be fitted.
    #[test]
    fn constant_radiance_falls_back_to_the_defaults() {
        let doc = r#"{
            "materials": [{"id": "grey", "type": "diffuse", "reflectance": [0.8, 0.8, 0.8]}],
            "shapes": [{"type": "disk", "material": "grey"}],
            "environment": {"type": "constant", "radiance": [2, 2, 2]},
            "camera": {"type": "perspective", "fov": 30, "origin": [0, 0, 4],
                       "target": [0, 0, 0], "up": [0, 1, 0], "width": 4, "height": 4}
        }"#;
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = crate::scene::Scene::from_json_str(doc, dir, dir).unwrap();
        let transport = Transport::new(Arc::new(scene));
        let fit = fit_lengthscale(&transport, config(Decomposition::Split)).unwrap();
        assert_eq!(fit.lengthscale, FALLBACK_LENGTHSCALE);
        assert_eq!(fit.noise_ratio, FALLBACK_NOISE_RATIO);
        assert_eq!(fit.log_marginal_likelihood, None);
        assert!(fit.at_bound);
    }

    #[test]
    fn fits_are_cached_per_configuration() {
        let transport = cornell(8);
        let kernels = FittedKernels::default();
        assert!(kernels.list().is_empty());
        let (fitting, reading) = (AmortisedRays::default(), AmortisedRays::default());
        let first = kernels
            .get_or_fit(&transport, config(Decomposition::Split), &fitting)
            .unwrap();
        let again = kernels
            .get_or_fit(&transport, config(Decomposition::Split), &reading)
            .unwrap();
        assert_eq!(first, again);
        assert_eq!(kernels.list(), [first]);
        // The fit's rays are counted by the request that fitted, only.
        assert!(first.rays >= (FIT_POINTS * first.fit_samples) as u64);
        assert_eq!((fitting.get(), reading.get()), (first.rays, 0));
    }

    #[test]
    fn the_family_of_largest_likelihood_is_selected_and_every_fit_kept() {
        let transport = cornell(8);
        let kernels = FittedKernels::default();
        let best = kernels
            .get_or_select(
                &transport,
                config(Decomposition::Hemisphere),
                &AmortisedRays::default(),
            )
            .unwrap();
        let fits = kernels.list();
        assert_eq!(fits.len(), KernelKind::ALL.len());
        let likelihoods: Vec<f64> = fits
            .iter()
            .map(|f| f.log_marginal_likelihood.expect("Cornell radiance varies"))
            .collect();
        let largest = likelihoods.iter().copied().fold(f64::MIN, f64::max);
        assert_eq!(best.log_marginal_likelihood, Some(largest));
        assert!(fits.contains(&best));
        // Asking again selects from the kept fits, identically.
        let again = kernels
            .get_or_select(
                &transport,
                config(Decomposition::Hemisphere),
                &AmortisedRays::default(),
            )
            .unwrap();
        assert_eq!(again, best);
        assert_eq!(kernels.list().len(), KernelKind::ALL.len());
    }
}

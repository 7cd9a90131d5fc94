//! Hemisphere integral estimators behind one interface: Monte Carlo,
//! quasi-Monte Carlo and Bayesian Monte Carlo (docs/math.md §3, §6).
//!
//! Each estimates `I = ∫_H f(ω) p(ω) dω` for a known density `p` (a
//! [`Density`]) from values of the unknown `f` (incident radiance) at
//! directions in the **local frame** (z = normal). A renderer asks an
//! estimator for directions once per shading point, traces them, and calls
//! [`HemisphereEstimator::estimate`] once per colour channel with the same
//! directions; everything channel-independent is precomputed per estimator,
//! not per call.
//!
//! Directions of QMC and BMC are a fixed set; a renderer that wants the
//! structured error of a fixed set turned into noise rotates its shading
//! frame about the normal per point (`Frame::rotated_about_normal`), which
//! leaves the weights exact for rotation-invariant densities (uniform,
//! Lambert; docs/math.md §5).

use std::borrow::Cow;
use std::f64::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

use glam::DVec3;
use rand::RngExt;
use rand_pcg::Pcg64;

use crate::bmc::cache::CachedQuadrature;
use crate::bmc::gls::Gls;
use crate::bmc::{BmcError, Density, PriorMean};
use crate::sphere::{SampleSet, SampleSetKind, SampleSetSpec};
use crate::stats::RunningMean;

/// An estimate of `∫_H f p dω` and the estimator's variance for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The estimated integral (units of `f` times those of `∫p`).
    pub value: f64,
    /// Variance of `value` as the estimator models it (see each estimator).
    pub variance: f64,
}

/// Errors from feeding an estimator inconsistent inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimatorError {
    /// `values` and `directions` must have one entry per sample.
    #[error("values: expected {expected} samples, got {got}")]
    SampleCount {
        /// Number of directions (or weights) the estimator holds.
        expected: usize,
        /// Number of values supplied.
        got: usize,
    },
}

impl EstimatorError {
    /// The input field at fault.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::SampleCount { .. } => Some("values"),
        }
    }
}

/// A rule that turns radiance samples into an integral estimate.
pub trait HemisphereEstimator: Send + Sync {
    /// Local-frame directions for one shading point: fresh draws for MC, the
    /// fixed set for QMC and BMC.
    fn directions(&self, rng: &mut Pcg64) -> Cow<'_, [DVec3]>;

    /// `∫_H f p dω` from `values[i] = f(directions[i])`, one channel at a time.
    fn estimate(&self, directions: &[DVec3], values: &[f64]) -> Result<Estimate, EstimatorError>;
}

/// The probability density the directions of a sample-mean estimator are
/// distributed with (per steradian, upper hemisphere).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplingPdf {
    /// `1/(2π)`.
    Uniform,
    /// `cos θ/π`.
    Cosine,
}

impl SamplingPdf {
    /// The density the directions of a sample set of `kind` follow (the
    /// spherical Fibonacci sets in the limit, docs/math.md §5): `1/(2π)` for
    /// the uniform-area kinds, `cos θ/π` for the cosine-distributed ones.
    pub fn of_set(kind: SampleSetKind) -> Self {
        match kind {
            SampleSetKind::Fibonacci | SampleSetKind::Uniform | SampleSetKind::Stratified => {
                Self::Uniform
            }
            SampleSetKind::FibonacciCosine
            | SampleSetKind::Cosine
            | SampleSetKind::StratifiedCosine => Self::Cosine,
        }
    }

    fn eval(self, direction: DVec3) -> f64 {
        match self {
            Self::Uniform => 0.5 * FRAC_1_PI,
            Self::Cosine => direction.z.max(0.0) * FRAC_1_PI,
        }
    }
}

/// Where a sample-mean estimator takes its directions from.
#[derive(Clone, Debug)]
enum Directions {
    /// Fresh random draws of `count` directions per shading point (MC).
    Random { kind: SampleSetKind, count: usize },
    /// One deterministic low-discrepancy set (QMC).
    Fixed(SampleSet),
}

/// Equal-weight estimators `Î = (1/N) Σ f(ω_i) p(ω_i)/q(ω_i)` (docs/math.md §6):
/// MC with random directions of density `q`, QMC with spherical Fibonacci
/// directions distributed (in the limit) like `q`.
///
/// Variance: the sample variance of the terms `t_i = f p/q` divided by `N`.
/// For MC it is the unbiased variance estimate. For QMC it is the variance an
/// MC estimator with the same terms would have: QMC usually does better, so it
/// is a pessimistic error scale rather than a calibrated variance (a single
/// deterministic point set carries no unbiased variance estimate).
#[derive(Clone, Debug)]
pub struct SampleMeanEstimator {
    density: Density,
    pdf: SamplingPdf,
    directions: Directions,
}

impl SampleMeanEstimator {
    /// Monte Carlo with `count ≥ 2` fresh directions per shading point drawn
    /// from `pdf` (uniform or cosine-weighted).
    pub fn monte_carlo(density: Density, pdf: SamplingPdf, count: usize) -> Result<Self, BmcError> {
        if count < 2 {
            // The sample variance needs two draws.
            return Err(BmcError::invalid(
                "samples",
                format!("MC needs at least 2, got {count}"),
            ));
        }
        Self::new(density, pdf, count, true)
    }

    /// Quasi-Monte Carlo on `count` spherical Fibonacci points: uniform-area
    /// points for `SamplingPdf::Uniform`, cosine-distributed ones for
    /// `SamplingPdf::Cosine` (docs/math.md §5). With Lambert `p` and cosine
    /// points this is `(1/N) Σ f`; with uniform points `(2π/N) Σ f p`.
    pub fn quasi_monte_carlo(
        density: Density,
        pdf: SamplingPdf,
        count: usize,
    ) -> Result<Self, BmcError> {
        Self::new(density, pdf, count, false)
    }

    fn new(
        density: Density,
        pdf: SamplingPdf,
        count: usize,
        random: bool,
    ) -> Result<Self, BmcError> {
        density.validate()?;
        let kind = match (pdf, random) {
            (SamplingPdf::Uniform, true) => SampleSetKind::Uniform,
            (SamplingPdf::Cosine, true) => SampleSetKind::Cosine,
            (SamplingPdf::Uniform, false) => SampleSetKind::Fibonacci,
            (SamplingPdf::Cosine, false) => SampleSetKind::FibonacciCosine,
        };
        // Generating once validates the count, so later random draws cannot
        // fail on it.
        let set = SampleSet::generate(SampleSetSpec {
            kind,
            count,
            seed: 0,
        })?;
        let directions = if random {
            Directions::Random { kind, count }
        } else {
            Directions::Fixed(set)
        };
        Ok(Self {
            density,
            pdf,
            directions,
        })
    }
}

impl HemisphereEstimator for SampleMeanEstimator {
    fn directions(&self, rng: &mut Pcg64) -> Cow<'_, [DVec3]> {
        match &self.directions {
            Directions::Fixed(set) => Cow::Borrowed(&set.directions),
            Directions::Random { kind, count } => {
                let spec = SampleSetSpec {
                    kind: *kind,
                    count: *count,
                    seed: rng.random(),
                };
                // The spec was validated in the constructor; only the seed changed.
                let set =
                    SampleSet::generate(spec).expect("sample set spec validated at construction");
                Cow::Owned(set.directions)
            }
        }
    }

    fn estimate(&self, directions: &[DVec3], values: &[f64]) -> Result<Estimate, EstimatorError> {
        check_count(directions.len(), values.len())?;
        Ok(importance_rule(&self.density, self.pdf, directions, values))
    }
}

/// The equal-weight rule `Î = (1/N) Σ f(ω_i) p(ω_i)/q(ω_i)` for directions
/// distributed with `pdf = q`, with the sample variance of its terms over
/// `N` (docs/math.md §6): MC and QMC, and the fallback of BMC estimates
/// rejected by the negative-weight guard (docs/math.md §3.6). Non-negative
/// for non-negative values. `directions` and `values` have equal lengths.
pub fn importance_rule(
    density: &Density,
    pdf: SamplingPdf,
    directions: &[DVec3],
    values: &[f64],
) -> Estimate {
    let terms = directions.iter().zip(values).map(|(&w, &f)| {
        let q = pdf.eval(w);
        // A direction the pdf cannot produce contributes nothing.
        if q > 0.0 {
            f * density.eval(w) / q
        } else {
            0.0
        }
    });
    mean_and_variance_of_mean(terms)
}

/// `(mean, sample variance / n)` of the terms (`crate::stats`); an infinite
/// variance for a single term, whose spread is unknown.
fn mean_and_variance_of_mean(terms: impl Iterator<Item = f64>) -> Estimate {
    let mut running = RunningMean::new();
    terms.for_each(|t| running.push(t));
    Estimate {
        value: running.mean(),
        variance: running.variance_of_mean().unwrap_or(f64::INFINITY),
    }
}

fn check_count(expected: usize, got: usize) -> Result<(), EstimatorError> {
    if expected == got {
        Ok(())
    } else {
        Err(EstimatorError::SampleCount { expected, got })
    }
}

/// How the BMC estimator reports its variance.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum BmcVariance {
    /// The posterior variance `V = V₀ − zᵀQ⁻¹z` for the kernel's own `σ²`;
    /// independent of the data (docs/math.md §3).
    #[default]
    Posterior,
    /// `V · σ̂²/σ²` with the per-estimate amplitude fit
    /// `σ̂²/σ² = rᵀQ⁻¹r / (N − d)`, `r` the data minus the prior mean (GLS
    /// mean: `d = 1`, zero mean: `d = 0`) — the maximum-likelihood amplitude
    /// of docs/math.md §7 for one point. Costs one `O(N²)` solve per call;
    /// makes the variance scale with the radiance level of each point.
    AmplitudeFit,
}

/// Bayesian Monte Carlo with precomputed weights: `Î = wᵀY` (GLS mean: the
/// weights already integrate constants exactly), variance per [`BmcVariance`].
///
/// The values are taken as non-negative (radiance): where negative weights
/// meet a value far above the others and `wᵀY` comes out negative, the
/// negative-weight guard of docs/math.md §3.6 replaces it by the
/// equal-weight rule on the same directions ([`importance_rule`] with the
/// set's own density [`SamplingPdf::of_set`]) and its sample variance.
#[derive(Clone, Debug)]
pub struct BayesianEstimator {
    cached: Arc<CachedQuadrature>,
    variance: BmcVariance,
    /// `Q⁻¹1`, for the GLS residual of the amplitude fit.
    gls: Gls,
}

impl BayesianEstimator {
    /// Estimator over a cached quadrature (see [`crate::bmc::cache`]).
    pub fn new(cached: Arc<CachedQuadrature>, variance: BmcVariance) -> Self {
        let gls = Gls::new(&cached.factorised.factorisation);
        Self {
            cached,
            variance,
            gls,
        }
    }

    /// The quadrature this estimator applies.
    pub fn quadrature(&self) -> &CachedQuadrature {
        &self.cached
    }

    /// `σ̂²/σ²` of [`BmcVariance::AmplitudeFit`] for one data vector.
    fn amplitude_ratio(&self, values: &[f64]) -> f64 {
        let n = values.len();
        let solved = self.cached.factorised.factorisation.solve(values);
        let quadratic: f64 = values.iter().zip(&solved).map(|(y, a)| y * a).sum();
        let (residual, dof) = match self.cached.quadrature.prior_mean {
            PriorMean::Zero => (quadratic, n),
            // Unbiased: one degree of freedom went into the GLS mean, and
            // with few values per point (N = 16..64) the ML divisor N would
            // shrink every error bar by a visible factor.
            PriorMean::Gls => (self.gls.residual(values, &solved), n - 1),
        };
        if dof == 0 {
            return f64::INFINITY;
        }
        residual.max(0.0) / dof as f64
    }
}

impl HemisphereEstimator for BayesianEstimator {
    fn directions(&self, _rng: &mut Pcg64) -> Cow<'_, [DVec3]> {
        Cow::Borrowed(self.cached.directions())
    }

    fn estimate(&self, directions: &[DVec3], values: &[f64]) -> Result<Estimate, EstimatorError> {
        let weights = &self.cached.quadrature.weights;
        check_count(weights.len(), directions.len())?;
        check_count(weights.len(), values.len())?;
        let value = self.cached.quadrature.estimate(values);
        // Only for values that are non-negative: residuals from a prior mean
        // may integrate to less than zero (their caller guards the total).
        if value < 0.0 && values.iter().all(|v| *v >= 0.0) {
            // Impossible for non-negative values (docs/math.md §3.6).
            let pdf = SamplingPdf::of_set(self.cached.factorised.set.spec.kind);
            return Ok(importance_rule(
                &self.cached.density,
                pdf,
                directions,
                values,
            ));
        }
        let posterior = self.cached.quadrature.posterior_variance;
        let variance = match self.variance {
            BmcVariance::Posterior => posterior,
            BmcVariance::AmplitudeFit => posterior * self.amplitude_ratio(values),
        };
        Ok(Estimate { value, variance })
    }
}

/// Irradiance `E = π I` from the integral of the Lambert density `cos θ/π`
/// (docs/math.md §1), with the variance scaled accordingly.
pub fn irradiance_from_lambert(estimate: Estimate) -> Estimate {
    Estimate {
        value: PI * estimate.value,
        variance: PI * PI * estimate.variance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::bmc::{Kernel, KernelKind, KernelMeanMethod};
    use rand::SeedableRng;

    /// `a + b·ω`, whose Lambert integral is `a + (2/3) b_z` (docs/math.md §8 / π).
    fn linear(w: DVec3) -> f64 {
        0.8 + DVec3::new(0.3, -0.2, 0.5).dot(w)
    }
    const LINEAR_INTEGRAL: f64 = 0.8 + 2.0 / 3.0 * 0.5;

    fn run(estimator: &dyn HemisphereEstimator, rng: &mut Pcg64, f: fn(DVec3) -> f64) -> Estimate {
        let directions = estimator.directions(rng);
        let values: Vec<f64> = directions.iter().map(|&w| f(w)).collect();
        estimator
            .estimate(&directions, &values)
            .expect("consistent input")
    }

    fn bmc(count: usize, prior_mean: PriorMean, variance: BmcVariance) -> BayesianEstimator {
        let cache = QuadratureCache::new(16 << 20);
        let kernel = Kernel::new(KernelKind::SquaredExponential, 0.7, 1.0, 1e-8).expect("kernel");
        let spec = SampleSetSpec {
            kind: SampleSetKind::Fibonacci,
            count,
            seed: 0,
        };
        let (q, _) = cache
            .quadrature(
                spec,
                &kernel,
                &Density::Lambert,
                prior_mean,
                KernelMeanMethod::Exact,
            )
            .expect("weights");
        BayesianEstimator::new(q, variance)
    }

    #[test]
    fn cosine_sampling_of_lambert_is_exact_for_constants() {
        let mut rng = Pcg64::seed_from_u64(1);
        for estimator in [
            SampleMeanEstimator::monte_carlo(Density::Lambert, SamplingPdf::Cosine, 16),
            SampleMeanEstimator::quasi_monte_carlo(Density::Lambert, SamplingPdf::Cosine, 16),
        ] {
            let e = run(&estimator.expect("valid"), &mut rng, |_| 2.5);
            assert!(
                (e.value - 2.5).abs() < 1e-12 && e.variance.abs() < 1e-20,
                "{e:?}"
            );
        }
    }

    #[test]
    fn monte_carlo_variance_is_calibrated() {
        // Over many independent estimates, the squared errors average to the
        // reported variance (±15 % with 400 estimates), for both pdfs.
        let mut rng = Pcg64::seed_from_u64(7);
        for pdf in [SamplingPdf::Uniform, SamplingPdf::Cosine] {
            let mc = SampleMeanEstimator::monte_carlo(Density::Lambert, pdf, 32).expect("valid");
            let (mut squared_error, mut variance) = (0.0, 0.0);
            for _ in 0..400 {
                let e = run(&mc, &mut rng, linear);
                squared_error += (e.value - LINEAR_INTEGRAL).powi(2);
                variance += e.variance;
            }
            let ratio = squared_error / variance;
            assert!((0.85..1.15).contains(&ratio), "{pdf:?}: {ratio}");
        }
    }

    #[test]
    fn qmc_converges_on_a_linear_integrand() {
        let mut rng = Pcg64::seed_from_u64(0);
        for pdf in [SamplingPdf::Uniform, SamplingPdf::Cosine] {
            let mut err = |n| {
                let qmc = SampleMeanEstimator::quasi_monte_carlo(Density::Lambert, pdf, n)
                    .expect("valid");
                (run(&qmc, &mut rng, linear).value - LINEAR_INTEGRAL).abs()
            };
            let (coarse, fine) = (err(16), err(256));
            assert!(fine < 2e-3 && fine < coarse, "{pdf:?}: {coarse} → {fine}");
        }
    }

    #[test]
    fn bmc_integrates_constants_and_linear_functions() {
        let mut rng = Pcg64::seed_from_u64(0);
        let estimator = bmc(64, PriorMean::Gls, BmcVariance::Posterior);
        let constant = run(&estimator, &mut rng, |_| 3.0);
        assert!((constant.value - 3.0).abs() < 1e-9, "{constant:?}");
        let e = run(&estimator, &mut rng, linear);
        assert!((e.value - LINEAR_INTEGRAL).abs() < 1e-4, "{e:?}");
        assert_eq!(
            e.variance,
            estimator.quadrature().quadrature.posterior_variance
        );
    }

    /// Cosine Fibonacci points with a tiny noise ratio have oscillating
    /// Lambert weights; a spike under the most negative one makes `wᵀY`
    /// negative, and the estimate becomes the equal-weight (QMC) rule on
    /// the same directions with its sample variance (docs/math.md §3.6).
    /// Data that keep `wᵀY ≥ 0` get the BMC estimate, untouched.
    #[test]
    fn a_negative_bmc_sum_falls_back_to_the_equal_weight_rule() {
        let cache = QuadratureCache::new(16 << 20);
        let kernel = Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 1e-8).expect("kernel");
        let spec = SampleSetSpec {
            kind: SampleSetKind::FibonacciCosine,
            count: 64,
            seed: 0,
        };
        let (q, _) = cache
            .quadrature(
                spec,
                &kernel,
                &Density::Lambert,
                PriorMean::Gls,
                KernelMeanMethod::Exact,
            )
            .expect("weights");
        let bmc = BayesianEstimator::new(q.clone(), BmcVariance::AmplitudeFit);
        let mut rng = Pcg64::seed_from_u64(0);
        let directions = bmc.directions(&mut rng).into_owned();
        let weights = &q.quadrature.weights;
        let (k, &most_negative) = weights
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .expect("weights");
        assert!(most_negative < 0.0);
        let mut values: Vec<f64> = directions.iter().map(|&w| linear(w)).collect();
        let kept = bmc.estimate(&directions, &values).expect("consistent");
        assert_eq!(kept.value, q.quadrature.estimate(&values));
        values[k] = 40.0;
        assert!(q.quadrature.estimate(&values) < 0.0);
        let fallback = bmc.estimate(&directions, &values).expect("consistent");
        let qmc = SampleMeanEstimator::quasi_monte_carlo(Density::Lambert, SamplingPdf::Cosine, 64)
            .expect("valid");
        assert_eq!(fallback, qmc.estimate(&directions, &values).expect("valid"));
        // Lambert density on cosine points: the plain mean of the values.
        let mean = values.iter().sum::<f64>() / 64.0;
        assert!((fallback.value - mean).abs() < 1e-12, "{fallback:?}");
        assert!(fallback.variance > 0.0);
    }

    #[test]
    fn amplitude_fit_scales_with_the_data() {
        let mut rng = Pcg64::seed_from_u64(0);
        let estimator = bmc(32, PriorMean::Gls, BmcVariance::AmplitudeFit);
        let small = run(&estimator, &mut rng, linear);
        let large = run(&estimator, &mut rng, |w| 3.0 * linear(w));
        assert!(small.variance > 0.0);
        assert!((large.variance / small.variance - 9.0).abs() < 1e-6);
        // A constant has no residual about the GLS mean: zero variance.
        assert!(run(&estimator, &mut rng, |_| 1.0).variance.abs() < 1e-12);
        let zero_mean = bmc(32, PriorMean::Zero, BmcVariance::AmplitudeFit);
        assert!(run(&zero_mean, &mut rng, |_| 1.0).variance > 0.0);
    }

    #[test]
    fn inconsistent_inputs_are_typed_errors() {
        let estimator = bmc(16, PriorMean::Zero, BmcVariance::Posterior);
        let mut rng = Pcg64::seed_from_u64(0);
        let directions = estimator.directions(&mut rng);
        let err = estimator
            .estimate(&directions, &[1.0; 3])
            .expect_err("too few values");
        assert_eq!(err.field(), Some("values"));
        let mc = SampleMeanEstimator::monte_carlo(Density::Lambert, SamplingPdf::Cosine, 8)
            .expect("valid");
        assert!(mc.estimate(&directions, &[1.0; 8]).is_err());
        assert!(
            SampleMeanEstimator::monte_carlo(Density::Lambert, SamplingPdf::Cosine, 0).is_err()
        );
        let bad = Density::Phong {
            exponent: f64::NAN,
            mirror_elevation: 0.0,
        };
        assert!(SampleMeanEstimator::quasi_monte_carlo(bad, SamplingPdf::Uniform, 8).is_err());
    }

    #[test]
    fn irradiance_is_pi_times_the_lambert_integral() {
        let e = irradiance_from_lambert(Estimate {
            value: 1.0,
            variance: 0.5,
        });
        assert_eq!(e.value, PI);
        assert_eq!(e.variance, 0.5 * PI * PI);
    }
}

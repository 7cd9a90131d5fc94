//! BMC with an unbiased correction: the GP posterior mean of a fixed-set BMC
//! rule as a control variate for Monte Carlo (docs/math.md §10.6).
//!
//! The BMC estimate `wᵀf_X` on the set `X` is the exact integral of the GP
//! posterior mean `m_X`, so adding the Monte Carlo estimate of the residual
//! `∫ (f − m_X) p` from `M` fresh directions `y_j ~ q` gives
//!
//! `Î = wᵀf_X + (1/M) Σ_j (f(y_j) − m_X(y_j)) p(y_j)/q(y_j)`,
//!
//! whose expectation over the fresh directions is `∫ f p` for every `X`
//! and every kernel: the fixed set's bias, which no number of rotated
//! batches of plain BMC removes, is gone, and independent batches average
//! out. The fresh directions are stratified, one cosine-distributed point in
//! each of `M` cells of equal cosine-weighted measure
//! ([`SampleSetKind::StratifiedCosine`]), which keeps the mean unbiased and
//! removes the residual's variation between cells. Its variance is at most
//! the residual's over `M`, which the residuals' sample variance estimates;
//! where the GP fits `f` it is far below `f`'s own, and the calibration on
//! the scene (docs/math.md §10.5) scales what the stratification removes.

use std::borrow::Cow;
use std::sync::Arc;

use glam::DVec3;
use rand::RngExt;
use rand_pcg::Pcg64;

use super::cache::CachedQuadrature;
use super::estimator::{
    Estimate, EstimatorError, HemisphereEstimator, SamplingPdf, importance_rule,
};
use super::gls::Gls;
use super::{Kernel, PriorMean};
use crate::sphere::{SampleSet, SampleSetKind, SampleSetSpec};

/// [`HemisphereEstimator`] of the module docs: the directions are the
/// quadrature's set followed by `residual_samples` fresh stratified
/// cosine-distributed ones.
#[derive(Clone, Debug)]
pub struct BmcControlVariate {
    cached: Arc<CachedQuadrature>,
    /// The kernel the quadrature was built with (`k(y, x_i)` of `m_X`).
    kernel: Kernel,
    gls: Gls,
    residual_samples: usize,
}

impl BmcControlVariate {
    /// `residual_samples ≥ 2` (the sample variance needs two); `kernel` must
    /// be the one `cached` was built with, or the correction is not of the
    /// rule's own posterior mean and the estimate, though still unbiased,
    /// loses its variance reduction.
    pub fn new(cached: Arc<CachedQuadrature>, kernel: Kernel, residual_samples: usize) -> Self {
        assert!(
            residual_samples >= 2,
            "the residual's variance needs two samples"
        );
        let gls = Gls::new(&cached.factorised.factorisation);
        Self {
            cached,
            kernel,
            gls,
            residual_samples,
        }
    }

    fn set_len(&self) -> usize {
        self.cached.quadrature.weights.len()
    }

    /// `m_X(y) = m̂ + k(y, X)ᵀ Q⁻¹ (f_X − m̂ 1)` at each of `ys`, with
    /// `m̂ = uᵀf_X / s` for the GLS mean (docs/math.md §3.3) and 0 for the
    /// zero mean; its Lambert integral is `wᵀf_X` (the weights of
    /// [`super::Quadrature::new`]).
    fn posterior_mean(&self, values: &[f64], ys: &[DVec3]) -> Vec<f64> {
        let mean = match self.cached.quadrature.prior_mean {
            PriorMean::Zero => 0.0,
            PriorMean::Gls => self.gls.mean(values),
        };
        let centred: Vec<f64> = values.iter().map(|f| f - mean).collect();
        let alpha = self.cached.factorised.factorisation.solve(&centred);
        let xs = self.cached.directions();
        ys.iter()
            .map(|&y| {
                mean + xs
                    .iter()
                    .zip(&alpha)
                    .map(|(&x, a)| self.kernel.eval(y, x) * a)
                    .sum::<f64>()
            })
            .collect()
    }
}

impl HemisphereEstimator for BmcControlVariate {
    fn directions(&self, rng: &mut Pcg64) -> Cow<'_, [DVec3]> {
        let fresh = SampleSet::generate(SampleSetSpec {
            kind: SampleSetKind::StratifiedCosine,
            count: self.residual_samples,
            seed: rng.random(),
        })
        .expect("a count of at least 2 cosine directions is valid");
        let mut directions = self.cached.directions().to_vec();
        directions.extend(fresh.directions);
        Cow::Owned(directions)
    }

    fn estimate(&self, directions: &[DVec3], values: &[f64]) -> Result<Estimate, EstimatorError> {
        let expected = self.set_len() + self.residual_samples;
        for got in [directions.len(), values.len()] {
            if got != expected {
                return Err(EstimatorError::SampleCount { expected, got });
            }
        }
        let (set_values, fresh_values) = values.split_at(self.set_len());
        let fresh = &directions[self.set_len()..];
        let rule = self.cached.quadrature.estimate(set_values);
        let predicted = self.posterior_mean(set_values, fresh);
        let residuals: Vec<f64> = fresh_values
            .iter()
            .zip(&predicted)
            .map(|(f, m)| f - m)
            .collect();
        let correction =
            importance_rule(&self.cached.density, SamplingPdf::Cosine, fresh, &residuals);
        Ok(Estimate {
            value: rule + correction.value,
            variance: correction.variance,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::bmc::estimator::BayesianEstimator;
    use crate::bmc::estimator::BmcVariance;
    use crate::bmc::{Density, KernelKind, KernelMeanMethod};
    use rand::SeedableRng;

    fn quadrature(count: usize) -> (Arc<CachedQuadrature>, Kernel) {
        let cache = QuadratureCache::new(16 << 20);
        let kernel = Kernel::new(KernelKind::Matern32, 0.6, 1.0, 1e-6).expect("kernel");
        let spec = SampleSetSpec {
            kind: SampleSetKind::FibonacciCosine,
            count,
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
        (q, kernel)
    }

    /// Light from a disc of half-angle 25° tilted 40° off the normal, and a
    /// dimmer sky: an edge that a fixed set of 32 directions misplaces.
    fn occluded_sky(w: DVec3) -> f64 {
        let axis = DVec3::new(40f64.to_radians().sin(), 0.0, 40f64.to_radians().cos());
        if w.dot(axis) > 25f64.to_radians().cos() {
            4.0
        } else {
            0.5
        }
    }

    /// The centres of an `n × n` grid in `(sin² θ, φ)`, where the Lambert
    /// density is uniform: each direction carries weight `1/n²`.
    fn lambert_grid(n: usize) -> impl Iterator<Item = DVec3> {
        (0..n * n).map(move |k| {
            let u = ((k / n) as f64 + 0.5) / n as f64;
            let phi = 2.0 * std::f64::consts::PI * ((k % n) as f64 + 0.5) / n as f64;
            let (s, c) = (u.sqrt(), (1.0 - u).sqrt());
            DVec3::new(s * phi.cos(), s * phi.sin(), c)
        })
    }

    /// `∫ occluded_sky cos θ/π`: the cap's Lambert measure on a fine grid.
    fn truth() -> f64 {
        let n = 2000;
        let inside = lambert_grid(n).filter(|&w| occluded_sky(w) > 1.0).count();
        0.5 + 3.5 * inside as f64 / (n * n) as f64
    }

    fn run(estimator: &dyn HemisphereEstimator, rng: &mut Pcg64) -> Estimate {
        let directions = estimator.directions(rng);
        let values: Vec<f64> = directions.iter().map(|&w| occluded_sky(w)).collect();
        estimator.estimate(&directions, &values).expect("estimate")
    }

    #[test]
    fn the_posterior_mean_integrates_to_the_bmc_estimate_and_interpolates() {
        let (q, kernel) = quadrature(32);
        let cv = BmcControlVariate::new(q.clone(), kernel, 8);
        let xs = q.directions().to_vec();
        let values: Vec<f64> = xs.iter().map(|&w| occluded_sky(w)).collect();
        // Interpolates the set's values (noise 1e-6 of σ² = 1).
        for (m, f) in cv.posterior_mean(&values, &xs).iter().zip(&values) {
            assert!((m - f).abs() < 1e-2, "{m} against {f}");
        }
        // Its Lambert integral, on a fine grid, is wᵀf.
        let grid: Vec<DVec3> = lambert_grid(400).collect();
        let integral = cv.posterior_mean(&values, &grid).iter().sum::<f64>() / grid.len() as f64;
        let bmc = q.quadrature.estimate(&values);
        assert!((integral - bmc).abs() < 1e-3, "{integral} against {bmc}");
    }

    #[test]
    fn batches_average_to_the_integral_where_plain_bmc_keeps_its_bias() {
        let truth = truth();
        let (q, kernel) = quadrature(32);
        let cv = BmcControlVariate::new(q.clone(), kernel, 32);
        let plain = BayesianEstimator::new(q, BmcVariance::AmplitudeFit);
        let mut rng = Pcg64::seed_from_u64(7);
        let batches = 4000;
        let (mut sum, mut variance_sum, mut z2) = (0.0, 0.0, 0.0);
        for _ in 0..batches {
            let e = run(&cv, &mut rng);
            sum += e.value;
            variance_sum += e.variance;
            z2 += (e.value - truth).powi(2) / e.variance;
        }
        let mean = sum / f64::from(batches);
        let sigma = variance_sum.sqrt() / f64::from(batches);
        assert!(
            (mean - truth).abs() < 4.0 * sigma,
            "mean {mean} truth {truth} σ {sigma}"
        );
        // The residual's sample variance states each batch's error.
        let rms_z = (z2 / f64::from(batches)).sqrt();
        assert!((0.85..1.2).contains(&rms_z), "rms z {rms_z}");
        // Plain BMC on the fixed set is off by more than the batches' σ:
        // this is the bias the correction removes.
        let bmc = run(&plain, &mut rng).value;
        assert!((bmc - truth).abs() > 10.0 * sigma, "{bmc} {truth} {sigma}");
    }

    #[test]
    fn wrong_lengths_are_typed_errors() {
        let (q, kernel) = quadrature(16);
        let cv = BmcControlVariate::new(q, kernel, 4);
        let mut rng = Pcg64::seed_from_u64(1);
        let directions = cv.directions(&mut rng);
        assert_eq!(directions.len(), 20);
        assert!(matches!(
            cv.estimate(&directions, &[1.0; 16]),
            Err(EstimatorError::SampleCount {
                expected: 20,
                got: 16
            })
        ));
    }
}

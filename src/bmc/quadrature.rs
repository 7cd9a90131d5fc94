//! BMC quadrature rules: weights `w` with `Î = Σ w_i Y_i` and the posterior
//! variance of the integral (docs/math.md §3).
//!
//! Weights depend on the sample directions, the kernel and the density but
//! never on the observations, so one [`Quadrature`] serves every shading
//! point that uses the same (rotated) sample set.

use super::dense::dot;
use serde::{Deserialize, Serialize};

use super::density::Density;
use super::error::BmcError;
use super::factorisation::Factorisation;
use super::gls::Gls;
use super::kernel::Kernel;
use super::kernel_mean::{KernelMeanMethod, kernel_means, prior_variance};
use crate::sphere::SampleSet;

/// Prior mean of the GP over the integrand.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorMean {
    /// `m̄ = 0`: `Î = zᵀ Q⁻¹ Y`.
    #[default]
    Zero,
    /// Unknown constant mean with a flat prior, estimated by generalised least
    /// squares; constants are then integrated exactly (`Σ w_i = ∫p`).
    Gls,
}

/// A BMC quadrature rule for one (sample set, kernel, density, prior mean).
#[derive(Clone, Debug, Serialize)]
pub struct Quadrature {
    /// `z_i = ∫ k(ω_i, ω) p(ω) dω` (units of `σ²`).
    pub kernel_means: Vec<f64>,
    /// `w` such that `Î = Σ w_i Y_i`; with [`PriorMean::Gls`] they include the
    /// estimated constant mean and sum to `density_integral`.
    pub weights: Vec<f64>,
    /// `V₀ = ∫∫ k p p`: variance of the integral before seeing any sample.
    pub prior_variance: f64,
    /// Posterior variance of the integral, clamped at 0 (see `raw_posterior_variance`).
    pub posterior_variance: f64,
    /// The unclamped value; slightly negative only through rounding/jitter when
    /// the samples pin the integral down almost exactly.
    pub raw_posterior_variance: f64,
    /// `∫_H p` (1 for Uniform/Lambert, < 1 for clipped Phong lobes).
    pub density_integral: f64,
    /// Prior mean the weights were built for.
    pub prior_mean: PriorMean,
    /// How the kernel means were computed.
    pub method: KernelMeanMethod,
    /// Jitter of the factorisation used (absolute, on the diagonal of `Q`).
    pub jitter: f64,
    /// Condition estimate of the factorisation used.
    pub condition_estimate: f64,
}

impl Quadrature {
    /// Weights and variances for `set`, `kernel` and `density`, using the
    /// factorisation of `Q` for the same set and kernel.
    ///
    /// Zero mean: `w = Q⁻¹ z`, `V = V₀ − zᵀQ⁻¹z`.
    ///
    /// GLS constant mean (universal kriging of the integral): with
    /// `u = Q⁻¹1`, `s = 1ᵀu`, `P = ∫p` and `R = P − 1ᵀQ⁻¹z`,
    /// `Î = m̂ P + zᵀQ⁻¹(Y − m̂1)`, `m̂ = uᵀY/s`, so `w = Q⁻¹z + u R/s` (and
    /// `Σ w = P`), and `V = V₀ − zᵀQ⁻¹z + R²/s`, the extra term being the
    /// uncertainty of `m̂` (Rasmussen & Williams, *Gaussian Processes for
    /// Machine Learning*, 2006, §2.7, eqs. 2.41–2.42, with a vague prior on
    /// the coefficient and basis `h = 1`, whose "test" value is `∫ 1 p = P`
    /// and whose cross-covariance is `z`; O'Hagan 1991, "Bayes–Hermite
    /// quadrature"). The test `variances_equal_the_error_variance_of_their_weights`
    /// checks it against `wᵀQw − 2wᵀz + V₀`.
    pub fn new(
        set: &SampleSet,
        kernel: &Kernel,
        factorisation: &Factorisation,
        density: &Density,
        prior_mean: PriorMean,
        method: KernelMeanMethod,
    ) -> Result<Quadrature, BmcError> {
        kernel.validate()?;
        density.validate()?;
        if !factorisation.matches(set, kernel) {
            return Err(BmcError::Mismatch {
                field: "factorisation",
                expected: format!("{:?} with {:?}", set.spec, kernel),
                actual: "a factorisation of another sample set or kernel".into(),
            });
        }
        let z = kernel_means(&set.directions, kernel, density, method)?;
        let prior_variance = prior_variance(kernel, density, method)?;
        let density_integral = density.integral();
        let w0 = factorisation.solve(&z);
        let explained = dot(&z, &w0);
        let (weights, raw) = match prior_mean {
            PriorMean::Zero => (w0, prior_variance - explained),
            PriorMean::Gls => {
                let gls = Gls::new(factorisation);
                let (u, s) = (gls.ones_solved(), gls.ones_sum());
                let r = density_integral - w0.iter().sum::<f64>();
                let weights = w0.iter().zip(u).map(|(w, u)| w + u * r / s).collect();
                (weights, prior_variance - explained + r * r / s)
            }
        };
        Ok(Quadrature {
            kernel_means: z,
            weights,
            prior_variance,
            posterior_variance: raw.max(0.0),
            raw_posterior_variance: raw,
            density_integral,
            prior_mean,
            method,
            jitter: factorisation.jitter,
            condition_estimate: factorisation.condition_estimate,
        })
    }

    /// `Î = Σ w_i y_i` for observations at the set's directions, in order.
    ///
    /// # Panics
    /// If `values.len()` differs from the number of weights (a programming
    /// error; use [`Self::try_estimate`] for unchecked input).
    pub fn estimate(&self, values: &[f64]) -> f64 {
        assert_eq!(values.len(), self.weights.len(), "one value per direction");
        dot(&self.weights, values)
    }

    /// [`Self::estimate`] with a typed error on a length mismatch.
    pub fn try_estimate(&self, values: &[f64]) -> Result<f64, BmcError> {
        if values.len() != self.weights.len() {
            return Err(BmcError::Mismatch {
                field: "values",
                expected: self.weights.len().to_string(),
                actual: values.len().to_string(),
            });
        }
        Ok(self.estimate(values))
    }

    /// Approximate heap + inline size, for byte-bounded caches.
    pub fn size_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + (self.kernel_means.len() + self.weights.len()) * std::mem::size_of::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use glam::DVec3;
    use nalgebra::{DMatrix, DVector};
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    use super::*;
    use crate::bmc::kernel::KernelKind;
    use crate::sphere::{SampleSetKind, SampleSetSpec};

    fn set(kind: SampleSetKind, count: usize, seed: u64) -> SampleSet {
        SampleSet::generate(SampleSetSpec { kind, count, seed }).unwrap()
    }

    fn rule(
        s: &SampleSet,
        k: &Kernel,
        d: &Density,
        mean: PriorMean,
    ) -> (Factorisation, Quadrature) {
        let f = Factorisation::new(s, k).unwrap();
        let q = Quadrature::new(s, k, &f, d, mean, KernelMeanMethod::Exact).unwrap();
        (f, q)
    }

    /// A grazing, clipped glossy lobe.
    const PHONG: Density = Density::Phong {
        exponent: 12.0,
        mirror_elevation: 1.1,
    };

    fn kernels() -> [Kernel; 3] {
        [
            Kernel::new(KernelKind::SquaredExponential, 0.4, 1.0, 0.0).unwrap(),
            Kernel::new(KernelKind::Matern32, 0.6, 2.0, 1e-6).unwrap(),
            Kernel::new(KernelKind::Matern52, 0.5, 0.5, 0.0).unwrap(),
        ]
    }

    /// docs/math.md §8: `Σ_i w_i k(ω_i, ω_j) = z_j` up to the diagonal term.
    #[test]
    fn weights_integrate_kernel_sections_exactly() {
        let s = set(SampleSetKind::Uniform, 24, 4);
        let mut cases: Vec<(Kernel, Density)> = kernels()
            .into_iter()
            .flat_map(|k| [(k, Density::Lambert), (k, Density::Uniform)])
            .collect();
        cases.push((kernels()[0], PHONG));
        for (k, d) in cases {
            let (f, q) = rule(&s, &k, &d, PriorMean::Zero);
            let diag = k.noise + f.jitter;
            let zmax = q.kernel_means.iter().fold(0.0f64, |a, b| a.max(*b));
            for (j, wj) in s.directions.iter().enumerate() {
                let kw: f64 = s
                    .directions
                    .iter()
                    .zip(&q.weights)
                    .map(|(wi, w)| w * k.eval(*wi, *wj))
                    .sum();
                let expected = q.kernel_means[j] - diag * q.weights[j];
                assert!((kw - expected).abs() < 1e-9 * zmax, "{k:?} {d:?} j={j}");
            }
        }
    }

    /// docs/math.md §8: `0 ≤ V ≤ V₀` and `V` shrinks as samples are added
    /// (random sets with one seed are nested: the first `n` of `2n` agree).
    #[test]
    fn posterior_variance_is_bounded_and_shrinks_with_more_samples() {
        for k in kernels() {
            for d in [Density::Lambert, Density::Uniform] {
                for mean in [PriorMean::Zero, PriorMean::Gls] {
                    let mut last = f64::INFINITY;
                    for n in [4, 8, 16, 32] {
                        let s = set(SampleSetKind::Uniform, n, 11);
                        let (_, q) = rule(&s, &k, &d, mean);
                        assert!(q.posterior_variance >= 0.0);
                        assert!(q.posterior_variance <= last, "{k:?} {d:?} {mean:?} n={n}");
                        if mean == PriorMean::Zero {
                            assert!(q.posterior_variance <= q.prior_variance);
                        }
                        last = q.posterior_variance;
                    }
                    assert!(last < 0.5 * q0(&k, &d), "{k:?} {d:?} did not shrink");
                }
            }
        }
        let k = kernels()[0];
        let mut last = f64::INFINITY;
        for n in [4, 16] {
            let (_, q) = rule(
                &set(SampleSetKind::Uniform, n, 11),
                &k,
                &PHONG,
                PriorMean::Zero,
            );
            assert!(q.posterior_variance >= 0.0 && q.posterior_variance < last);
            assert!(q.posterior_variance <= q.prior_variance);
            last = q.posterior_variance;
        }
    }

    fn q0(k: &Kernel, d: &Density) -> f64 {
        prior_variance(k, d, KernelMeanMethod::Exact).unwrap()
    }

    /// docs/math.md §8: with the GLS constant mean, `Σ w_i = ∫p` and constants
    /// are integrated exactly (furnace test: uniform `L` gives `E = πL`).
    #[test]
    fn gls_weights_sum_to_the_density_integral_and_pass_the_furnace_test() {
        let s = set(SampleSetKind::Fibonacci, 40, 0);
        for k in kernels() {
            for d in [Density::Lambert, Density::Uniform] {
                let (_, q) = rule(&s, &k, &d, PriorMean::Gls);
                let sum: f64 = q.weights.iter().sum();
                assert!((sum - d.integral()).abs() < 1e-12, "{k:?} {d:?}");
            }
            if k.kind != KernelKind::Matern32 {
                let (_, q) = rule(&s, &k, &PHONG, PriorMean::Gls);
                let sum: f64 = q.weights.iter().sum();
                assert!((sum - PHONG.integral()).abs() < 1e-12, "{k:?} Phong");
            }
            let (_, q) = rule(&s, &k, &Density::Lambert, PriorMean::Gls);
            let radiance = 3.7;
            let irradiance = PI * q.estimate(&vec![radiance; s.len()]);
            assert!((irradiance - PI * radiance).abs() < 1e-11);
        }
        // Zero mean: only approximately, and better for longer lengthscales.
        let mut last = f64::INFINITY;
        for ell in [0.3, 1.0, 2.0] {
            let k = Kernel::new(KernelKind::SquaredExponential, ell, 1.0, 0.0).unwrap();
            let (_, q) = rule(&s, &k, &Density::Lambert, PriorMean::Zero);
            let err = (q.estimate(&vec![1.0; s.len()]) - 1.0).abs();
            assert!(err < last, "ℓ={ell}: {err}");
            last = err;
        }
        assert!(last < 1e-3, "{last}");
    }

    /// docs/math.md §8: `∫_H (a + b·ω) cos θ dω = aπ + (2π/3) b_z`.
    #[test]
    fn linear_radiance_is_integrated_accurately() {
        let (a, b) = (0.8, DVec3::new(0.3, -0.5, 0.6));
        let exact = a * PI + 2.0 * PI / 3.0 * b.z;
        let s = set(SampleSetKind::Fibonacci, 64, 0);
        for k in kernels() {
            let (_, q) = rule(&s, &k, &Density::Lambert, PriorMean::Gls);
            let y: Vec<f64> = s.directions.iter().map(|w| a + b.dot(*w)).collect();
            let e = PI * q.estimate(&y);
            assert!((e / exact - 1.0).abs() < 2e-3, "{k:?}: {e} vs {exact}");
        }
        let k = Kernel::new(KernelKind::SquaredExponential, 1.0, 1.0, 0.0).unwrap();
        let (_, q) = rule(&s, &k, &Density::Lambert, PriorMean::Gls);
        let y: Vec<f64> = s.directions.iter().map(|w| a + b.dot(*w)).collect();
        assert!((PI * q.estimate(&y) / exact - 1.0).abs() < 1e-6);
    }

    /// Both variances are the exact error variance of their linear
    /// estimator: for any weights, `Var(Σ w_i Y_i − I) = wᵀQw − 2wᵀz + V₀`
    /// under `f ~ GP(0, k)`; with the GLS weights, the error does not depend on
    /// the unknown constant at all (the weights sum to `∫p`), so the
    /// universal-kriging formula must agree with this identity exactly.
    #[test]
    fn variances_equal_the_error_variance_of_their_weights() {
        let s = set(SampleSetKind::Cosine, 20, 8);
        for k in kernels() {
            for d in [Density::Lambert, PHONG] {
                for mean in [PriorMean::Zero, PriorMean::Gls] {
                    if k.kind == KernelKind::Matern32 && d == PHONG {
                        continue; // slowest combination; covered by calibration
                    }
                    let (f, q) = rule(&s, &k, &d, mean);
                    let n = s.len();
                    let w = &q.weights;
                    let mut wqw = 0.0;
                    for i in 0..n {
                        for j in 0..n {
                            wqw += w[i] * w[j] * k.eval(s.directions[i], s.directions[j]);
                        }
                        wqw += w[i] * w[i] * (k.noise + f.jitter);
                    }
                    let wz: f64 = w.iter().zip(&q.kernel_means).map(|(a, b)| a * b).sum();
                    let direct = wqw - 2.0 * wz + q.prior_variance;
                    assert!(
                        (direct - q.raw_posterior_variance).abs() < 1e-9 * q.prior_variance,
                        "{k:?} {d:?} {mean:?}: {direct} vs {}",
                        q.raw_posterior_variance
                    );
                }
            }
        }
    }

    /// docs/math.md §8 calibration: for `f ~ GP(0, k)`, `(Y, I)` is jointly
    /// Gaussian with `Cov Y = K + σ_n² I`, `Cov(Y, I) = z`, `Var I = V₀`; drawing
    /// them jointly, `(Î − I)/sqrt(V)` must be standard normal.
    #[test]
    fn posterior_variance_is_calibrated_over_gp_draws() {
        let s = set(SampleSetKind::Stratified, 10, 3);
        for (k, d) in [
            (
                Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 0.0).unwrap(),
                Density::Lambert,
            ),
            (
                Kernel::new(KernelKind::Matern32, 0.4, 2.0, 0.01).unwrap(),
                PHONG,
            ),
            (
                Kernel::new(KernelKind::Matern52, 0.3, 1.0, 0.0).unwrap(),
                Density::Uniform,
            ),
        ] {
            let (f, q) = rule(&s, &k, &d, PriorMean::Zero);
            assert_eq!(f.jitter, 0.0);
            let n = s.len();
            let mut joint = DMatrix::zeros(n + 1, n + 1);
            for i in 0..n {
                for j in 0..n {
                    joint[(i, j)] = k.eval(s.directions[i], s.directions[j]);
                }
                joint[(i, i)] += k.noise;
                joint[(i, n)] = q.kernel_means[i];
                joint[(n, i)] = q.kernel_means[i];
            }
            joint[(n, n)] = q.prior_variance;
            let l = joint.cholesky().expect("joint covariance is PD").l();
            let mut rng = Pcg64::seed_from_u64(42);
            let draws = 1000;
            let (mut covered, mut sum_sq) = (0, 0.0);
            for _ in 0..draws {
                let e = DVector::from_fn(n + 1, |_, _| crate::testing::standard_normal(&mut rng));
                let x = &l * e;
                let t = (q.estimate(&x.as_slice()[..n]) - x[n]) / q.posterior_variance.sqrt();
                covered += usize::from(t.abs() <= 2.0);
                sum_sq += t * t;
            }
            let coverage = covered as f64 / draws as f64;
            assert!((0.90..=0.99).contains(&coverage), "{k:?}: {coverage}");
            let var = sum_sq / draws as f64;
            assert!((0.85..=1.15).contains(&var), "{k:?}: {var}");
        }
    }

    #[test]
    fn mismatched_factorisation_and_values_are_typed_errors() {
        let s = set(SampleSetKind::Uniform, 8, 1);
        let [k1, k2, _] = kernels();
        let f = Factorisation::new(&s, &k1).unwrap();
        let err = Quadrature::new(
            &s,
            &k2,
            &f,
            &Density::Lambert,
            PriorMean::Zero,
            KernelMeanMethod::Exact,
        )
        .unwrap_err();
        assert_eq!(err.field(), Some("factorisation"));
        let q = Quadrature::new(
            &s,
            &k1,
            &f,
            &Density::Lambert,
            PriorMean::Zero,
            KernelMeanMethod::Exact,
        )
        .unwrap();
        assert_eq!(q.try_estimate(&[1.0]).unwrap_err().field(), Some("values"));
        let bad = Density::Phong {
            exponent: f64::NAN,
            mirror_elevation: 0.0,
        };
        let err = Quadrature::new(&s, &k1, &f, &bad, PriorMean::Zero, KernelMeanMethod::Exact)
            .unwrap_err();
        assert_eq!(err.field(), Some("exponent"));
        let err = Quadrature::new(
            &s,
            &k2,
            &Factorisation::new(&s, &k2).unwrap(),
            &Density::Lambert,
            PriorMean::Zero,
            KernelMeanMethod::SphericalGaussian,
        )
        .unwrap_err();
        assert!(matches!(err, BmcError::Unsupported { .. }));
    }
}

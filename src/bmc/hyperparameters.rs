//! Kernel hyperparameters by maximum marginal likelihood (docs/math.md §7).
//!
//! Many shading points share one sample set, so their observation vectors
//! `Y_1..Y_M` are pooled: with the unit-variance kernel matrix
//! `K̃(ℓ) + η I` (`η = σ_n²/σ²`, the noise ratio) and `Q = σ² (K̃ + ηI)`,
//! the summed log marginal likelihood
//!
//! `Σ_m [−½ r_mᵀ Q⁻¹ r_m − ½ log|Q| − (N/2) log 2π]`
//!
//! is maximised by `σ̂² = (1/(MN)) Σ_m r_mᵀ (K̃ + ηI)⁻¹ r_m` in closed form,
//! leaving the profile likelihood
//! `−(MN/2)(log σ̂² + 1 + log 2π) − (M/2) log|K̃ + ηI|` in `ℓ` (and `η`).
//! `r_m` is `Y_m` minus its generalised-least-squares constant mean
//! `m̂ = 1ᵀ(K̃+ηI)⁻¹Y / 1ᵀ(K̃+ηI)⁻¹1` (docs/math.md §3), matching the GLS prior
//! mean of the quadrature.
//!
//! The profile is maximised over `log ℓ` by a coarse grid and golden-section
//! refinement around the best grid point; a fitted noise ratio is profiled
//! over a half-decade grid of `log η` (ℓ re-optimised at each) and refined
//! by golden section with ℓ re-optimised inside.

use serde::Serialize;

use super::gls::Gls;
use crate::bmc::{BmcError, Factorisation, Kernel, KernelKind};
use crate::sphere::SampleSet;

/// Search range and noise treatment for [`fit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Lengthscale search interval (chordal distance units; on the unit
    /// sphere `ℓ ∈ [0.05, 5]` spans needle-sharp to nearly constant).
    pub lengthscale_bounds: (f64, f64),
    /// Noise ratio `σ_n²/σ²`: fixed when the bounds are equal, else fitted.
    pub noise_ratio_bounds: (f64, f64),
    /// Lengthscale grid points before refinement (≥ 3).
    pub grid_points: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            lengthscale_bounds: (0.05, 5.0),
            noise_ratio_bounds: (1e-8, 1e-8),
            grid_points: 21,
        }
    }
}

/// Fitted hyperparameters and how well the data determined them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Fit {
    /// Maximum-likelihood lengthscale `ℓ`.
    pub lengthscale: f64,
    /// Closed-form amplitude `σ̂²` at that `ℓ` (units of `Y²`).
    pub variance: f64,
    /// Observation noise `σ_n² = η σ̂²` (units of `Y²`).
    pub noise: f64,
    /// Summed log marginal likelihood at the optimum.
    pub log_likelihood: f64,
    /// `ℓ` ended within 1 % (in log space) of a search bound: the data
    /// prefer a value outside the range, so treat `ℓ` as not identified.
    pub lengthscale_at_bound: bool,
    /// The same for a fitted noise ratio (always `false` when fixed).
    pub noise_at_bound: bool,
}

impl Fit {
    /// Either fitted hyperparameter ended at (within 1 % of) a search bound,
    /// so the optimum found is the bound's, not the likelihood's.
    pub fn at_bound(&self) -> bool {
        self.lengthscale_at_bound || self.noise_at_bound
    }
}

/// Why hyperparameters could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// Fewer observation vectors than needed to pool a likelihood.
    #[error("observations: need at least {needed} vectors, got {got}")]
    TooFewVectors {
        /// Minimum number of vectors.
        needed: usize,
        /// Number supplied.
        got: usize,
    },
    /// A vector's length differs from the sample set's size.
    #[error("observations[{index}]: expected {expected} values, got {got}")]
    Length {
        /// Offending vector.
        index: usize,
        /// Sample count of the set.
        expected: usize,
        /// Its length.
        got: usize,
    },
    /// A value is NaN or infinite.
    #[error("observations[{index}]: non-finite value")]
    NonFinite {
        /// Offending vector.
        index: usize,
    },
    /// Every vector is constant: after mean removal nothing is left to
    /// determine the lengthscale or the amplitude.
    #[error("observations: every vector is constant; lengthscale and variance are not identified")]
    ConstantData,
    /// Bounds that are not finite, positive and ordered.
    #[error("{field}: bounds must be finite, positive and ordered")]
    Bounds {
        /// Which bounds.
        field: &'static str,
    },
    /// The kernel matrix could not be built or factorised.
    #[error(transparent)]
    Bmc(#[from] BmcError),
}

impl FitError {
    /// The input field at fault.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::TooFewVectors { .. }
            | Self::Length { .. }
            | Self::NonFinite { .. }
            | Self::ConstantData => Some("observations"),
            Self::Bounds { field } => Some(field),
            Self::Bmc(e) => e.field(),
        }
    }
}

/// Minimum number of observation vectors [`fit`] accepts.
pub const MIN_VECTORS: usize = 2;

/// Maximises the pooled marginal likelihood of `observations` (one vector of
/// radiance samples per shading point, in the order of `set.directions`) over
/// the lengthscale (and noise ratio) of a `kind` kernel; see the module docs.
pub fn fit(
    set: &SampleSet,
    kind: KernelKind,
    observations: &[Vec<f64>],
    options: &FitOptions,
) -> Result<Fit, FitError> {
    validate(set, observations, options)?;
    let profile = Profile {
        set,
        kind,
        observations,
    };
    let log_bounds = |(lo, hi): (f64, f64)| (lo.ln(), hi.ln());
    let (l_lo, l_hi) = log_bounds(options.lengthscale_bounds);
    let (n_lo, n_hi) = log_bounds(options.noise_ratio_bounds);
    let fit_noise = n_hi > n_lo;

    let l_step = (l_hi - l_lo) / (options.grid_points - 1) as f64;
    // Profile out ℓ for a given η: grid (or a bracket around a previous
    // optimum), then golden section within one step of the best point.
    let best_lengthscale = |log_eta: f64, around: Option<f64>| -> Result<(f64, f64), FitError> {
        let (lo, hi, count) = match around {
            Some(x) => (
                (x - 2.0 * l_step).max(l_lo),
                (x + 2.0 * l_step).min(l_hi),
                5,
            ),
            None => (l_lo, l_hi, options.grid_points),
        };
        let mut best = (f64::NEG_INFINITY, lo);
        for i in 0..count {
            let log_l = lo + (hi - lo) * i as f64 / (count - 1) as f64;
            let value = profile.log_likelihood(log_l, log_eta)?.0;
            if value > best.0 {
                best = (value, log_l);
            }
        }
        let step = (hi - lo) / (count - 1) as f64;
        let log_l = golden_section((best.1 - step).max(lo), (best.1 + step).min(hi), |x| {
            profile.log_likelihood(x, log_eta).map(|v| v.0)
        })?;
        Ok((profile.log_likelihood(log_l, log_eta)?.0, log_l))
    };
    // η is profiled over a grid of half decades first: the likelihood has a
    // ridge along which short ℓ with no noise competes with longer ℓ plus
    // noise, so coordinate-wise search from one start point is not enough.
    let eta_steps = if n_hi > n_lo {
        ((n_hi - n_lo) / (0.5 * std::f64::consts::LN_10)).ceil() as usize
    } else {
        0
    };
    let mut best = (f64::NEG_INFINITY, l_lo, n_lo);
    for k in 0..=eta_steps {
        let log_eta = if eta_steps == 0 {
            n_lo
        } else {
            n_lo + (n_hi - n_lo) * k as f64 / eta_steps as f64
        };
        let (value, log_l) = best_lengthscale(log_eta, None)?;
        if value > best.0 {
            best = (value, log_l, log_eta);
        }
    }
    let (_, mut log_l, mut log_eta) = best;
    if eta_steps > 0 {
        let n_step = (n_hi - n_lo) / eta_steps as f64;
        log_eta = golden_section(
            (log_eta - n_step).max(n_lo),
            (log_eta + n_step).min(n_hi),
            |x| best_lengthscale(x, Some(log_l)).map(|v| v.0),
        )?;
        log_l = best_lengthscale(log_eta, Some(log_l))?.1;
    }
    let (log_likelihood, variance) = profile.log_likelihood(log_l, log_eta)?;
    let near = |x: f64, lo: f64, hi: f64| (x - lo).abs().min((hi - x).abs()) < 0.01 * (hi - lo);
    Ok(Fit {
        lengthscale: log_l.exp(),
        variance,
        noise: log_eta.exp() * variance,
        log_likelihood,
        lengthscale_at_bound: near(log_l, l_lo, l_hi),
        noise_at_bound: fit_noise && near(log_eta, n_lo, n_hi),
    })
}

fn validate(
    set: &SampleSet,
    observations: &[Vec<f64>],
    options: &FitOptions,
) -> Result<(), FitError> {
    if observations.len() < MIN_VECTORS {
        return Err(FitError::TooFewVectors {
            needed: MIN_VECTORS,
            got: observations.len(),
        });
    }
    let n = set.directions.len();
    for (index, y) in observations.iter().enumerate() {
        if y.len() != n {
            return Err(FitError::Length {
                index,
                expected: n,
                got: y.len(),
            });
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(FitError::NonFinite { index });
        }
    }
    let ordered = |(lo, hi): (f64, f64)| lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo;
    if !ordered(options.lengthscale_bounds)
        || options.lengthscale_bounds.1 == options.lengthscale_bounds.0
    {
        return Err(FitError::Bounds {
            field: "lengthscale_bounds",
        });
    }
    if !ordered(options.noise_ratio_bounds) {
        return Err(FitError::Bounds {
            field: "noise_ratio_bounds",
        });
    }
    if options.grid_points < 3 {
        return Err(FitError::Bounds {
            field: "grid_points",
        });
    }
    let constant = observations.iter().all(|y| {
        let first = y[0];
        y.iter()
            .all(|&v| (v - first).abs() <= 1e-12 * first.abs().max(1e-300))
    });
    if constant {
        return Err(FitError::ConstantData);
    }
    Ok(())
}

struct Profile<'a> {
    set: &'a SampleSet,
    kind: KernelKind,
    observations: &'a [Vec<f64>],
}

impl Profile<'_> {
    /// Profile log likelihood and `σ̂²` at `(log ℓ, log η)`.
    fn log_likelihood(&self, log_l: f64, log_eta: f64) -> Result<(f64, f64), FitError> {
        let kernel = Kernel::new(self.kind, log_l.exp(), 1.0, log_eta.exp())?;
        let factorisation = Factorisation::new(self.set, &kernel)?;
        let n = self.set.directions.len();
        let gls = Gls::new(&factorisation);
        let mut quadratic = 0.0;
        for y in self.observations {
            quadratic += gls.residual(y, &factorisation.solve(y));
        }
        // Maximum likelihood: the profiled amplitude divides by every value
        // (M points × N directions), as the likelihood it maximises does.
        let total = (self.observations.len() * n) as f64;
        let variance = quadratic / total;
        if variance <= 0.0 || !variance.is_finite() {
            return Err(FitError::ConstantData);
        }
        let log_likelihood =
            -0.5 * total * (variance.ln() + 1.0 + (2.0 * std::f64::consts::PI).ln())
                - 0.5 * self.observations.len() as f64 * factorisation.log_determinant();
        Ok((log_likelihood, variance))
    }
}

/// Maximiser of a unimodal `f` on `[lo, hi]` by golden-section search, to a
/// bracket width of 1e-4 (in log units: 0.01 % of the parameter).
fn golden_section(
    mut lo: f64,
    mut hi: f64,
    mut f: impl FnMut(f64) -> Result<f64, FitError>,
) -> Result<f64, FitError> {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let mut a = hi - ratio * (hi - lo);
    let mut b = lo + ratio * (hi - lo);
    let (mut fa, mut fb) = (f(a)?, f(b)?);
    while hi - lo > 1e-4 {
        if fa >= fb {
            hi = b;
            (b, fb) = (a, fa);
            a = hi - ratio * (hi - lo);
            fa = f(a)?;
        } else {
            lo = a;
            (a, fa) = (b, fb);
            b = lo + ratio * (hi - lo);
            fb = f(b)?;
        }
    }
    Ok(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::{SampleSetKind, SampleSetSpec};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    fn set(count: usize) -> SampleSet {
        SampleSet::generate(SampleSetSpec {
            kind: SampleSetKind::Fibonacci,
            count,
            seed: 0,
        })
        .expect("valid set")
    }

    /// `vectors` draws of `GP(c, k)` at the set's directions, with `c` a
    /// random offset per draw (removed by the GLS mean).
    pub(super) fn gp_draws(
        set: &SampleSet,
        kernel: &Kernel,
        vectors: usize,
        seed: u64,
    ) -> Vec<Vec<f64>> {
        let n = set.directions.len();
        let k = nalgebra::DMatrix::from_fn(n, n, |i, j| {
            kernel.eval(set.directions[i], set.directions[j])
                + if i == j { kernel.noise } else { 0.0 }
        });
        let l = k.cholesky().expect("positive definite").l();
        let mut rng = Pcg64::seed_from_u64(seed);
        (0..vectors)
            .map(|_| {
                let z =
                    nalgebra::DVector::from_fn(n, |_, _| crate::testing::standard_normal(&mut rng));
                let offset = rng.random_range(-1.0..1.0);
                (&l * z).iter().map(|y| y + offset).collect()
            })
            .collect()
    }

    #[test]
    fn recovers_the_lengthscale_of_gp_draws() {
        let set = set(64);
        for (lengthscale, variance) in [(0.3, 2.0), (0.6, 0.5)] {
            let truth = Kernel::new(
                KernelKind::SquaredExponential,
                lengthscale,
                variance,
                1e-6 * variance,
            )
            .expect("kernel");
            let draws = gp_draws(&set, &truth, 30, 11);
            let options = FitOptions {
                noise_ratio_bounds: (1e-6, 1e-6),
                ..FitOptions::default()
            };
            let fit = fit(&set, KernelKind::SquaredExponential, &draws, &options).expect("fit");
            assert!((fit.lengthscale / lengthscale - 1.0).abs() < 0.2, "{fit:?}");
            assert!((fit.variance / variance - 1.0).abs() < 0.4, "{fit:?}");
            assert!(!fit.lengthscale_at_bound);
        }
    }

    #[test]
    fn fitted_noise_is_found() {
        let set = set(48);
        let truth = Kernel::new(KernelKind::Matern52, 0.5, 1.0, 0.05).expect("kernel");
        let draws = gp_draws(&set, &truth, 40, 5);
        let options = FitOptions {
            noise_ratio_bounds: (1e-8, 1.0),
            ..FitOptions::default()
        };
        let fit = fit(&set, KernelKind::Matern52, &draws, &options).expect("fit");
        let ratio = fit.noise / fit.variance;
        assert!((0.02..0.12).contains(&ratio), "{fit:?}");
        assert!((fit.lengthscale / 0.5 - 1.0).abs() < 0.3, "{fit:?}");
    }

    /// Noise-free draws leave the noise ratio at its lower bound while `ℓ`
    /// is found inside its range: the fit is still at a bound.
    #[test]
    fn noise_at_its_bound_counts_as_at_bound() {
        let set = set(48);
        let truth = Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 1e-10).expect("kernel");
        let draws = gp_draws(&set, &truth, 20, 7);
        let options = FitOptions {
            noise_ratio_bounds: (1e-5, 1e-1),
            ..FitOptions::default()
        };
        let fit = fit(&set, KernelKind::SquaredExponential, &draws, &options).expect("fit");
        assert!(fit.noise_at_bound, "{fit:?}");
        assert!(!fit.lengthscale_at_bound, "{fit:?}");
        assert!(fit.at_bound());
        let interior = Fit {
            noise_at_bound: false,
            ..fit
        };
        assert!(!interior.at_bound());
        let short = Fit {
            lengthscale_at_bound: true,
            ..interior
        };
        assert!(short.at_bound());
    }

    #[test]
    fn white_noise_pushes_the_lengthscale_to_its_bound() {
        let set = set(32);
        let mut rng = Pcg64::seed_from_u64(3);
        let draws: Vec<Vec<f64>> = (0..20)
            .map(|_| (0..32).map(|_| rng.random::<f64>()).collect())
            .collect();
        let fit = fit(
            &set,
            KernelKind::SquaredExponential,
            &draws,
            &FitOptions::default(),
        )
        .expect("fit");
        assert!(fit.lengthscale_at_bound, "{fit:?}");
    }

    #[test]
    fn unidentifiable_or_bad_data_are_typed_errors() {
        let set = set(16);
        let options = FitOptions::default();
        let kind = KernelKind::SquaredExponential;
        let constant = vec![vec![2.0; 16]; 5];
        assert!(matches!(
            fit(&set, kind, &constant, &options),
            Err(FitError::ConstantData)
        ));
        let one = vec![vec![1.0; 16]];
        assert!(matches!(
            fit(&set, kind, &one, &options),
            Err(FitError::TooFewVectors { got: 1, .. })
        ));
        let short = vec![vec![1.0; 16], vec![1.0; 15]];
        let err = fit(&set, kind, &short, &options).expect_err("length");
        assert!(matches!(err, FitError::Length { index: 1, .. }));
        assert_eq!(err.field(), Some("observations"));
        let mut nan = vec![(0..16).map(f64::from).collect::<Vec<_>>(); 2];
        nan[1][3] = f64::NAN;
        assert!(matches!(
            fit(&set, kind, &nan, &options),
            Err(FitError::NonFinite { index: 1 })
        ));
        let varied = vec![(0..16).map(f64::from).collect::<Vec<_>>(); 2];
        let bad_bounds = FitOptions {
            lengthscale_bounds: (-1.0, 2.0),
            ..options
        };
        let err = fit(&set, kind, &varied, &bad_bounds).expect_err("bounds");
        assert_eq!(err.field(), Some("lengthscale_bounds"));
    }
}

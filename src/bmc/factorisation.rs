//! Cholesky factorisation of the BMC Gram matrix `Q = K + (σ_n² + jitter) I`
//! (bmc-math.md §3), computed once per (sample set, kernel) and shared by
//! every density, prior mean and shading point.
//!
//! The linear algebra (nalgebra today) stays behind this type so that it can
//! be swapped for another backend without touching callers.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};
use rayon::prelude::*;

use super::error::BmcError;
use super::kernel::{Kernel, KernelKey};
use crate::sphere::{MAX_SAMPLES, SampleSet, SampleSetSpec};

/// First jitter tried after a failure, relative to the mean diagonal of `K + σ_n² I`.
const FIRST_RELATIVE_JITTER: f64 = 1e-10;
/// Largest jitter tried, relative to the mean diagonal; beyond it the prior
/// is being changed rather than regularised, so we report an error.
const MAX_RELATIVE_JITTER: f64 = 1e-2;
/// Largest accepted condition estimate: beyond it the triangular solves lose
/// more than ~13 of 16 digits, so the jitter is escalated further.
const MAX_CONDITION: f64 = 1e13;

/// `Q = L Lᵀ` with the jitter that made it numerically positive definite.
#[derive(Clone, Debug)]
pub struct Factorisation {
    cholesky: Cholesky<f64, Dyn>,
    /// The set the factor was built from, to reject mismatched uses.
    spec: SampleSetSpec,
    /// The kernel the factor was built from, likewise.
    kernel: KernelKey,
    /// Jitter added to the diagonal on top of `σ_n²` (absolute; 0 when none was needed).
    pub jitter: f64,
    /// `(max_i L_ii / min_i L_ii)²`, a cheap lower bound on the 2-norm
    /// condition number of `Q` (each pivot `L_ii²` lies in `[λ_min, λ_max]`).
    pub condition_estimate: f64,
}

impl Factorisation {
    /// Factor `Q` for this set and kernel. Tries no jitter first, then
    /// `1e-10 × mean diag`, growing ×10, until the Cholesky succeeds with a
    /// condition estimate below 1e13; a typed error past `1e-2 × mean diag`.
    pub fn new(set: &SampleSet, kernel: &Kernel) -> Result<Factorisation, BmcError> {
        kernel.validate()?;
        let n = set.directions.len();
        if n == 0 || n > MAX_SAMPLES {
            return Err(BmcError::invalid(
                "samples",
                format!("must be between 1 and {MAX_SAMPLES}, got {n}"),
            ));
        }
        if let Some(bad) = set
            .directions
            .iter()
            .find(|d| !d.is_finite() || (d.length() - 1.0).abs() > 1e-9)
        {
            return Err(BmcError::invalid(
                "directions",
                format!("must be finite unit vectors, got {bad}"),
            ));
        }
        let dirs = &set.directions;
        // Column-major fill; K is symmetric, so rows and columns coincide.
        let mut data = vec![0.0; n * n];
        data.par_chunks_mut(n).enumerate().for_each(|(j, col)| {
            for (i, value) in col.iter_mut().enumerate() {
                *value = kernel.eval(dirs[i], dirs[j]);
            }
        });
        let k = DMatrix::from_vec(n, n, data);
        let mean_diag = kernel.variance + kernel.noise;
        let mut jitter = 0.0;
        loop {
            let mut q = k.clone();
            for i in 0..n {
                q[(i, i)] += kernel.noise + jitter;
            }
            if let Some(cholesky) = Cholesky::new(q) {
                let condition_estimate = condition_estimate(&cholesky);
                if condition_estimate <= MAX_CONDITION {
                    return Ok(Factorisation {
                        cholesky,
                        spec: set.spec,
                        kernel: kernel.cache_key(),
                        jitter,
                        condition_estimate,
                    });
                }
            }
            jitter = if jitter == 0.0 {
                FIRST_RELATIVE_JITTER * mean_diag
            } else {
                jitter * 10.0
            };
            if jitter > MAX_RELATIVE_JITTER * mean_diag * (1.0 + 1e-9) {
                return Err(BmcError::NotPositiveDefinite {
                    jitter: jitter / 10.0,
                });
            }
        }
    }

    /// `N`, the number of sample directions.
    pub fn len(&self) -> usize {
        self.cholesky.l_dirty().nrows()
    }

    /// Always false: a factorisation has at least one direction.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether this factor was built from `set` and `kernel`.
    pub fn matches(&self, set: &SampleSet, kernel: &Kernel) -> bool {
        self.spec == set.spec && self.kernel == kernel.cache_key() && self.len() == set.len()
    }

    /// `Q⁻¹ b` by two triangular solves.
    ///
    /// # Panics
    /// If `b.len() != self.len()` (a programming error; see [`Self::try_solve`]).
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        assert_eq!(b.len(), self.len(), "right-hand side length");
        self.cholesky
            .solve(&DVector::from_column_slice(b))
            .as_slice()
            .to_vec()
    }

    /// `Q⁻¹ b`, or a typed error when the length is wrong.
    pub fn try_solve(&self, b: &[f64]) -> Result<Vec<f64>, BmcError> {
        if b.len() != self.len() {
            return Err(BmcError::Mismatch {
                field: "values",
                expected: self.len().to_string(),
                actual: b.len().to_string(),
            });
        }
        Ok(self.solve(b))
    }

    /// `log |Q| = 2 Σ log L_ii` (for the marginal likelihood, bmc-math.md §7).
    pub fn log_determinant(&self) -> f64 {
        let l = self.cholesky.l_dirty();
        2.0 * (0..l.nrows()).map(|i| l[(i, i)].ln()).sum::<f64>()
    }

    /// Approximate heap + inline size, for byte-bounded caches.
    pub fn size_bytes(&self) -> usize {
        let n = self.len();
        std::mem::size_of::<Self>() + n * n * std::mem::size_of::<f64>()
    }
}

fn condition_estimate(cholesky: &Cholesky<f64, Dyn>) -> f64 {
    let l = cholesky.l_dirty();
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for i in 0..l.nrows() {
        let d = l[(i, i)];
        lo = lo.min(d);
        hi = hi.max(d);
    }
    (hi / lo).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::kernel::KernelKind;
    use crate::sphere::SampleSetKind;

    fn set(kind: SampleSetKind, count: usize) -> SampleSet {
        SampleSet::generate(SampleSetSpec {
            kind,
            count,
            seed: 1,
        })
        .unwrap()
    }

    #[test]
    fn solve_inverts_q_and_log_determinant_matches() {
        let s = set(SampleSetKind::Uniform, 12);
        let k = Kernel::new(KernelKind::Matern52, 0.6, 1.3, 0.05).unwrap();
        let f = Factorisation::new(&s, &k).unwrap();
        assert_eq!(f.jitter, 0.0);
        let b: Vec<f64> = (0..12).map(|i| (i as f64).sin()).collect();
        let x = f.solve(&b);
        let mut q = DMatrix::zeros(12, 12);
        for i in 0..12 {
            for j in 0..12 {
                q[(i, j)] = k.eval(s.directions[i], s.directions[j]);
            }
            q[(i, i)] += 0.05;
        }
        let r = &q * DVector::from_vec(x) - DVector::from_vec(b);
        assert!(r.amax() < 1e-12);
        let det = q.determinant();
        assert!((f.log_determinant() - det.ln()).abs() < 1e-10);
        assert!(f.condition_estimate >= 1.0);
        assert!(f.size_bytes() >= 12 * 12 * 8);
    }

    #[test]
    fn ill_conditioned_matrix_gets_jitter() {
        // Long lengthscale SE on many points: K is numerically singular.
        let s = set(SampleSetKind::Fibonacci, 256);
        let k = Kernel::new(KernelKind::SquaredExponential, 3.0, 1.0, 0.0).unwrap();
        let f = Factorisation::new(&s, &k).unwrap();
        assert!(f.jitter >= 1e-10 && f.jitter <= 1e-2, "{}", f.jitter);
        assert!(f.condition_estimate <= MAX_CONDITION);
    }

    #[test]
    fn duplicated_directions_need_jitter() {
        let mut s = set(SampleSetKind::Uniform, 4);
        s.directions[1] = s.directions[0];
        let k = Kernel::new(KernelKind::Matern32, 0.3, 1.0, 0.0).unwrap();
        let f = Factorisation::new(&s, &k).unwrap();
        assert!(f.jitter > 0.0);
    }

    #[test]
    fn bad_inputs_are_typed_errors() {
        let k = Kernel::new(KernelKind::Matern32, 0.3, 1.0, 0.0).unwrap();
        let mut s = set(SampleSetKind::Uniform, 4);
        s.directions[2].x = f64::NAN;
        assert_eq!(
            Factorisation::new(&s, &k).unwrap_err().field(),
            Some("directions")
        );
        s.directions.clear();
        assert_eq!(
            Factorisation::new(&s, &k).unwrap_err().field(),
            Some("samples")
        );
        let mut bad = k;
        bad.lengthscale = -1.0;
        let s = set(SampleSetKind::Uniform, 4);
        assert_eq!(
            Factorisation::new(&s, &bad).unwrap_err().field(),
            Some("lengthscale")
        );
        let f = Factorisation::new(&s, &k).unwrap();
        assert_eq!(f.try_solve(&[1.0]).unwrap_err().field(), Some("values"));
    }
}

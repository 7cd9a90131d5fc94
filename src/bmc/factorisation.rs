//! Cholesky factorisation of the BMC Gram matrix `Q = K + (σ_n² + jitter) I`
//! (docs/math.md §3), computed once per (sample set, kernel) and shared by
//! every density, prior mean and shading point.
//!
//! The linear algebra is faer's dense LLᵀ, chosen by measurement against
//! nalgebra (docs/BENCHMARKS.md, "Linear algebra": 4–18× faster for
//! N ≥ 256). It stays behind this type so callers never see the backend.
//!
//! Everything inside one factorisation is sequential: faer with `Par::Seq`
//! and a plain loop for the kernel matrix. The service already parallelises
//! across requests and points with rayon. Factorisations run inside
//! single-flight cache initialisers (`bmc::cache`, the record rules, the
//! lengthscale fit), which now run on a pool of their own (`crate::isolated`),
//! so a join in there could no longer deadlock on its own key; whether one
//! pays is for measurement. The explicit `Par` argument of faer's low-level
//! routines keeps this independent of faer's global setting.
//! Every call into faer is followed by `dense::clear_upper_vector_state`
//! (that module says why).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::{Conj, Mat, MatMut, Par};

use super::dense::clear_upper_vector_state;
use super::error::BmcError;
use super::kernel::{Kernel, KernelKey};
use crate::sphere::{MAX_SAMPLES, SampleSet, SampleSetSpec};

/// First jitter tried after a failure, relative to the mean diagonal of `K + σ_n² I`.
const FIRST_RELATIVE_JITTER: f64 = 1e-10;
/// Largest accepted condition estimate: beyond it the triangular solves lose
/// more than ~13 of 16 digits, so the jitter is escalated further.
const MAX_CONDITION: f64 = 1e13;
/// Factorisations tried at most: no jitter, then `FIRST_RELATIVE_JITTER`
/// growing ×10 up to `1e-2 × mean diag` (9 steps); beyond that the prior is
/// being changed rather than regularised, so we report an error. The loop stops on this
/// count, not on a floating-point comparison, so no value of the kernel can
/// make it spin (an infinite diagonal once made `inf > inf` the exit test).
const MAX_ATTEMPTS: usize = 10;

/// `Q = L Lᵀ` with the jitter that made it numerically positive definite.
#[derive(Clone, Debug)]
pub struct Factorisation {
    /// Lower-triangular factor `L` in the lower triangle; the strict upper
    /// triangle still holds `Q` and is never read.
    l: Mat<f64>,
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
        for (j, col) in data.chunks_mut(n).enumerate() {
            for (i, value) in col.iter_mut().enumerate() {
                *value = kernel.eval(dirs[i], dirs[j]);
            }
        }
        let mean_diag = kernel.variance + kernel.noise;
        let mut jitter = 0.0;
        for attempt in 0..MAX_ATTEMPTS {
            if attempt > 0 {
                jitter = if attempt == 1 {
                    FIRST_RELATIVE_JITTER * mean_diag
                } else {
                    jitter * 10.0
                };
            }
            let diagonal = kernel.noise + jitter;
            let mut l = Mat::from_fn(n, n, |i, j| {
                data[j * n + i] + if i == j { diagonal } else { 0.0 }
            });
            if cholesky_in_place(&mut l) {
                let condition_estimate = condition_estimate(&l);
                if condition_estimate <= MAX_CONDITION {
                    return Ok(Factorisation {
                        l,
                        spec: set.spec,
                        kernel: kernel.cache_key(),
                        jitter,
                        condition_estimate,
                    });
                }
            }
        }
        Err(BmcError::NotPositiveDefinite { jitter })
    }

    /// `N`, the number of sample directions.
    pub fn len(&self) -> usize {
        self.l.nrows()
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
        let mut x = b.to_vec();
        let n = x.len();
        // The LLᵀ solve needs no scratch space (faer's `solve_in_place_scratch` is empty).
        llt::solve::solve_in_place_with_conj(
            self.l.as_ref(),
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut x, n, 1),
            Par::Seq,
            MemStack::new(&mut []),
        );
        clear_upper_vector_state();
        x
    }

    /// `Q⁻¹ B` in place for `B` stored column-major as `columns` columns of
    /// length `N` (one pass over the factor for all columns).
    ///
    /// # Panics
    /// If `b.len() != columns · N` (a programming error).
    pub fn solve_columns_in_place(&self, b: &mut [f64], columns: usize) {
        let n = self.len();
        assert_eq!(b.len(), n * columns, "right-hand side length");
        llt::solve::solve_in_place_with_conj(
            self.l.as_ref(),
            Conj::No,
            MatMut::from_column_major_slice_mut(b, n, columns),
            Par::Seq,
            MemStack::new(&mut []),
        );
        clear_upper_vector_state();
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

    /// `log |Q| = 2 Σ log L_ii` (for the marginal likelihood, docs/math.md §7).
    pub fn log_determinant(&self) -> f64 {
        2.0 * (0..self.len()).map(|i| self.l[(i, i)].ln()).sum::<f64>()
    }

    /// Approximate heap + inline size, for byte-bounded caches.
    pub fn size_bytes(&self) -> usize {
        let n = self.len();
        std::mem::size_of::<Self>() + n * n * std::mem::size_of::<f64>()
    }
}

/// Overwrites the lower triangle of `q` with its Cholesky factor; false when
/// a pivot is not positive (Q not numerically positive definite).
fn cholesky_in_place(q: &mut Mat<f64>) -> bool {
    let n = q.nrows();
    let mut scratch = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
        n,
        Par::Seq,
        Default::default(),
    ));
    let factored = llt::factor::cholesky_in_place(
        q.as_mut(),
        Default::default(),
        Par::Seq,
        MemStack::new(&mut scratch),
        Default::default(),
    );
    clear_upper_vector_state();
    factored.is_ok()
}

fn condition_estimate(l: &Mat<f64>) -> f64 {
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
    use nalgebra::{DMatrix, DVector};

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

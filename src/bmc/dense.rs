//! Dense products through faer, and the rule for every call into faer's
//! kernels: leave the vector registers' upper halves clean afterwards.
//!
//! faer's kernels (through the `gemm` crate) choose AVX-512 or AVX2 code at
//! run time, while this crate is compiled for the x86-64 baseline, whose
//! floating point is SSE. Those kernels return with the upper halves of the
//! vector registers still marked in use, and SSE code run afterwards on the
//! same thread pays for that state until something clears it: a cached image
//! whose record rule called faer's product once per batch spent 1.3–2× as
//! long in ray traversal, light sampling and cache lookups, with the same
//! rays (docs/BENCHMARKS.md, "Records estimated in batches"). One
//! `vzeroupper` after each call removes it.

/// Clears the upper halves of the vector registers (`vzeroupper`) where the
/// CPU has AVX; call it after every faer routine.
pub(crate) fn clear_upper_vector_state() {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the instruction exists on this CPU (checked above), and it
        // only zeroes bits no live value of this caller holds: Rust code
        // compiled for the baseline keeps its floats in the lower 128 bits.
        unsafe { std::arch::x86_64::_mm256_zeroupper() }
    }
}

/// `a·b` over the shorter length, with four partial sums, which the
/// compiler can keep in vector registers (a single running sum forces
/// sequential additions).
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0; 4];
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// `M X` for a symmetric `n × n` matrix `M` (row-major, hence also
/// column-major) and `X` column-major with `n` rows: column-major, as many
/// columns as `X`. One pass over `M` serves every column.
///
/// # Panics
/// If `M` is not `n × n` or `X` not a whole number of columns.
pub fn symmetric_product(m: &[f64], n: usize, x: &[f64]) -> Vec<f64> {
    assert_eq!(m.len(), n * n, "symmetric matrix size");
    let columns = x.len().checked_div(n).unwrap_or(0);
    assert_eq!(columns * n, x.len(), "whole columns");
    let mut out = vec![0.0; x.len()];
    faer::linalg::matmul::matmul(
        faer::MatMut::from_column_major_slice_mut(&mut out, n, columns),
        faer::Accum::Replace,
        faer::MatRef::from_column_major_slice(m, n, n),
        faer::MatRef::from_column_major_slice(x, n, columns),
        1.0,
        faer::Par::Seq,
    );
    clear_upper_vector_state();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a plain double loop, for a symmetric matrix and three columns.
    #[test]
    fn symmetric_product_matches_the_definition() {
        let n = 37;
        let m: Vec<f64> = (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                ((i + j) as f64 * 0.37).sin() + (i * j) as f64 * 1e-3
            })
            .collect();
        let x: Vec<f64> = (0..3 * n).map(|k| (k as f64 * 0.11).cos()).collect();
        let out = symmetric_product(&m, n, &x);
        for c in 0..3 {
            for i in 0..n {
                let want: f64 = (0..n).map(|k| m[i * n + k] * x[c * n + k]).sum();
                assert!((out[c * n + i] - want).abs() < 1e-12, "{c} {i}");
            }
        }
        assert!(symmetric_product(&[], 0, &[]).is_empty());
    }
}

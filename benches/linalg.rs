//! Dense Cholesky factor + solve: nalgebra versus faer.
//!
//! The matrix is what BMC actually factors: a squared-exponential kernel
//! matrix (ℓ = 0.5) on uniform-area spherical Fibonacci points of the upper
//! hemisphere (docs/math.md §2, §5) plus a 1e-8 diagonal jitter. One solve with
//! one right-hand side follows the factorisation, as for the weights `Q⁻¹z`.
//! faer runs sequentially (`Par::Seq`) because the service parallelises across
//! requests, not inside one factorisation; nalgebra is always sequential.
//! By these figures production uses faer (docs/BENCHMARKS.md, "Linear algebra").

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use faer::linalg::solvers::Solve;
use std::hint::black_box;

const SIZES: [usize; 6] = [64, 128, 256, 512, 1024, 2048];

fn fibonacci_hemisphere(n: usize) -> Vec<[f64; 3]> {
    let golden = (1.0 + 5f64.sqrt()) / 2.0;
    (0..n)
        .map(|i| {
            let cos_theta = 1.0 - (i as f64 + 0.5) / n as f64;
            let sin_theta = (1.0 - cos_theta * cos_theta).sqrt();
            let phi = std::f64::consts::TAU * (i as f64 / golden).fract();
            [sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta]
        })
        .collect()
}

fn kernel_entry(points: &[[f64; 3]], i: usize, j: usize) -> f64 {
    let (a, b) = (points[i], points[j]);
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let jitter = if i == j { 1e-8 } else { 0.0 };
    ((dot - 1.0) / 0.25).exp() + jitter
}

fn cholesky(c: &mut Criterion) {
    faer::set_global_parallelism(faer::Par::Seq);
    let mut group = c.benchmark_group("cholesky_factor_solve");
    for n in SIZES {
        let points = fibonacci_hemisphere(n);
        let rhs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();

        let na_matrix = nalgebra::DMatrix::from_fn(n, n, |i, j| kernel_entry(&points, i, j));
        let na_rhs = nalgebra::DVector::from_column_slice(&rhs);
        group.bench_with_input(BenchmarkId::new("nalgebra", n), &n, |b, _| {
            b.iter(|| {
                let chol = black_box(na_matrix.clone())
                    .cholesky()
                    .expect("kernel matrix with jitter is positive definite");
                chol.solve(black_box(&na_rhs))
            })
        });

        let faer_matrix = faer::Mat::<f64>::from_fn(n, n, |i, j| kernel_entry(&points, i, j));
        let faer_rhs = faer::Col::<f64>::from_fn(n, |i| rhs[i]);
        group.bench_with_input(BenchmarkId::new("faer", n), &n, |b, _| {
            b.iter(|| {
                let llt = black_box(&faer_matrix)
                    .llt(faer::Side::Lower)
                    .expect("kernel matrix with jitter is positive definite");
                llt.solve(black_box(&faer_rhs))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, cholesky);
criterion_main!(benches);

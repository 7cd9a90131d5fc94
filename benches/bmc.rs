//! BMC quadrature costs: cold weight computation (sample set,
//! factorisation, exact kernel means, solves), a cached lookup, one
//! estimate (the dot product `wᵀY`), and irradiance-cache records (N = 1024)
//! estimated `k` at a time. SE kernel, Lambert density, GLS mean.

use std::hint::black_box;

use bmc_irradiance::bmc::cache::QuadratureCache;
use bmc_irradiance::bmc::estimator::{BayesianEstimator, BmcVariance, HemisphereEstimator};
use bmc_irradiance::bmc::{Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use bmc_irradiance::cache::RecordRule;
use bmc_irradiance::integrator::cached::default_rule_spec;
use bmc_irradiance::render::{RadianceSample, Rgb};
use bmc_irradiance::sphere::{SampleSetKind, SampleSetSpec};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use rand::SeedableRng;

fn spec(count: usize) -> SampleSetSpec {
    SampleSetSpec {
        kind: SampleSetKind::Fibonacci,
        count,
        seed: 0,
    }
}

fn kernel() -> Kernel {
    Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 1e-8).expect("valid kernel")
}

fn weights(c: &mut Criterion) {
    let mut group = c.benchmark_group("bmc_weights_cold");
    group.sample_size(10);
    for n in [64, 256, 1024, 2048] {
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, &n| {
            b.iter(|| {
                // A fresh cache per iteration: nothing is reused.
                let cache = QuadratureCache::new(1 << 30);
                cache
                    .quadrature(
                        black_box(spec(n)),
                        &kernel(),
                        &Density::Lambert,
                        PriorMean::Gls,
                        KernelMeanMethod::Exact,
                    )
                    .expect("weights")
            })
        });
    }
    group.finish();
}

fn cached_lookup(c: &mut Criterion) {
    let cache = QuadratureCache::new(1 << 30);
    let lookup = || {
        cache.quadrature(
            black_box(spec(64)),
            &kernel(),
            &Density::Lambert,
            PriorMean::Gls,
            KernelMeanMethod::Exact,
        )
    };
    lookup().expect("weights");
    c.bench_function("bmc_weights_cached_lookup_64", |b| {
        b.iter(|| lookup().expect("cached weights"))
    });
}

fn estimate(c: &mut Criterion) {
    let cache = QuadratureCache::new(1 << 30);
    let (quadrature, _) = cache
        .quadrature(
            spec(64),
            &kernel(),
            &Density::Lambert,
            PriorMean::Gls,
            KernelMeanMethod::Exact,
        )
        .expect("weights");
    let estimator = BayesianEstimator::new(quadrature, BmcVariance::Posterior);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    let directions = estimator.directions(&mut rng).into_owned();
    let values: Vec<f64> = directions.iter().map(|d| 1.0 + d.x * d.z).collect();
    c.bench_function("bmc_estimate_64", |b| {
        b.iter(|| {
            estimator
                .estimate(black_box(&directions), black_box(&values))
                .expect("estimate")
        })
    });
}

/// Records of the final preset's rule (1024 directions) estimated `k` at a
/// time; criterion reports the time of a batch, so divide by `k`.
fn record_batches(c: &mut Criterion) {
    let mut rule_spec = default_rule_spec();
    rule_spec.samples.count = 1024;
    let rule = RecordRule::new(rule_spec).expect("rule");
    let records: Vec<Vec<RadianceSample>> = (0..64)
        .map(|r| {
            (0..rule.directions().len())
                .map(|i| RadianceSample {
                    radiance: Rgb::from_array([
                        0.2 + ((i * 7 + r) % 13) as f64 * 0.1,
                        0.3,
                        0.1 + ((i + r) % 5) as f64 * 0.05,
                    ]),
                    distance: 1.0 + ((i * 3 + r) % 11) as f64 * 0.2,
                    variance: Rgb::from_array([0.01; 3]),
                    direct: Rgb::BLACK,
                })
                .collect()
        })
        .collect();
    let mut group = c.benchmark_group("record_estimates_1024");
    for k in [1usize, 4, 16, 32, 64] {
        let batch: Vec<&[RadianceSample]> = records[..k].iter().map(Vec::as_slice).collect();
        group.bench_with_input(BenchmarkId::from_parameter(k), &batch, |b, batch| {
            b.iter(|| rule.estimate_batch(black_box(batch)))
        });
    }
    group.finish();
}

criterion_group!(benches, weights, cached_lookup, estimate, record_batches);
criterion_main!(benches);

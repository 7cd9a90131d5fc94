//! Ray throughput on incoherent rays: closest hit and shadow (any-hit) rays
//! on the Cornell box (36 triangles) and the 101 760-triangle mesh scene,
//! single-threaded and with rayon on 2 threads.
//!
//! Rays: origins uniform in the scene bounds, directions uniform on the
//! sphere (closest hit); shadow rays connect two uniform points in the bounds
//! (`t_max` = their distance). Seeded, so every run traces the same rays.
//!
//! `cargo bench --bench raytrace`; throughput is reported in rays/s
//! ("elem/s").

use std::hint::black_box;
use std::path::Path;

use bmc_irradiance::scene::{Ray, Scene};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

const RAYS: usize = 1 << 16;

fn load(name: &str) -> Scene {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    Scene::load(&dir.join(name), &dir).expect("bundled scene loads")
}

fn uniform_point(rng: &mut rand_pcg::Pcg64, lo: DVec3, hi: DVec3) -> DVec3 {
    lo + (hi - lo) * DVec3::new(rng.random(), rng.random(), rng.random())
}

fn uniform_direction(rng: &mut rand_pcg::Pcg64) -> DVec3 {
    let z = 1.0 - 2.0 * rng.random::<f64>();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.random::<f64>();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// (closest-hit rays, shadow rays) for `scene`.
fn rays(scene: &Scene) -> (Vec<Ray>, Vec<Ray>) {
    let (lo, hi) = scene.bounds();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(2024);
    let closest = (0..RAYS)
        .map(|_| Ray {
            origin: uniform_point(&mut rng, lo, hi),
            dir: uniform_direction(&mut rng),
            t_max: f64::INFINITY,
        })
        .collect();
    let shadow = (0..RAYS)
        .map(|_| {
            let a = uniform_point(&mut rng, lo, hi);
            let b = uniform_point(&mut rng, lo, hi);
            let d = b - a;
            Ray {
                origin: a,
                dir: d.normalize(),
                t_max: d.length(),
            }
        })
        .collect();
    (closest, shadow)
}

fn bench(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    for name in ["cornell-box.json", "mesh.json"] {
        let scene = load(name);
        let (closest, shadow) = rays(&scene);
        let mut group = c.benchmark_group(format!("raytrace/{}", name.trim_end_matches(".json")));
        group.throughput(Throughput::Elements(RAYS as u64));
        group.sample_size(20);
        group.bench_function("closest/1-thread", |b| {
            b.iter(|| {
                closest
                    .iter()
                    .filter(|r| scene.intersect(black_box(r)).is_some())
                    .count()
            })
        });
        group.bench_function("shadow/1-thread", |b| {
            b.iter(|| {
                shadow
                    .iter()
                    .filter(|r| scene.occluded(black_box(r)))
                    .count()
            })
        });
        group.bench_function("closest/2-threads", |b| {
            b.iter(|| {
                pool.install(|| {
                    closest
                        .par_chunks(1024)
                        .map(|c| {
                            c.iter()
                                .filter(|r| scene.intersect(black_box(r)).is_some())
                                .count()
                        })
                        .sum::<usize>()
                })
            })
        });
        group.bench_function("shadow/2-threads", |b| {
            b.iter(|| {
                pool.install(|| {
                    shadow
                        .par_chunks(1024)
                        .map(|c| c.iter().filter(|r| scene.occluded(black_box(r))).count())
                        .sum::<usize>()
                })
            })
        });
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Rays per CPU-second of one thread, for machines too loaded for wall-clock
//! benchmarks to mean much: the same incoherent rays as `benches/raytrace.rs`,
//! timed with the thread's own CPU time from `/proc/thread-self/stat`
//! (Linux; 10 ms ticks, so each measurement runs for seconds).
//!
//! Usage: `cargo run --release --example ray_throughput [-- [--dump DIR] SCENE.json ...]`
//!
//! `--dump DIR` also writes each scene's triangles and both ray sets as
//! little-endian f32 rows (`<scene>.triangles.f32`: 9 per triangle;
//! `<scene>.closest.f32`, `<scene>.shadow.f32`: origin, direction, t_max),
//! so that another tracer can be timed on the same rays
//! (`docs/validation/embree_same_rays.py`).

use std::path::Path;
use std::time::Instant;

use bmc_irradiance::scene::{Ray, Scene};
use glam::DVec3;
use rand::{RngExt, SeedableRng};

/// User + system CPU seconds of the calling thread.
fn thread_cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap_or_default();
    // Fields after the parenthesised command name; utime and stime are the
    // 14th and 15th fields of the whole line.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

fn main() -> anyhow::Result<()> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut names: Vec<String> = std::env::args().skip(1).collect();
    let dump = match names.iter().position(|a| a == "--dump") {
        Some(i) if i + 1 < names.len() => Some(names.drain(i..i + 2).nth(1).unwrap_or_default()),
        Some(_) => anyhow::bail!("--dump needs a directory"),
        None => None,
    };
    if names.is_empty() {
        names = vec!["cornell-box.json".into(), "mesh.json".into()];
    }
    for name in names {
        let scene = Scene::load(&dir.join(&name), &dir)?;
        let (lo, hi) = scene.bounds();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(2024);
        let mut point = || lo + (hi - lo) * DVec3::new(rng.random(), rng.random(), rng.random());
        let n = 1 << 20;
        let mut closest = Vec::with_capacity(n);
        let mut shadow = Vec::with_capacity(n);
        for _ in 0..n {
            let (a, b, c) = (point(), point(), point());
            closest.push(Ray {
                origin: a,
                dir: (b - a).normalize(),
                t_max: f64::INFINITY,
            });
            shadow.push(Ray {
                origin: a,
                dir: (c - a).normalize(),
                t_max: (c - a).length(),
            });
        }
        if let Some(dir) = &dump {
            write_dump(Path::new(dir), &name, &scene, &closest, &shadow)?;
        }
        for (kind, rays) in [("closest", &closest), ("shadow", &shadow)] {
            let (cpu0, wall0) = (thread_cpu_seconds(), Instant::now());
            let mut hits = 0usize;
            let mut traced = 0usize;
            while thread_cpu_seconds() - cpu0 < 3.0 {
                for r in rays.iter() {
                    hits += if kind == "closest" {
                        scene.intersect(r).is_some() as usize
                    } else {
                        scene.occluded(r) as usize
                    };
                }
                traced += rays.len();
            }
            let cpu = thread_cpu_seconds() - cpu0;
            println!(
                "{name} {kind}: {:.2} M rays per CPU-second ({:.2} M/s wall), hit fraction {:.3}",
                traced as f64 / cpu / 1e6,
                traced as f64 / wall0.elapsed().as_secs_f64() / 1e6,
                hits as f64 / traced as f64
            );
        }
    }
    Ok(())
}

/// Writes the scene's triangles and the two ray sets as f32 rows.
fn write_dump(
    dir: &Path,
    name: &str,
    scene: &Scene,
    closest: &[Ray],
    shadow: &[Ray],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    let stem = name.trim_end_matches(".json");
    let f32_bytes = |values: &mut dyn Iterator<Item = f64>| -> Vec<u8> {
        values.flat_map(|v| (v as f32).to_le_bytes()).collect()
    };
    let triangles = f32_bytes(
        &mut scene
            .triangle_vertices()
            .flat_map(|t| t.into_iter().flat_map(|p| p.to_array())),
    );
    std::fs::write(dir.join(format!("{stem}.triangles.f32")), triangles)?;
    for (kind, rays) in [("closest", closest), ("shadow", shadow)] {
        let rows = f32_bytes(&mut rays.iter().flat_map(|r| {
            let (o, d) = (r.origin, r.dir);
            [o.x, o.y, o.z, d.x, d.y, d.z, r.t_max]
        }));
        std::fs::write(dir.join(format!("{stem}.{kind}.f32")), rows)?;
    }
    Ok(())
}

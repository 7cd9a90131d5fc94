//! The `obvhs` crate (a compressed 8-wide BVH, CWBVH, built by PLOC, with its
//! own f32 triangle test) timed on exactly the rays our tracer traces, as
//! `embree3_same_rays.c` times Embree 3: the "well-kept crate" option.
//!
//! `target/release/examples/ray_throughput --dump DIR` writes the triangles
//! and both ray sets (little-endian f32 rows); this program builds one CWBVH
//! per stem, traces each set one ray per call (`ray_traverse` for the closest
//! hit, `ray_traverse_miss` for shadow rays) for at least 3 CPU-seconds of the
//! calling thread, and prints rays per CPU-second and the hit fraction (which
//! must agree with ray_throughput's).
//!
//! Measurement only, never part of the build: in a throwaway Cargo project
//! whose `[dependencies]` are `obvhs = "0.4"` and `glam = "0.34"`, copy this
//! file to `src/main.rs`, then
//!   cargo build --release                                   # SSE2, as ours
//!   RUSTFLAGS="-C target-cpu=native" cargo build --release  # AVX2 / AVX-512
//!   target/release/NAME DIR cornell-box,mesh [fast|medium|slow]

use std::time::Duration;

use glam::vec3a;
use obvhs::BvhBuildParams;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;

/// User + system CPU seconds of the calling thread (Linux, 10 ms ticks).
fn thread_cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap_or_default();
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let fields: Vec<f64> = rest
        .split_whitespace()
        .map(|f| f.parse().unwrap_or(0.0))
        .collect();
    (fields[11] + fields[12]) / 100.0
}

fn read_f32(path: &str) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (dir, stems) = (&args[1], &args[2]);
    let build = args.get(3).map_or("medium", String::as_str);
    let params = match build {
        "fast" => BvhBuildParams::fast_build(),
        "slow" => BvhBuildParams::slow_build(),
        _ => BvhBuildParams::medium_build(),
    };
    for stem in stems.split(',') {
        let triangles: Vec<Triangle> = read_f32(&format!("{dir}/{stem}.triangles.f32"))
            .chunks_exact(9)
            .map(|c| Triangle {
                v0: vec3a(c[0], c[1], c[2]),
                v1: vec3a(c[3], c[4], c[5]),
                v2: vec3a(c[6], c[7], c[8]),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&triangles, params, &mut Duration::default());
        // Triangles in the tree's order, as obvhs's own examples store them.
        let ordered: Vec<RtTriangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| RtTriangle::from(&triangles[i as usize]))
            .collect();
        for kind in ["closest", "shadow"] {
            let rays: Vec<Ray> = read_f32(&format!("{dir}/{stem}.{kind}.f32"))
                .chunks_exact(7)
                .map(|c| Ray::new(vec3a(c[0], c[1], c[2]), vec3a(c[3], c[4], c[5]), 0.0, c[6]))
                .collect();
            let start = thread_cpu_seconds();
            let (mut traced, mut hits) = (0usize, 0usize);
            while thread_cpu_seconds() - start < 3.0 {
                for ray in &rays {
                    let test = |ray: &Ray, i: usize| ordered[i].intersect(ray);
                    hits += if kind == "closest" {
                        bvh.ray_traverse(*ray, &mut RayHit::none(), test) as usize
                    } else {
                        !bvh.ray_traverse_miss(*ray, test) as usize
                    };
                }
                traced += rays.len();
            }
            let seconds = thread_cpu_seconds() - start;
            println!(
                "{stem} {kind}: {:.2} M rays per CPU-second, hit fraction {:.3} (obvhs {build} build)",
                traced as f64 / seconds / 1e6,
                hits as f64 / traced as f64
            );
        }
    }
}

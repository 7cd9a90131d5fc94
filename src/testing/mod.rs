//! Test support shared by the unit tests next to the code and the
//! integration tests in `tests/it`: the bundled-scene fixtures, the one
//! statistical assertion, and crafted files and uploads ([`crafted`]). Not
//! part of the service's interface.
//!
//! # Tolerance policy
//! A Monte Carlo result is compared with another or with a reference by
//! [`agrees`]: `|a − b| ≤ k·se + rel·|b|`, where `se` is the standard error of
//! the difference (the two errors combined in quadrature when both are
//! random) and
//! - `k = 4` by default: a correct estimator fails a single check with
//!   probability 6·10⁻⁵, so a suite of a few hundred such checks stays green;
//!   `k = 5` where one test makes many comparisons at once;
//! - `rel` is zero for unbiased comparisons. It is non-zero only where a
//!   method has a known, bounded bias (interpolation from cache records, BMC
//!   glossy weights interpolated in `θ_r`), and then the test says which
//!   bias and how large it is allowed to be.
//!
//! Deterministic quantities (closed forms, identities) are compared with
//! plain absolute or relative bounds instead.

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use crate::cache::Record;
use crate::render::{Rgb, Transport};
use crate::scene::Scene;

mod crafted;
pub use crafted::*;

/// A small valid scene document: a diffuse unit rectangle under a constant
/// white sky, seen by an 8² camera.
pub const TINY_SCENE: &str = r#"{
    "materials": [{"id": "white", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
    "shapes": [{"type": "rectangle", "material": "white"}],
    "environment": {"type": "constant", "radiance": [1, 1, 1]},
    "camera": {"type": "perspective", "fov": 40, "origin": [0, 0, 3], "target": [0, 0, 0],
               "up": [0, 1, 0], "width": 8, "height": 8}
}"#;

/// Whether `a` and `b` agree within `sigmas` standard errors `se` of their
/// difference plus a relative allowance `rel·|b|` (module docs).
pub fn agrees(a: f64, b: f64, se: f64, sigmas: f64, rel: f64) -> bool {
    (a - b).abs() <= sigmas * se + rel * b.abs()
}

/// The bundled Cornell box, with its camera resized to `side`² pixels.
pub fn cornell(side: u32) -> Transport {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(dir.join("cornell-box.json")).expect("bundled scene");
    let mut doc: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    doc["camera"]["width"] = side.into();
    doc["camera"]["height"] = side.into();
    let scene = Scene::from_json_str(&doc.to_string(), &dir, &dir).expect("loads");
    Transport::new(Arc::new(scene))
}

/// A ground plane (z = 0, facing +z) under a square occluder of half-side
/// ¼ at height 1, lit by a point light of intensity 4 at height 2 above the
/// origin, whose shadow on the ground is the square of half-side ½, and by
/// a constant sky of radiance `sky` (none if 0).
pub fn occluded_ground(sky: f64) -> Transport {
    let mut doc = serde_json::json!({
        "materials": [{"id": "grey", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
        "shapes": [
            {"type": "rectangle", "material": "grey", "to_world": [{"scale": [10, 10, 1]}]},
            {"type": "rectangle", "material": "grey",
             "to_world": [{"scale": [0.25, 0.25, 1]}, {"translate": [0, 0, 1]}]}
        ],
        "lights": [{"type": "point", "position": [0, 0, 2], "intensity": [4, 4, 4]}],
        "camera": {"type": "perspective", "fov": 30, "origin": [0, 0, 6],
                   "target": [0, 0, 0], "up": [0, 1, 0], "width": 4, "height": 4}
    });
    if sky > 0.0 {
        doc["environment"] = serde_json::json!({"type": "constant", "radiance": [sky, sky, sky]});
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::from_json_str(&doc.to_string(), dir, dir).expect("loads");
    Transport::new(Arc::new(scene))
}

/// A record holding `irradiance` at `position` within `radius`, with no
/// variance and no gradients (the place and value a test needs).
pub fn flat_record(position: DVec3, normal: DVec3, irradiance: Rgb, radius: f64) -> Record {
    Record {
        position,
        normal,
        irradiance,
        variance: Rgb::BLACK,
        radius,
        rotation_gradient: [DVec3::ZERO; 3],
        translation_gradient: [DVec3::ZERO; 3],
    }
}

/// A standard normal variate by Box–Muller (`1 − U` keeps the logarithm finite).
pub fn standard_normal<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
    use rand::RngExt;
    let (u, v): (f64, f64) = (rng.random(), rng.random());
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Runs `f` on a rayon pool of `threads` threads (results must not depend on it).
pub fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agreement_is_within_sigmas_plus_the_relative_allowance() {
        assert!(agrees(10.0, 10.3, 0.1, 4.0, 0.0));
        assert!(!agrees(10.0, 10.5, 0.1, 4.0, 0.0));
        assert!(agrees(10.0, 10.5, 0.1, 4.0, 0.02));
    }
}

//! Every light's samples against what it emits: delta lights give the
//! exact irradiance of their formulas in one sample; area lights and the
//! environment agree with a numerical integral of their radiance.

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::*;
use crate::render::{QueryPoint, Transport};

/// A unit floor (z = 0, facing +z) under `lights` (JSON), with `extra`
/// shapes and no environment.
fn scene(lights: &str, extra: &str) -> Transport {
    let text = format!(
        r#"{{"materials": [{{"id": "m", "type": "diffuse", "reflectance": 0.5}}],
            "shapes": [{{"type": "rectangle", "material": "m", "to_world": {{"scale": [20, 20, 1]}}}}{extra}],
            "lights": [{lights}],
            "camera": {{"type": "perspective", "fov": 40, "width": 4, "height": 4,
                        "to_world": {{"look_at": {{"origin": [0, -5, 3], "target": [0, 0, 0], "up": [0, 0, 1]}}}}}}}}"#
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::from_json_str(&text, dir, dir).unwrap_or_else(|e| panic!("{e}"));
    Transport::new(Arc::new(scene))
}

/// Direct irradiance at `x` on the floor (normal +z) by `n` light samples.
fn direct(transport: &Transport, x: DVec3, n: u32) -> Rgb {
    let point = QueryPoint::new(x, DVec3::Z).unwrap();
    let mut rng = Pcg64::seed_from_u64(1);
    let mut stats = TraceStats::default();
    transport
        .direct_irradiance(&point, n, &mut rng, &mut stats)
        .0
        .mean
}

fn close(a: Rgb, b: [f64; 3], rel: f64) -> bool {
    a.to_array()
        .iter()
        .zip(b)
        .all(|(a, b)| (a - b).abs() <= rel * b.abs().max(1e-12))
}

#[test]
fn a_point_light_gives_i_cos_over_d_squared() {
    let t = scene(
        r#"{"type": "point", "position": [1, 0, 2], "intensity": [4, 2, 1]}"#,
        "",
    );
    for x in [DVec3::ZERO, DVec3::new(-1.0, 2.0, 0.0)] {
        let d = DVec3::new(1.0, 0.0, 2.0) - x;
        let e = d.z / d.length() / d.length_squared();
        assert!(close(direct(&t, x, 3), [4.0 * e, 2.0 * e, e], 1e-12), "{x}");
    }
}

#[test]
fn a_spot_light_falls_off_linearly_between_beam_and_cutoff() {
    // Straight down from height 1; cutoff 40°, beam 20°.
    let t = scene(
        r#"{"type": "spot", "position": [0, 0, 1], "direction": [0, 0, -1], "intensity": 2,
            "cutoff_angle": 40, "beam_width": 20}"#,
        "",
    );
    for (degrees, falloff) in [
        (0.0, 1.0),
        (15.0, 1.0),
        (30.0, 0.5),
        (35.0, 0.25),
        (45.0, 0.0),
    ] {
        let theta = f64::to_radians(degrees);
        let x = DVec3::new(theta.tan(), 0.0, 0.0);
        let d2 = 1.0 + x.x * x.x;
        let e = 2.0 * falloff * theta.cos() / d2;
        assert!(
            close(direct(&t, x, 2), [e; 3], 1e-9),
            "{degrees}°: {:?} vs {e}",
            direct(&t, x, 2)
        );
    }
    assert_eq!(spot_falloff(0.3, 0.3, 0.2), 0.0);
}

#[test]
fn a_directional_light_gives_e_cos_and_casts_shadows() {
    let down = DVec3::new(0.0, 1.0, -1.0).normalize();
    let t = scene(
        r#"{"type": "directional", "direction": [0, 1, -1], "irradiance": 3}"#,
        r#", {"type": "sphere", "material": "m", "center": [0, -2, 2], "radius": 0.5}"#,
    );
    let e = 3.0 * -down.z;
    assert!(close(
        direct(&t, DVec3::new(5.0, 0.0, 0.0), 2),
        [e; 3],
        1e-12
    ));
    // The sphere stands between the light and the origin.
    assert!(direct(&t, DVec3::ZERO, 2).is_black());
}

#[test]
fn lights_are_chosen_by_power_and_each_stays_unbiased() {
    // Two point lights of intensity 1 and 3: chosen with probabilities ¼
    // and ¾, each sample carries its light over its probability, so the mean
    // over many samples is the sum of both.
    let t = scene(
        r#"{"type": "point", "position": [0, 0, 1], "intensity": 1},
           {"type": "point", "position": [0, 0, 2], "intensity": 3}"#,
        "",
    );
    let exact = 1.0 + 3.0 / 4.0;
    let got = direct(&t, DVec3::ZERO, 40_000).g;
    assert!((got - exact).abs() < 0.02 * exact, "{got} vs {exact}");
    let sampler = t.lights();
    let s = sampler
        .sample(t.scene(), DVec3::ZERO, 0.1, [0.5, 0.5])
        .unwrap();
    assert!(s.delta && (s.pdf - 0.25).abs() < 1e-12, "{s:?}");
}

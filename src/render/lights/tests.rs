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
fn lights_are_chosen_by_the_irradiance_they_bring_and_each_stays_unbiased() {
    // Point lights of intensity 1 at height 1 and 3 at height 2: at the
    // origin they bring 1 and ¾ (before the cosine), so they are chosen
    // with probabilities 4/7 and 3/7; each sample carries its light over its
    // probability, so the mean over many samples is the sum of both.
    let t = scene(
        r#"{"type": "point", "position": [0, 0, 1], "intensity": 1},
           {"type": "point", "position": [0, 0, 2], "intensity": 3}"#,
        "",
    );
    let exact = 1.0 + 3.0 / 4.0;
    let got = direct(&t, DVec3::ZERO, 40_000).g;
    assert!((got - exact).abs() < 0.02 * exact, "{got} vs {exact}");
    let sampler = t.lights();
    let first = sampler
        .sample(t.scene(), DVec3::ZERO, 0.5, [0.5, 0.5])
        .unwrap();
    assert!(
        first.delta && (first.pdf - 4.0 / 7.0).abs() < 1e-12,
        "{first:?}"
    );
    let second = sampler
        .sample(t.scene(), DVec3::ZERO, 0.6, [0.5, 0.5])
        .unwrap();
    assert!((second.pdf - 3.0 / 7.0).abs() < 1e-12, "{second:?}");
}

#[test]
fn a_spot_light_is_never_chosen_outside_its_cone() {
    // A bright spot straight down over the origin (cutoff 20°) and a dim
    // point light: outside the cone every sample goes to the point light;
    // inside, the spot takes its share of what both bring.
    let t = scene(
        r#"{"type": "spot", "position": [0, 0, 1], "direction": [0, 0, -1], "intensity": 100,
            "cutoff_angle": 20, "beam_width": 10},
           {"type": "point", "position": [3, 0, 1], "intensity": 1}"#,
        "",
    );
    let sampler = t.lights();
    let outside = DVec3::new(3.0, 0.0, 0.0);
    for u in [0.0, 0.3, 0.999] {
        let s = sampler.sample(t.scene(), outside, u, [0.5, 0.5]).unwrap();
        assert!((s.pdf - 1.0).abs() < 1e-12, "{u}: {s:?}");
        assert!((s.wi - DVec3::Z).length() < 1e-12, "{u}: {s:?}");
    }
    let spot = sampler
        .sample(t.scene(), DVec3::ZERO, 0.0, [0.5, 0.5])
        .unwrap();
    let share = 100.0 / (100.0 + 1.0 / 10.0);
    assert!((spot.pdf - share).abs() < 1e-12, "{spot:?}");
    let exact = 100.0 + 1.0 / 10.0 * (1.0 / 10f64.sqrt());
    let got = direct(&t, DVec3::ZERO, 20_000).g;
    assert!((got - exact).abs() < 1e-3 * exact, "{got} vs {exact}");
}

#[test]
fn light_samples_report_the_densities_that_the_pdfs_of_what_a_ray_finds_give() {
    // An emitting square above the floor and a constant sky: at two points
    // (under the square and far from it), a sample of either kind has the
    // density that MIS later computes for the same direction from what a
    // ray there finds.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = r#"{"materials": [{"id": "m", "type": "diffuse", "reflectance": 0.5}],
        "shapes": [{"type": "rectangle", "material": "m", "to_world": {"scale": [20, 20, 1]}},
                   {"type": "rectangle", "material": "m", "flip_normals": true,
                    "to_world": [{"scale": [0.5, 0.5, 1]}, {"translate": [0, 0, 2]}],
                    "emitter": {"type": "area", "radiance": 10}}],
        "environment": {"type": "constant", "radiance": [0.2, 0.2, 0.2]},
        "camera": {"type": "perspective", "fov": 40, "width": 4, "height": 4,
                   "to_world": {"look_at": {"origin": [0, -5, 3], "target": [0, 0, 0], "up": [0, 0, 1]}}}}"#;
    let scene = Scene::from_json_str(text, dir, dir).unwrap_or_else(|e| panic!("{e}"));
    let t = Transport::new(Arc::new(scene));
    let sampler = t.lights();
    let mut rng = Pcg64::seed_from_u64(3);
    use rand::RngExt;
    for x in [DVec3::new(0.1, 0.2, 0.0), DVec3::new(6.0, -4.0, 0.0)] {
        let (mut area, mut sky) = (0, 0);
        for _ in 0..400 {
            let Some(s) = sampler.sample(t.scene(), x, rng.random(), [rng.random(), rng.random()])
            else {
                continue;
            };
            let ray = t.scene().spawn_ray(x, DVec3::Z, s.wi);
            let pdf = match t.scene().intersect(&ray) {
                Some(hit) if s.target.is_some() => {
                    area += 1;
                    sampler.pdf_area_hit(t.scene(), x, &hit)
                }
                Some(_) => continue,
                None => {
                    sky += 1;
                    sampler.pdf_environment(t.scene(), x, s.wi)
                }
            };
            assert!((pdf - s.pdf).abs() <= 1e-6 * s.pdf, "{x}: {pdf} vs {s:?}");
        }
        assert!(area > 0 && sky > 0, "{x}: {area} area, {sky} sky samples");
    }
}

//! The bundled Cornell box as Mitsuba 3 XML and as JSON give exactly the
//! same irradiance (same seed), through the public API.

use std::path::Path;
use std::sync::Arc;

use bmc_irradiance::render::Cancel;
use bmc_irradiance::render::{IrradianceOptions, PathDepth, QueryPoint, Transport};
use bmc_irradiance::scene::{MitsubaOptions, Scene};
use glam::DVec3;

fn transport(name: &str) -> Transport {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene = Scene::load(&dir.join(name), &dir).unwrap_or_else(|e| panic!("{name}: {e}"));
    Transport::new(Arc::new(scene))
}

#[test]
fn cornell_box_irradiance_is_identical_from_xml_and_json() {
    let points: Vec<QueryPoint> = [
        ((0.0, -1.0, 0.0), (0.0, 1.0, 0.0)),
        ((0.5, 0.2, -0.99), (0.0, 0.0, 1.0)),
        ((-0.99, 0.3, 0.1), (1.0, 0.0, 0.0)),
        ((0.99, -0.5, 0.4), (-1.0, 0.0, 0.0)),
        ((0.2, 0.95, 0.3), (0.0, -1.0, 0.0)),
    ]
    .into_iter()
    .map(|((x, y, z), (a, b, c))| {
        QueryPoint::new(DVec3::new(x, y, z), DVec3::new(a, b, c)).unwrap()
    })
    .collect();
    let options = IrradianceOptions {
        samples: 64,
        max_depth: PathDepth::constant(4),
        seed: 7,
        ..IrradianceOptions::default()
    };
    let json = transport("cornell-box.json")
        .irradiance_at_points(&points, &options, &|| {}, &Cancel::never())
        .unwrap();
    let xml = transport("cornell-box.xml")
        .irradiance_at_points(&points, &options, &|| {}, &Cancel::never())
        .unwrap();
    for (j, x) in json.iter().zip(&xml) {
        assert!(j.irradiance.r > 0.0, "{j:?}");
        // Debug prints f64 exactly: equal strings mean bit-identical values.
        assert_eq!(format!("{x:?}"), format!("{j:?}"));
    }
}

/// `tests/data/mitsuba/all.xml` uses every supported element; Mitsuba 3.9.1
/// loads it and reports (docs/validation/mitsuba_xml_check.py) the scene
/// bounds [-2, -2, -5]–[3.5, 2.5, 3.5] and a horizontal field of view of
/// 47.21631622314453° (float32) for the 35 mm lens on a square film.
#[test]
fn every_supported_element_reads_as_mitsuba_does() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba");
    let (scene, warnings) =
        Scene::load_mitsuba_xml(&dir.join("all.xml"), &dir, &MitsubaOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
    // Every element is now exact.
    assert!(warnings.is_empty(), "{warnings:?}");
    let (lo, hi) = scene.bounds();
    assert!(
        (lo - DVec3::new(-2.0, -2.0, -5.0)).abs().max_element() < 1e-6,
        "{lo}"
    );
    assert!(
        (hi - DVec3::new(3.5, 2.5, 3.5)).abs().max_element() < 1e-6,
        "{hi}"
    );
    // Mitsuba's 8 shapes; the area light and the point light.
    assert_eq!(scene.shape_count(), 8);
    assert_eq!(scene.emitters.len(), 2);
    assert!(scene.environment.is_some());
    let (w, _) = scene.camera.resolution();
    let edge = scene.camera.generate_ray(0.0, w as f64 * 0.5).dir;
    let forward = scene
        .camera
        .generate_ray(w as f64 * 0.5, w as f64 * 0.5)
        .dir;
    let half_fov = edge.angle_between(forward).to_degrees();
    assert!(
        (2.0 * half_fov - 47.21631622314453).abs() < 1e-4,
        "{half_fov}"
    );
}

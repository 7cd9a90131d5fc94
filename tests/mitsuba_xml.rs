//! The bundled Cornell box as Mitsuba 3 XML and as JSON give exactly the
//! same irradiance (same seed), through the public API.

use std::path::Path;
use std::sync::Arc;

use bmc_irradiance::render::{IrradianceOptions, QueryPoint, Transport};
use bmc_irradiance::scene::Scene;
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
        max_depth: 4,
        seed: 7,
        ..IrradianceOptions::default()
    };
    let json = transport("cornell-box.json")
        .irradiance_at_points(&points, &options, &|| {})
        .unwrap();
    let xml = transport("cornell-box.xml")
        .irradiance_at_points(&points, &options, &|| {})
        .unwrap();
    for (j, x) in json.iter().zip(&xml) {
        assert!(j.irradiance.r > 0.0, "{j:?}");
        // Debug prints f64 exactly: equal strings mean bit-identical values.
        assert_eq!(format!("{x:?}"), format!("{j:?}"));
    }
}

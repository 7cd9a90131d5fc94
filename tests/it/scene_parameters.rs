//! Every numeric parameter of every material and light plugin, at the
//! extremes a client may send: a scene the service accepts renders a tile
//! (path tracing and the irradiance cache) and answers a point query with
//! finite numbers; a scene it refuses is a 422 naming the parameter. Before
//! this held, `dielectric` with `int_ior` 1e300 was accepted and then made
//! every request on the scene a 500 (a NaN ray overran the BVH stack), and
//! `conductor` with `eta = k = 0` rendered `null` pixels.

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::common::{TestApp, spawn_app};

/// Values a careless or hostile client sends: zeros, denormals, the
/// smallest and largest finite doubles, negatives, and ordinary ones.
const EXTREMES: [f64; 12] = [
    0.0,
    5e-324,
    1e-300,
    1e-12,
    0.01,
    0.5,
    3.0,
    100.0,
    1e12,
    1e300,
    f64::MAX,
    -1.0,
];

/// `(plugin, parameter)` of every numeric material parameter, with the
/// other parameters the plugin needs.
fn material_parameters() -> Vec<(Value, &'static str)> {
    let mut out = Vec::new();
    let mut add = |base: Value, names: &[&'static str]| {
        for name in names {
            out.push((base.clone(), *name));
        }
    };
    add(
        json!({"type": "diffuse", "reflectance": 0.5}),
        &["reflectance"],
    );
    add(
        json!({"type": "glossy", "diffuse": 0.3, "specular": 0.3, "exponent": 20}),
        &["diffuse", "specular", "exponent"],
    );
    for kind in ["conductor", "roughconductor"] {
        add(
            json!({"type": kind, "eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.2]}),
            &["eta", "k", "specular_reflectance"],
        );
    }
    add(json!({"type": "roughconductor"}), &["alpha"]);
    // Both parts of a metal's index at once (0 and 0 divided by zero).
    add(json!({"type": "conductor"}), &["eta+k"]);
    add(
        json!({"type": "roughconductor", "alpha_u": 0.1, "alpha_v": 0.3}),
        &["alpha_u", "alpha_v"],
    );
    for kind in ["dielectric", "thindielectric", "roughdielectric"] {
        add(
            json!({"type": kind}),
            &[
                "int_ior",
                "ext_ior",
                "specular_reflectance",
                "specular_transmittance",
            ],
        );
    }
    add(json!({"type": "roughdielectric"}), &["alpha"]);
    // The two indices pulling apart: the relative index at its extremes.
    for kind in ["dielectric", "roughplastic"] {
        add(
            json!({"type": kind}),
            &["int_ior/ext_ior", "ext_ior/int_ior"],
        );
    }
    for kind in ["plastic", "roughplastic"] {
        add(
            json!({"type": kind}),
            &[
                "int_ior",
                "ext_ior",
                "diffuse_reflectance",
                "specular_reflectance",
            ],
        );
    }
    add(json!({"type": "roughplastic"}), &["alpha"]);
    add(
        json!({"type": "blendbsdf", "bsdf": [{"type": "diffuse", "reflectance": 0.8},
                                              {"type": "conductor"}]}),
        &["weight"],
    );
    add(
        json!({"type": "mask", "bsdf": {"type": "diffuse", "reflectance": 0.8}}),
        &["opacity"],
    );
    out
}

/// `(where, light, parameter)` of every numeric light parameter: `where`
/// is `lights`, `emitter` (an area light on the floor) or `environment`.
fn light_parameters() -> Vec<(&'static str, Value, &'static str)> {
    vec![
        (
            "lights",
            json!({"type": "point", "position": [0, 0, 2]}),
            "intensity",
        ),
        ("lights", json!({"type": "point"}), "position"),
        (
            "lights",
            json!({"type": "spot", "position": [0, 0, 3], "direction": [0, 0, -1]}),
            "intensity",
        ),
        (
            "lights",
            json!({"type": "spot", "position": [0, 0, 3], "direction": [0, 0, -1]}),
            "cutoff_angle",
        ),
        (
            "lights",
            json!({"type": "spot", "position": [0, 0, 3], "direction": [0, 0, -1]}),
            "beam_width",
        ),
        ("lights", json!({"type": "spot"}), "position"),
        (
            "lights",
            json!({"type": "spot", "position": [0, 0, 3]}),
            "direction",
        ),
        ("lights", json!({"type": "directional"}), "irradiance"),
        ("lights", json!({"type": "directional"}), "direction"),
        ("emitter", json!({"type": "area"}), "radiance"),
        ("environment", json!({"type": "constant"}), "radiance"),
    ]
}

/// A floor, a sphere of `material` over it and a camera looking down at
/// both, lit by `lights`, an area light and a sky unless `light` replaces
/// one of them.
fn scene(material: Value, light: Option<(&str, Value)>) -> Value {
    let mut material = material;
    material["id"] = json!("m");
    let mut doc = json!({
        "name": "fuzz",
        "materials": [material, {"id": "floor", "type": "diffuse", "reflectance": 0.5}],
        "shapes": [
            {"type": "rectangle", "material": "floor",
             "to_world": [{"scale": [3, 3, 1]}],
             "emitter": {"type": "area", "radiance": 0.2}},
            {"type": "sphere", "center": [0, 0, 0.6], "radius": 0.5, "material": "m"}
        ],
        "lights": [{"type": "point", "position": [1, 1, 2], "intensity": 4}],
        "environment": {"type": "constant", "radiance": [0.4, 0.5, 0.6]},
        "camera": {"fov": 50, "width": 6, "height": 6,
                   "origin": [0, -3, 3], "target": [0, 0, 0.4], "up": [0, 0, 1]},
        "max_depth": 4
    });
    match light {
        Some(("lights", light)) => doc["lights"] = json!([light]),
        Some(("emitter", light)) => doc["shapes"][0]["emitter"] = light,
        Some(("environment", light)) => doc["environment"] = light,
        _ => {}
    }
    doc
}

/// What went wrong with one scene, if anything.
async fn check(app: &TestApp, doc: &Value, place: &str) -> Option<String> {
    let posted = app.post_json("/v1/scenes?replace=true", doc).await;
    let status = posted.status();
    let body: Value = posted.json().await.unwrap();
    if status == StatusCode::UNPROCESSABLE_ENTITY {
        // The parameter or, where two conflict, the other one of the same
        // plugin.
        let field = body["error"]["field"].as_str().unwrap_or_default();
        return (!field.starts_with(place))
            .then(|| format!("refused naming {field:?}, not a parameter of {place}: {body}"));
    }
    if !status.is_success() {
        return Some(format!("POST answered {status}: {body}"));
    }
    for estimator in [
        json!({"method": "path"}),
        json!({"method": "cache", "samples": 16}),
    ] {
        let tile = json!({"x": 0, "y": 0, "width": 6, "height": 6, "format": "json",
                          "samples_per_pixel": 2, "seed": 1, "estimator": estimator});
        let response = app.post_json("/v1/scenes/fuzz/tiles", &tile).await;
        let status = response.status();
        let body: Value = response.json().await.unwrap();
        if status != StatusCode::OK {
            return Some(format!("tile {estimator} answered {status}: {body}"));
        }
        let finite = |v: &Value| v.as_f64().is_some_and(f64::is_finite);
        let pixels = body["rgb"].as_array().unwrap();
        if !pixels
            .iter()
            .flat_map(|p| p.as_array().unwrap())
            .all(finite)
        {
            return Some(format!("tile {estimator} has pixels that are not finite"));
        }
    }
    let query = json!({
        "points": [{"position": [0.8, 0.0, 0.0], "normal": [0, 0, 1]},
                   {"position": [0.0, 0.0, 1.1], "normal": [0, 0, 1]}],
        "estimator": {"method": "bmc", "samples": 8},
        "seed": 3
    });
    let response = app.post_json("/v1/scenes/fuzz/irradiance", &query).await;
    let status = response.status();
    let body: Value = response.json().await.unwrap();
    if status != StatusCode::OK {
        return Some(format!("point query answered {status}: {body}"));
    }
    let numbers = ["irradiance", "std_dev"].map(|k| body[k].to_string());
    if numbers.iter().any(|n| n.contains("null")) {
        return Some(format!(
            "point query gave numbers that are not finite: {body}"
        ));
    }
    None
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn accepted_parameters_render_finite_numbers_and_refused_ones_are_named() {
    let app = spawn_app().await;
    let mut failures = Vec::new();
    let mut passed = 0;
    for (base, parameter) in material_parameters() {
        for value in EXTREMES {
            let mut material = base.clone();
            let pair = match parameter {
                "eta+k" => Some(("eta", "k", value)),
                "int_ior/ext_ior" => Some(("int_ior", "ext_ior", 1.0 / value)),
                "ext_ior/int_ior" => Some(("ext_ior", "int_ior", 1.0 / value)),
                _ => None,
            };
            match pair {
                Some((a, b, other)) => {
                    material[a] = json!(value);
                    material[b] = json!(other);
                }
                None => material[parameter] = json!(value),
            }
            let doc = scene(material.clone(), None);
            match check(&app, &doc, "materials[0].").await {
                Some(why) => failures.push(format!("{material}: {why}")),
                None => passed += 1,
            }
        }
    }
    for (place, base, parameter) in light_parameters() {
        for value in EXTREMES {
            let mut light = base.clone();
            light[parameter] = match parameter {
                "position" | "direction" => json!([value, 0.5, value]),
                _ => json!(value),
            };
            let doc = scene(
                json!({"type": "diffuse", "reflectance": 0.5}),
                Some((place, light.clone())),
            );
            let field = match place {
                "lights" => "lights[0].",
                "emitter" => "shapes[0].emitter.",
                _ => "environment.",
            };
            if let Some(why) = check(&app, &doc, field).await {
                failures.push(format!("{place} {light}: {why}"));
            } else {
                passed += 1;
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        failures.len() + passed,
        failures.join("\n")
    );
    // The service is healthy after all of it.
    let health: Value = app.get("/health").await.json().await.unwrap();
    assert_eq!(health["status"], "ok", "{health}");
}

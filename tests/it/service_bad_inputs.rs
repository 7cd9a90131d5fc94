//! One table of bad requests across every route: each gets its status, the
//! JSON error body with its code and the field at fault, and afterwards the
//! service still answers and still holds every scene it had.

use crate::common::{TINY_SCENE, error_of, spawn_app_with_scenes};
use reqwest::{Method, StatusCode};
use serde_json::{Value, json};

/// A request body: JSON, or raw bytes with a content type.
enum Body {
    None,
    Json(Value),
    Raw(&'static str, &'static str),
}

struct Case {
    name: &'static str,
    method: Method,
    path: &'static str,
    body: Body,
    status: StatusCode,
    code: &'static str,
    field: Option<&'static str>,
}

fn points(point: Value) -> Value {
    json!({"points": [point], "estimator": {"method": "mc", "samples": 4}, "max_depth": 2})
}

fn good_point() -> Value {
    json!({"position": [0.0, 0.0, 1.0], "normal": [0.0, 0.0, 1.0]})
}

fn tile(edit: impl FnOnce(&mut Value)) -> Value {
    let mut body = json!({"x": 0, "y": 0, "width": 4, "height": 4, "format": "json"});
    edit(&mut body);
    body
}

fn scene(edit: impl FnOnce(&mut Value)) -> Value {
    let mut doc: Value = serde_json::from_str(TINY_SCENE).unwrap();
    doc["name"] = json!("new");
    edit(&mut doc);
    doc
}

fn cases() -> Vec<Case> {
    use StatusCode as S;
    let unprocessable = |name, method, path, body, field| Case {
        name,
        method,
        path,
        body: Body::Json(body),
        status: S::UNPROCESSABLE_ENTITY,
        code: "invalid_field",
        field: Some(field),
    };
    let irradiance = "/v1/scenes/tiny/irradiance";
    let tiles = "/v1/scenes/tiny/tiles";
    let cases = vec![
        // Scenes.
        Case {
            name: "scene: malformed JSON",
            method: Method::POST,
            path: "/v1/scenes",
            body: Body::Raw("application/json", "{\"name\": \"x\", "),
            status: S::BAD_REQUEST,
            code: "malformed_json",
            field: None,
        },
        Case {
            name: "scene: plain text",
            method: Method::POST,
            path: "/v1/scenes",
            body: Body::Raw("text/plain", "hello"),
            status: S::UNSUPPORTED_MEDIA_TYPE,
            code: "unsupported_media_type",
            field: None,
        },
        unprocessable(
            "scene: unknown material",
            Method::POST,
            "/v1/scenes",
            scene(|d| d["shapes"][0]["material"] = json!("nope")),
            "shapes[0].material",
        ),
        unprocessable(
            "scene: file outside the scenes directory",
            Method::POST,
            "/v1/scenes",
            scene(|d| {
                d["shapes"] =
                    json!([{"type": "obj", "filename": "../../etc/passwd", "material": "white"}])
            }),
            "shapes[0].filename",
        ),
        unprocessable(
            "scene: broken EXR environment",
            Method::POST,
            "/v1/scenes",
            scene(|d| d["environment"] = json!({"type": "envmap", "filename": "broken.exr"})),
            "environment.filename",
        ),
        unprocessable(
            "scene: zero-size camera",
            Method::POST,
            "/v1/scenes",
            scene(|d| d["camera"]["width"] = json!(0)),
            "camera.width",
        ),
        unprocessable(
            "scene: absurd radiance",
            Method::POST,
            "/v1/scenes",
            scene(|d| d["environment"]["radiance"] = json!([1, 1, 1e308])),
            "environment.radiance[2]",
        ),
        Case {
            name: "scene: XML without id",
            method: Method::POST,
            path: "/v1/scenes",
            body: Body::Raw("application/xml", "<scene version=\"3.0.0\"/>"),
            status: S::UNPROCESSABLE_ENTITY,
            code: "invalid_field",
            field: Some("id"),
        },
        Case {
            name: "scene: unknown id",
            method: Method::GET,
            path: "/v1/scenes/nope",
            body: Body::None,
            status: S::NOT_FOUND,
            code: "not_found",
            field: None,
        },
        Case {
            name: "scene: delete unknown id",
            method: Method::DELETE,
            path: "/v1/scenes/nope",
            body: Body::None,
            status: S::NOT_FOUND,
            code: "not_found",
            field: None,
        },
        // Irradiance.
        unprocessable(
            "irradiance: zero-length normal",
            Method::POST,
            irradiance,
            points(json!({"position": [0, 0, 1], "normal": [0, 0, 0]})),
            "points[0].normal",
        ),
        unprocessable(
            "irradiance: NaN written as a string",
            Method::POST,
            irradiance,
            points(json!({"position": [0, 0, 1], "normal": ["NaN", 0, 1]})),
            "points[0].normal[0]",
        ),
        Case {
            name: "irradiance: position beyond f64",
            method: Method::POST,
            path: irradiance,
            body: Body::Raw(
                "application/json",
                r#"{"points": [{"position": [0, 1e999, 1], "normal": [0, 0, 1]}], "estimator": {"method": "mc", "samples": 4}}"#,
            ),
            status: S::UNPROCESSABLE_ENTITY,
            code: "invalid_field",
            field: Some("points[0].position[1]"),
        },
        unprocessable(
            "irradiance: two-component normal",
            Method::POST,
            irradiance,
            points(json!({"position": [0, 0, 1], "normal": [0, 1]})),
            "points[0].normal",
        ),
        unprocessable(
            "irradiance: unknown estimator",
            Method::POST,
            irradiance,
            json!({"points": [good_point()], "estimator": {"method": "guess", "samples": 4}}),
            "estimator.method",
        ),
        unprocessable(
            "irradiance: missing points",
            Method::POST,
            irradiance,
            json!({"estimator": {"method": "mc", "samples": 4}}),
            "points",
        ),
        Case {
            name: "irradiance: absurd sample count",
            method: Method::POST,
            path: irradiance,
            body: Body::Json(
                json!({"points": [good_point()], "estimator": {"method": "mc", "samples": 4_000_000_000u64}}),
            ),
            status: S::UNPROCESSABLE_ENTITY,
            code: "limit_exceeded",
            field: Some("estimator.samples"),
        },
        Case {
            name: "irradiance: unknown scene",
            method: Method::POST,
            path: "/v1/scenes/nope/irradiance",
            body: Body::Json(points(good_point())),
            status: S::NOT_FOUND,
            code: "not_found",
            field: None,
        },
        Case {
            name: "irradiance: form-encoded body",
            method: Method::POST,
            path: irradiance,
            body: Body::Raw("application/x-www-form-urlencoded", "points=1"),
            status: S::UNSUPPORTED_MEDIA_TYPE,
            code: "unsupported_media_type",
            field: None,
        },
        Case {
            name: "irradiance: empty body",
            method: Method::POST,
            path: irradiance,
            body: Body::Raw("application/json", ""),
            status: S::BAD_REQUEST,
            code: "malformed_json",
            field: None,
        },
        Case {
            name: "irradiance: JSON array instead of object",
            method: Method::POST,
            path: irradiance,
            body: Body::Json(json!([1, 2, 3])),
            status: S::UNPROCESSABLE_ENTITY,
            code: "invalid_field",
            field: None,
        },
        // Radiance.
        unprocessable(
            "radiance: point off every surface",
            Method::POST,
            "/v1/scenes/tiny/radiance",
            json!({"points": [{"position": [0, 0, 2], "normal": [0, 0, 1], "direction": [0, 0, 1]}],
                             "estimator": {"method": "path"}}),
            "points[0].position",
        ),
        unprocessable(
            "radiance: zero-length direction",
            Method::POST,
            "/v1/scenes/tiny/radiance",
            json!({"points": [{"position": [0, 0, 0], "normal": [0, 0, 1], "direction": [0, 0, 0]}]}),
            "points[0].direction",
        ),
        unprocessable(
            "radiance: zero repeats",
            Method::POST,
            "/v1/scenes/tiny/radiance",
            json!({"points": [{"position": [0, 0, 0], "normal": [0, 0, 1], "direction": [0, 0, 1]}],
                             "repeats": 0}),
            "repeats",
        ),
        // Tiles.
        unprocessable(
            "tile: outside the image",
            Method::POST,
            tiles,
            tile(|t| t["x"] = json!(8)),
            "x",
        ),
        unprocessable(
            "tile: past the bottom edge",
            Method::POST,
            tiles,
            tile(|t| t["y"] = json!(6)),
            "height",
        ),
        unprocessable(
            "tile: negative width",
            Method::POST,
            tiles,
            tile(|t| t["width"] = json!(-4)),
            "width",
        ),
        Case {
            name: "tile: absurd area",
            method: Method::POST,
            path: tiles,
            body: Body::Json(tile(|t| {
                t["width"] = json!(100_000);
                t["height"] = json!(100_000);
            })),
            status: S::UNPROCESSABLE_ENTITY,
            code: "limit_exceeded",
            field: Some("width*height"),
        },
        // Work that multiplies past the budget although each knob is in range:
        // one pixel, 4096 record directions × 65,536 paths each.
        Case {
            name: "tile: one record's paths over its share of the work budget",
            method: Method::POST,
            path: tiles,
            body: Body::Json(tile(|t| {
                t["width"] = json!(1);
                t["height"] = json!(1);
                t["estimator"] =
                    json!({"method": "cache", "samples": 4096, "paths_per_direction": 65536});
            })),
            status: S::UNPROCESSABLE_ENTITY,
            code: "limit_exceeded",
            field: Some("estimated_paths_per_record"),
        },
        Case {
            name: "radiance: one record's paths over its share of the work budget",
            method: Method::POST,
            path: "/v1/scenes/tiny/radiance",
            body: Body::Json(json!({
                "points": [{"position": [0, 0, 0], "normal": [0, 0, 1], "direction": [0, 0, 1]}],
                "estimator": {"method": "cache", "samples": 4096, "paths_per_direction": 65536},
            })),
            status: S::UNPROCESSABLE_ENTITY,
            code: "limit_exceeded",
            field: Some("estimated_paths_per_record"),
        },
        // Camera paths past the budget: an 8² path-traced tile at 4096 spp,
        // 2^18 paths, against the test's budget of 2^17.
        Case {
            name: "tile: camera paths over the work budget",
            method: Method::POST,
            path: tiles,
            body: Body::Json(tile(|t| {
                t["width"] = json!(8);
                t["height"] = json!(8);
                t["samples_per_pixel"] = json!(4096);
                t["estimator"] = json!({"method": "path"});
            })),
            status: S::UNPROCESSABLE_ENTITY,
            code: "limit_exceeded",
            field: Some("estimated_paths"),
        },
        // A variance and noise whose sum overflows once spun the factorisation forever.
        unprocessable(
            "quadrature: variance and noise that overflow",
            Method::POST,
            "/v1/quadratures",
            json!({"sample_set": {"kind": "fibonacci", "count": 16},
                   "kernel": {"kind": "squared_exponential", "lengthscale": 0.5,
                              "variance": 1e308, "noise": 1e308},
                   "density": {"kind": "lambert"}}),
            "kernel.variance",
        ),
        unprocessable(
            "irradiance: bmc kernel whose variance and noise overflow",
            Method::POST,
            irradiance,
            json!({"points": [good_point()],
                   "estimator": {"method": "bmc", "samples": 16,
                                 "kernel": {"kind": "squared_exponential", "lengthscale": 0.5,
                                            "variance": 1e308, "noise": 1e308}}}),
            "estimator.kernel.variance",
        ),
        unprocessable(
            "irradiance: position far outside any scene",
            Method::POST,
            irradiance,
            points(json!({"position": [1e308, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]})),
            "points[0].position",
        ),
        unprocessable(
            "tile: unknown format",
            Method::POST,
            tiles,
            tile(|t| t["format"] = json!("tiff")),
            "format",
        ),
        unprocessable(
            "tile: zero samples per pixel",
            Method::POST,
            tiles,
            tile(|t| t["samples_per_pixel"] = json!(0)),
            "samples_per_pixel",
        ),
        unprocessable(
            "tile: exposure beyond f32",
            Method::POST,
            tiles,
            tile(|t| t["exposure"] = json!(1e300)),
            "exposure",
        ),
        unprocessable(
            "tile: too many ambient bounces",
            Method::POST,
            tiles,
            tile(|t| t["estimator"] = json!({"method": "cache", "ambient_bounces": 99})),
            "estimator.ambient_bounces",
        ),
        unprocessable(
            "tile: secondary cache with ambient bounces",
            Method::POST,
            tiles,
            tile(|t| {
                t["estimator"] =
                    json!({"method": "cache", "secondary_cache": true, "ambient_bounces": 1})
            }),
            "estimator.secondary_cache",
        ),
        unprocessable(
            "tile: unknown estimator",
            Method::POST,
            tiles,
            tile(|t| t["estimator"] = json!({"method": "magic"})),
            "estimator.method",
        ),
        // Routing.
        Case {
            name: "scene id that is not UTF-8",
            method: Method::GET,
            path: "/v1/scenes/%FF%FE",
            body: Body::None,
            status: S::UNPROCESSABLE_ENTITY,
            code: "invalid_field",
            field: Some("id"),
        },
        Case {
            name: "unknown route",
            method: Method::GET,
            path: "/v2/everything",
            body: Body::None,
            status: S::NOT_FOUND,
            code: "not_found",
            field: None,
        },
        Case {
            name: "wrong method",
            method: Method::GET,
            path: irradiance,
            body: Body::None,
            status: S::METHOD_NOT_ALLOWED,
            code: "method_not_allowed",
            field: None,
        },
    ];
    cases
}

#[tokio::test]
async fn every_bad_request_gets_its_status_code_and_field() {
    let app = spawn_app_with_scenes(
        &[("tiny.json", TINY_SCENE), ("broken.exr", "not an EXR")],
        |c| c.limits.max_paths_per_request = 1 << 17,
    )
    .await;
    let cases = cases();
    assert!(cases.len() >= 25, "{} cases", cases.len());
    for case in cases {
        let mut request = app.client.request(case.method.clone(), app.url(case.path));
        request = match case.body {
            Body::None => request,
            Body::Json(value) => request.json(&value),
            Body::Raw(content_type, text) => {
                request.header("content-type", content_type).body(text)
            }
        };
        let response = request.send().await.unwrap();
        assert_eq!(response.status(), case.status, "{}", case.name);
        let (code, field) = error_of(response).await;
        assert_eq!(code, case.code, "{}", case.name);
        assert_eq!(field.as_deref(), case.field, "{}", case.name);
    }
    // Still serving, nothing lost, nothing half-added.
    assert_eq!(app.scene_ids().await, ["tiny"]);
    let fine = app
        .post_json("/v1/scenes/tiny/irradiance", &points(good_point()))
        .await;
    assert_eq!(fine.status(), StatusCode::OK);
}

//! `POST /v1/scenes/{id}/tiles` end to end: the three encodings agree, tiles
//! assemble into the whole image, and bad tiles name their field.

mod common;

use bmc_irradiance::image::exr_io::decode_exr;
use common::{TINY_SCENE, error_of, spawn_app_with_scenes};
use reqwest::StatusCode;
use serde_json::{Value, json};

fn tile(x: u32, y: u32, width: u32, height: u32, format: &str) -> Value {
    json!({"x": x, "y": y, "width": width, "height": height, "format": format,
           "samples_per_pixel": 4, "max_depth": 4, "seed": 5})
}

/// `(width, height, rgb)` of a JSON tile body.
fn json_pixels(body: &Value) -> (u64, u64, Vec<[f32; 3]>) {
    let rgb = body["rgb"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let c: Vec<f32> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            [c[0], c[1], c[2]]
        })
        .collect();
    (
        body["width"].as_u64().unwrap(),
        body["height"].as_u64().unwrap(),
        rgb,
    )
}

#[tokio::test]
async fn encodings_agree_and_tiles_assemble_into_the_image() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let post = |body: Value| {
        let app = &app;
        async move {
            let response = app.post_json("/v1/scenes/tiny/tiles", &body).await;
            assert_eq!(response.status(), StatusCode::OK, "{body}");
            response
        }
    };

    let whole = post(tile(0, 0, 8, 8, "json")).await;
    assert_eq!(whole.headers()["content-type"], "application/json");
    assert_eq!(whole.headers()["x-tile-x"], "0");
    let rays: u64 = whole.headers()["x-rays"].to_str().unwrap().parse().unwrap();
    assert!(rays >= 8 * 8 * 4, "{rays}");
    let whole: Value = whole.json().await.unwrap();
    let (w, h, pixels) = json_pixels(&whole);
    assert_eq!((w, h, pixels.len()), (8, 8, 64));
    assert_eq!(whole["variance"].as_array().unwrap().len(), 64);
    // The lit rectangle fills the middle of the view; the sky (radiance 1) the rest.
    assert!(
        pixels
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0))
    );
    assert!(pixels.iter().any(|p| p[0] > 0.0));

    // Two halves: the same pixels, whatever the tiling.
    for (y, rows) in [(0u32, 0..32usize), (4, 32..64)] {
        let half: Value = post(tile(0, y, 8, 4, "json")).await.json().await.unwrap();
        let (_, _, half_pixels) = json_pixels(&half);
        assert_eq!(half_pixels, pixels[rows]);
    }

    // EXR carries the same floats and the variance channel.
    let exr = post(tile(0, 0, 8, 8, "exr")).await;
    assert_eq!(exr.headers()["content-type"], "image/x-exr");
    let image = decode_exr(&exr.bytes().await.unwrap()).unwrap();
    assert_eq!((image.width(), image.height()), (8, 8));
    assert_eq!(image.rgb(), &pixels[..]);
    assert_eq!(image.variance().unwrap().len(), 64);

    // PNG: an 8-bit image of the tile's size.
    let png = post(tile(2, 2, 4, 3, "png")).await;
    assert_eq!(png.headers()["content-type"], "image/png");
    assert_eq!(png.headers()["x-tile-y"], "2");
    let decoded = image::load_from_memory(&png.bytes().await.unwrap()).unwrap();
    assert_eq!((decoded.width(), decoded.height()), (4, 3));

    let metrics = app.get("/metrics").await.text().await.unwrap();
    assert!(
        metrics.contains("/v1/scenes/{id}/tiles"),
        "per-route metrics: {metrics}"
    );
}

#[tokio::test]
async fn bad_tiles_name_their_field() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |config| {
        config.limits.max_tile_area = 16;
        config.limits.max_samples = 8;
    })
    .await;
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut body = tile(0, 0, 4, 4, "json");
        edit(&mut body);
        body
    };
    let cases: Vec<(&str, Value, StatusCode, &str, &str)> = vec![
        (
            "x outside",
            with(&|b| b["x"] = json!(8)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "x",
        ),
        (
            "past the bottom",
            with(&|b| b["y"] = json!(6)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "height",
        ),
        (
            "zero width",
            with(&|b| b["width"] = json!(0)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "width",
        ),
        (
            "area over the limit",
            with(&|b| b["width"] = json!(5)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "limit_exceeded",
            "width",
        ),
        (
            "spp over the limit",
            with(&|b| b["samples_per_pixel"] = json!(9)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "limit_exceeded",
            "samples_per_pixel",
        ),
        (
            "zero spp",
            with(&|b| b["samples_per_pixel"] = json!(0)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "samples_per_pixel",
        ),
        (
            "unknown format",
            with(&|b| b["format"] = json!("tiff")),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "format",
        ),
        (
            "unknown method",
            with(&|b| b["estimator"] = json!({"method": "magic"})),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "estimator.method",
        ),
        (
            "negative x",
            with(&|b| b["x"] = json!(-1)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "x",
        ),
        (
            "max_depth 0",
            with(&|b| b["max_depth"] = json!(0)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "max_depth",
        ),
        (
            "exposure overflow",
            with(&|b| b["exposure"] = json!(1e300)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            "exposure",
        ),
    ];
    for (name, body, status, code, field) in cases {
        let response = app.post_json("/v1/scenes/tiny/tiles", &body).await;
        assert_eq!(response.status(), status, "{name}");
        assert_eq!(
            error_of(response).await,
            (code.to_owned(), Some(field.to_owned())),
            "{name}"
        );
    }
    let unknown = app
        .post_json("/v1/scenes/nope/tiles", &tile(0, 0, 1, 1, "png"))
        .await;
    assert_eq!(unknown.status(), StatusCode::NOT_FOUND);
    // The scene survived every bad request.
    let fine = app
        .post_json("/v1/scenes/tiny/tiles", &tile(0, 0, 4, 4, "json"))
        .await;
    assert_eq!(fine.status(), StatusCode::OK);
}

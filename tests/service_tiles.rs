//! `POST /v1/scenes/{id}/tiles` end to end: the three encodings agree and
//! tiles assemble into the whole image (bad tiles: `service_bad_inputs.rs`).

mod common;

use bmc_irradiance::image::exr_io::decode_exr;
use common::{TINY_SCENE, spawn_app_with_scenes};
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

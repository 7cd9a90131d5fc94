//! `POST /v1/scenes/{id}/radiance` end to end: through the irradiance cache
//! it agrees with path tracing and leaves its records in the scene's cache.

use crate::common::spawn_app_with_scenes;
use bmc_irradiance::testing::agrees;
use reqwest::StatusCode;
use serde_json::{Value, json};

fn request(estimator: Value, repeats: u32) -> Value {
    json!({
        // The Cornell back wall above the boxes, seen from the front.
        "points": [{"position": [0.1, 0.6, -1.0], "normal": [0, 0, 1], "direction": [0.2, -0.1, 1.0]},
                   {"position": [-0.3, 0.2, -1.0], "normal": [0, 0, 2], "direction": [0.0, 0.0, 1.0]}],
        "estimator": estimator,
        "repeats": repeats,
        "max_depth": 6,
        "seed": 3,
    })
}

fn rgb(body: &Value, key: &str, i: usize) -> Vec<f64> {
    body[key][i]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

#[tokio::test]
async fn cached_radiance_agrees_with_path_tracing_and_fills_the_cache() {
    let cornell = include_str!("../../scenes/cornell-box.json");
    let app = spawn_app_with_scenes(&[("box.json", cornell)], |_| {}).await;
    let post = |body: Value| {
        let app = &app;
        async move {
            let response = app.post_json("/v1/scenes/box/radiance", &body).await;
            assert_eq!(response.status(), StatusCode::OK);
            response.json::<Value>().await.unwrap()
        }
    };
    let path = post(request(json!({"method": "path"}), 2048)).await;
    let bmc = post(request(
        json!({"method": "cache", "samples": 128, "paths_per_direction": 4, "light_samples": 64}),
        4,
    ))
    .await;
    assert!(bmc["rays"].as_u64().unwrap() > 0);
    for i in 0..2 {
        let (p, sp) = (rgb(&path, "radiance", i), rgb(&path, "std_dev", i));
        let (b, sb) = (rgb(&bmc, "radiance", i), rgb(&bmc, "std_dev", i));
        for c in 0..3 {
            assert!(b[c] > 0.0 && sb[c] > 0.0 && sp[c] > 0.0, "{bmc}");
            // 4σ of both estimates plus 3 % for the records' unmodelled path noise.
            assert!(
                agrees(b[c], p[c], sp[c].hypot(sb[c]), 4.0, 0.03),
                "point {i} channel {c}: {path} vs {bmc}"
            );
        }
    }
    let cache: Value = app.get("/v1/scenes/box/cache").await.json().await.unwrap();
    assert_eq!(
        cache["caches"][0]["configuration"]["max_depth"], 6,
        "{cache}"
    );
    assert_eq!(cache["caches"][0]["stats"]["records"], 2, "{cache}");
}

/// With `secondary_cache` the records a radiance request creates read the
/// scene's secondary cache: the first request builds it (its rays counted
/// in the response), the next finds it, and both agree with path tracing.
#[tokio::test]
async fn radiance_through_the_secondary_cache_agrees_with_path_tracing() {
    let cornell = include_str!("../../scenes/cornell-box.json");
    let app = spawn_app_with_scenes(&[("box.json", cornell)], |_| {}).await;
    let post = |estimator: Value, repeats: u32, seed: u64| {
        let app = &app;
        let mut body = request(estimator, repeats);
        // Long enough paths for a cached bounce (AMBIENT_MIN_DEPTH from the point).
        body["max_depth"] = json!(20);
        body["seed"] = json!(seed);
        async move {
            let response = app.post_json("/v1/scenes/box/radiance", &body).await;
            assert_eq!(response.status(), StatusCode::OK);
            response.json::<Value>().await.unwrap()
        }
    };
    let path = post(json!({"method": "path"}), 2048, 3).await;
    let estimator = json!({"method": "cache", "samples": 128, "paths_per_direction": 4,
                           "light_samples": 64, "secondary_cache": true});
    let building = post(estimator.clone(), 4, 3).await;
    let cache: Value = app.get("/v1/scenes/box/cache").await.json().await.unwrap();
    assert!(
        cache["caches"][0]["secondary_records"].as_u64().unwrap() > 0,
        "{cache}"
    );
    let reading = post(estimator, 4, 4).await;
    assert!(reading["rays"].as_u64() < building["rays"].as_u64());
    for bmc in [&building, &reading] {
        for i in 0..2 {
            let (p, sp) = (rgb(&path, "radiance", i), rgb(&path, "std_dev", i));
            let (b, sb) = (rgb(bmc, "radiance", i), rgb(bmc, "std_dev", i));
            for c in 0..3 {
                // 4σ plus 3 % for the records' unmodelled noise and the
                // secondary cache's interpolation.
                assert!(
                    agrees(b[c], p[c], sp[c].hypot(sb[c]), 4.0, 0.03),
                    "point {i} channel {c}: {path} vs {bmc}"
                );
            }
        }
    }
}

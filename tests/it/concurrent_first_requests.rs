//! Many concurrent first requests on a fresh service, on every route whose
//! first request fills a cache computed once per key (calibrations and their
//! training sets, lengthscale fits, quadratures and factorisations, the
//! irradiance caches, reproducible tiles' records and passes, secondary
//! caches). A request that waited on a rayon thread for a computation
//! suspended below it on the same thread wedged the pool for good; here every
//! request answers 200 in bounded time, round after round, and the service
//! stays healthy.

use std::time::{Duration, Instant};

use crate::common::spawn_app_with_scenes;
use reqwest::StatusCode;
use serde_json::{Value, json};

const CORNELL: &str = include_str!("../../scenes/cornell-box.json");
const CONCURRENT: usize = 16;
const ROUNDS: usize = 5;
/// Far beyond what these small requests take in a debug build, far below
/// "forever".
const BOUND: Duration = Duration::from_secs(240);

fn points(estimator: Value) -> Value {
    json!({
        "points": [{"position": [0.1, -0.999, 0.2], "normal": [0, 1, 0]},
                   {"position": [-0.3, 0.2, -0.999], "normal": [0, 0, 1]}],
        "estimator": estimator,
        "max_depth": 3,
    })
}

/// Each route that fills a cache on first use: (method and path, body).
fn first_requests() -> Vec<(&'static str, Option<Value>)> {
    vec![
        (
            "/v1/scenes/box/irradiance",
            Some(points(json!({"method": "qmc", "samples": 16}))),
        ),
        (
            "/v1/scenes/box/irradiance",
            Some(points(json!({"method": "bmc", "samples": 16}))),
        ),
        (
            "/v1/scenes/box/irradiance",
            Some(points(
                json!({"method": "bmc", "samples": 16, "kernel": {"lengthscale": "auto"}}),
            )),
        ),
        (
            "/v1/quadratures",
            Some(json!({
                "sample_set": {"kind": "fibonacci", "count": 24},
                "kernel": {"kind": "squared_exponential", "lengthscale": 0.6, "variance": 1.0, "noise": 1e-8},
                "density": {"kind": "lambert"}
            })),
        ),
        ("/v1/scenes/box/tiles/1/1.png?size=16&preset=draft", None),
        (
            "/v1/scenes/box/tiles",
            Some(
                json!({"x": 24, "y": 24, "width": 8, "height": 8, "format": "json",
                "max_depth": 3, "seed": 2, "samples_per_pixel": 1, "pass": 0,
                "estimator": {"method": "cache", "samples": 16, "light_samples": 1,
                              "accuracy": 0.5, "secondary_cache": true}}),
            ),
        ),
        (
            "/v1/scenes/box/radiance",
            Some(json!({
                "points": [{"position": [0.1, 0.6, -1.0], "normal": [0, 0, 1], "direction": [0.2, -0.1, 1.0]}],
                "estimator": {"method": "cache", "samples": 16, "light_samples": 1},
                "repeats": 1, "max_depth": 3, "seed": 3,
            })),
        ),
        (
            "/v1/scenes/box/irradiance",
            Some(points(
                json!({"method": "bmc", "samples": 16, "records_prior": true}),
            )),
        ),
    ]
}

async fn send(client: reqwest::Client, url: String, body: Option<Value>) -> (StatusCode, String) {
    let request = match body {
        Some(body) => client.post(url).json(&body),
        None => client.get(url),
    };
    let response = request.send().await.unwrap();
    let status = response.status();
    let text = if status.is_success() {
        String::new()
    } else {
        response.text().await.unwrap_or_default()
    };
    (status, text)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn concurrent_first_requests_never_wedge_the_pool() {
    for round in 0..ROUNDS {
        let app = spawn_app_with_scenes(&[("box.json", CORNELL)], |_| {}).await;
        for (path, body) in first_requests() {
            let started = Instant::now();
            let mut clients = tokio::task::JoinSet::new();
            for _ in 0..CONCURRENT {
                clients.spawn(send(app.client.clone(), app.url(path), body.clone()));
            }
            let answers = tokio::time::timeout(BOUND, clients.join_all())
                .await
                .unwrap_or_else(|_| panic!("round {round}: {path} {body:?} hung"));
            for (status, text) in answers {
                assert_eq!(
                    status,
                    StatusCode::OK,
                    "round {round}: {path} {body:?}: {text}"
                );
            }
            let health = app.get("/health").await;
            assert_eq!(
                health.status(),
                StatusCode::OK,
                "round {round} after {path}"
            );
            let health: Value = health.json().await.unwrap();
            assert_eq!(health["cpu"]["running"], 0, "{health}");
            eprintln!(
                "round {round}: {CONCURRENT} × {path} in {:.1} s",
                started.elapsed().as_secs_f64()
            );
        }
    }
}

//! Identical concurrent first requests for one quadrature compute it once.
//! Alone in its test binary: the metrics recorder is process-wide, so no other
//! test may touch the cache counters while this one reads them.

#[path = "it/common/mod.rs"]
mod common;

use common::spawn_app;
use serde_json::{Value, json};

fn counter(metrics: &str, name: &str) -> f64 {
    metrics
        .lines()
        .find_map(|line| line.strip_prefix(name)?.trim().parse().ok())
        .unwrap_or(0.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn sixteen_identical_first_requests_factorise_once() {
    let app = spawn_app().await;
    let before = app.get("/metrics").await.text().await.unwrap();
    let body = json!({
        // Closed-form kernel means (SE, uniform) keep the one computation short
        // in debug builds; only the factorisation of N = 256 takes a while.
        "sample_set": {"kind": "stratified", "count": 256, "seed": 5},
        "kernel": {"kind": "squared_exponential", "lengthscale": 0.45},
        "density": {"kind": "uniform"}
    });
    let tasks: Vec<_> = (0..16)
        .map(|_| {
            let request = app.client.post(app.url("/v1/quadratures")).json(&body);
            tokio::spawn(async move {
                let response = request.send().await.unwrap();
                assert_eq!(response.status(), reqwest::StatusCode::OK);
                response.json::<Value>().await.unwrap()
            })
        })
        .collect();
    let mut bodies = Vec::new();
    for task in tasks {
        bodies.push(task.await.unwrap());
    }
    let computed = bodies
        .iter()
        .filter(|b| b["cached"] == json!(false))
        .count();
    assert_eq!(computed, 1);
    assert!(bodies.iter().all(|b| b["weights"] == bodies[0]["weights"]));

    let after = app.get("/metrics").await.text().await.unwrap();
    let misses = "bmc_factorisation_cache_misses_total";
    let hits = "bmc_factorisation_cache_hits_total";
    assert_eq!(
        counter(&after, misses) - counter(&before, misses),
        1.0,
        "{after}"
    );
    assert_eq!(
        counter(&after, hits) - counter(&before, hits),
        15.0,
        "{after}"
    );
    assert!(counter(&after, "bmc_factorisation_cache_bytes") >= 200.0 * 200.0 * 8.0);
}

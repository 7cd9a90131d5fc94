//! Property test over the request bodies of every route: valid bodies with
//! random parts replaced by random JSON (extreme numbers, wrong types, deep
//! or empty structures) or arbitrary JSON documents. Whatever arrives, the
//! service answers in time with a success or a 4xx carrying the JSON error
//! body (503 only as back-pressure), never a 5xx, and stays healthy with its
//! scenes.
//!
//! It runs briefly and deterministically in CI (`FUZZ_CASES`, default 160
//! cases, from a fixed seed, so a landing never depends on luck); set
//! `FUZZ_CASES=5000 FUZZ_RANDOM=1` for a longer session that explores new cases.

use std::time::Duration;

use crate::common::{TINY_SCENE, spawn_app_with_scenes};
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngAlgorithm, TestRng, TestRunner};
use serde_json::{Value, json};

/// Valid bodies of every POST route, to mutate.
fn seeds() -> Vec<(&'static str, Value)> {
    let point = json!({"position": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]});
    let mut scene: Value = serde_json::from_str(TINY_SCENE).unwrap();
    scene["name"] = json!("fuzzed");
    vec![
        (
            "/v1/scenes/tiny/irradiance",
            json!({"points": [point], "estimator": {"method": "bmc", "samples": 16,
                   "decomposition": "split", "sample_set": {"kind": "fibonacci_cosine"},
                   "kernel": {"kind": "matern52", "lengthscale": 0.5}},
                   "max_depth": 4, "seed": 1}),
        ),
        (
            "/v1/scenes/tiny/tiles",
            json!({"x": 0, "y": 0, "width": 4, "height": 4, "format": "json",
                   "samples_per_pixel": 2, "estimator": {"method": "cache", "samples": 16,
                   "accuracy": 0.5, "paths_per_direction": 2}, "max_depth": 4, "seed": 3}),
        ),
        (
            "/v1/scenes/tiny/radiance",
            json!({"points": [{"position": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0],
                   "direction": [0.1, 0.0, 1.0]}], "estimator": {"method": "path"},
                   "repeats": 2, "max_depth": 4, "seed": 1}),
        ),
        (
            "/v1/quadratures",
            json!({"sample_set": {"kind": "fibonacci", "count": 16},
                   "kernel": {"kind": "squared_exponential", "lengthscale": 0.5,
                              "variance": 1.0, "noise": 1e-8},
                   "density": {"kind": "lambert"}, "prior_mean": "zero", "kernel_mean": "exact"}),
        ),
        ("/v1/scenes", scene),
    ]
}

/// JSON values that break assumptions (extremes, wrong types, nesting) and
/// plausible ones (small numbers, the API's own names).
fn nasty_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        1 => Just(json!(null)),
        1 => Just(json!(0)),
        1 => Just(json!(-1)),
        1 => Just(json!(1e308)),
        1 => Just(json!(-1e308)),
        1 => Just(json!(5e-324)),
        1 => Just(json!(u64::MAX)),
        1 => Just(json!(i64::MIN)),
        1 => Just(json!(4097)),
        1 => Just(json!(65536)),
        1 => Just(json!("")),
        1 => Just(json!("auto")),
        // Plausible values, so mutated bodies also reach the estimators.
        8 => prop::sample::select(vec![1.0, 2.0, 0.5, 0.01, 8.0, 16.0, 64.0, 256.0])
            .prop_map(Value::from),
        8 => prop::sample::select(vec![
            "bmc", "path", "mc", "qmc", "split", "hemisphere", "exr", "png", "json",
            "fibonacci", "cosine", "uniform", "stratified", "matern32", "matern52",
            "squared_exponential", "lambert", "phong", "gls", "zero", "sg",
        ])
        .prop_map(Value::from),
        1 => Just(json!([])),
        1 => Just(json!({})),
        1 => any::<bool>().prop_map(Value::from),
        1 => any::<i64>().prop_map(Value::from),
        1 => any::<f64>()
            .prop_filter("finite", |v| v.is_finite())
            .prop_map(Value::from),
        1 => "[a-z_]{0,12}".prop_map(Value::from),
    ];
    leaf.prop_recursive(3, 16, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::from),
            prop::collection::btree_map("[a-z_]{1,8}", inner, 0..4)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// Replaces the node reached by `choices` (each picks a child) with `value`.
fn mutate(node: &mut Value, choices: &[usize], value: Value) {
    let Some((&choice, rest)) = choices.split_first() else {
        *node = value;
        return;
    };
    match node {
        Value::Object(map) if !map.is_empty() => {
            let key = map.keys().nth(choice % map.len()).unwrap().clone();
            mutate(map.get_mut(&key).unwrap(), rest, value);
        }
        Value::Array(items) if !items.is_empty() => {
            let len = items.len();
            mutate(&mut items[choice % len], rest, value);
        }
        _ => *node = value,
    }
}

#[test]
fn mutated_and_arbitrary_bodies_never_break_the_service() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let app = runtime.block_on(spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |c| {
        // Keep each accepted request short: the budget refuses the rest.
        c.limits.request_deadline_secs = 5;
        c.limits.max_paths_per_request = 1 << 18;
    }));
    let cases = std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(160);
    let config = ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    let mut runner = if std::env::var_os("FUZZ_RANDOM").is_some() {
        TestRunner::new(config)
    } else {
        TestRunner::new_with_rng(config, TestRng::deterministic_rng(RngAlgorithm::ChaCha))
    };
    let seeds = seeds();
    // The unmutated bodies succeed, so mutations start from the handlers' success paths.
    for (path, body) in &seeds {
        let status = runtime.block_on(async { app.post_json(path, body).await.status() });
        assert!(status.is_success(), "{path} {body} → {status}");
    }
    let statuses = std::cell::RefCell::new(std::collections::BTreeMap::<u16, u32>::new());
    let strategy = (
        0..seeds.len(),
        prop::collection::vec(
            (prop::collection::vec(0usize..8, 1..5), nasty_value()),
            1..3,
        ),
        prop::option::weighted(0.05, nasty_value()),
    );
    runner
        .run(&strategy, |(route, mutations, whole)| {
            let (path, seed) = &seeds[route];
            let body = whole.unwrap_or_else(|| {
                let mut body = seed.clone();
                for (choices, value) in mutations {
                    mutate(&mut body, &choices, value);
                }
                body
            });
            let (status, text) = runtime.block_on(async {
                let response = app
                    .client
                    .post(app.url(path))
                    .json(&body)
                    .timeout(Duration::from_secs(15))
                    .send()
                    .await
                    .expect("answered in time");
                let status = response.status();
                (status, response.text().await.unwrap_or_default())
            });
            *statuses.borrow_mut().entry(status.as_u16()).or_default() += 1;
            prop_assert!(
                !status.is_server_error() || status.as_u16() == 503,
                "{path} {body} → {status} {text}"
            );
            if status.is_client_error() {
                let error: Value = serde_json::from_str(&text).unwrap_or_default();
                prop_assert!(error["error"]["code"].is_string(), "{path} {body} → {text}");
            }
            Ok(())
        })
        .unwrap();
    // Most mutations are refused; the statuses show the mix.
    eprintln!("statuses: {:?}", statuses.into_inner());
    runtime.block_on(async {
        let health: Value = app.get("/health").await.json().await.unwrap();
        assert_eq!(health["status"], "ok");
        let scenes: Value = app.get("/v1/scenes").await.json().await.unwrap();
        assert!(scenes.as_array().unwrap().iter().any(|s| s["id"] == "tiny"));
    });
}

//! `POST /v1/quadratures` end to end: cache miss then hit, and bad requests.

use crate::common::{TestApp, error_of, spawn_app, spawn_app_with};
use reqwest::StatusCode;
use serde_json::{Value, json};

fn request(count: u32, lengthscale: f64) -> Value {
    json!({
        "sample_set": {"kind": "fibonacci", "count": count},
        "kernel": {"kind": "squared_exponential", "lengthscale": lengthscale, "variance": 1.0, "noise": 1e-8},
        "density": {"kind": "lambert"}
    })
}

async fn quadrature(app: &TestApp, body: &Value) -> Value {
    let response = app.post_json("/v1/quadratures", body).await;
    assert_eq!(response.status(), StatusCode::OK);
    response.json().await.unwrap()
}

fn weight_sum(body: &Value) -> f64 {
    body["weights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_f64().unwrap())
        .sum()
}

#[tokio::test]
async fn first_request_computes_and_the_second_is_served_from_the_cache() {
    let app = spawn_app().await;
    let first = quadrature(&app, &request(32, 0.5)).await;
    assert_eq!(first["cached"], json!(false));
    let second = quadrature(&app, &request(32, 0.5)).await;
    assert_eq!(second["cached"], json!(true));
    assert_eq!(first["weights"], second["weights"]);
    assert_eq!(first["id"], second["id"]);
    for field in ["directions", "kernel_means", "weights"] {
        assert_eq!(first[field].as_array().unwrap().len(), 32, "{field}");
    }
    // Lambert weights of the zero-mean rule integrate constants nearly exactly.
    let sum = weight_sum(&first);
    assert!((sum - 1.0).abs() < 0.05, "{sum}");
    let (prior, posterior) = (
        first["prior_variance"].as_f64().unwrap(),
        first["posterior_variance"].as_f64().unwrap(),
    );
    assert!(0.0 <= posterior && posterior < prior, "{first}");

    // A different lengthscale is another configuration with another id.
    let other = quadrature(&app, &request(32, 0.6)).await;
    assert_eq!(other["cached"], json!(false));
    assert_ne!(other["id"], first["id"]);
    // GLS weights integrate constants exactly: they sum to ∫p.
    let gls = quadrature(
        &app,
        &json!({
            "sample_set": {"kind": "uniform", "count": 16, "seed": 3},
            "kernel": {"kind": "matern52", "lengthscale": 0.8},
            "density": {"kind": "phong", "exponent": 8.0, "mirror_elevation": 0.4},
            "prior_mean": "gls"
        }),
    )
    .await;
    assert!((weight_sum(&gls) - gls["density_integral"].as_f64().unwrap()).abs() < 1e-9);
}

#[tokio::test]
async fn bad_requests_name_their_field() {
    let app = spawn_app_with(|config| config.limits.max_samples = 128).await;
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut body = request(16, 0.5);
        edit(&mut body);
        body
    };
    let cases: Vec<(&str, Value, &str, &str)> = vec![
        (
            "zero count",
            request(0, 0.5),
            "invalid_field",
            "sample_set.count",
        ),
        (
            "count over the limit",
            request(129, 0.5),
            "limit_exceeded",
            "sample_set.count",
        ),
        (
            "negative lengthscale",
            request(16, -0.5),
            "invalid_field",
            "kernel.lengthscale",
        ),
        (
            "tiny lengthscale",
            request(16, 1e-5),
            "invalid_field",
            "kernel.lengthscale",
        ),
        (
            "zero variance",
            with(&|b| b["kernel"]["variance"] = json!(0.0)),
            "invalid_field",
            "kernel.variance",
        ),
        (
            "negative noise",
            with(&|b| b["kernel"]["noise"] = json!(-1.0)),
            "invalid_field",
            "kernel.noise",
        ),
        (
            "unknown kernel",
            with(&|b| b["kernel"]["kind"] = json!("cubic")),
            "invalid_field",
            "kernel.kind",
        ),
        (
            "unknown set",
            with(&|b| b["sample_set"]["kind"] = json!("halton")),
            "invalid_field",
            "sample_set.kind",
        ),
        (
            "phong without exponent",
            with(&|b| b["density"] = json!({"kind": "phong"})),
            "invalid_field",
            "density.exponent",
        ),
        (
            "negative exponent",
            with(&|b| b["density"] = json!({"kind": "phong", "exponent": -2})),
            "invalid_field",
            "density.exponent",
        ),
        (
            "mirror below horizon",
            with(&|b| {
                b["density"] = json!({"kind": "phong", "exponent": 2, "mirror_elevation": 2.0})
            }),
            "invalid_field",
            "density.mirror_elevation",
        ),
        (
            "sg with matern",
            with(&|b| {
                b["kernel"]["kind"] = json!("matern32");
                b["kernel_mean"] = json!("spherical_gaussian");
            }),
            "invalid_field",
            "kernel_mean",
        ),
        (
            "missing kernel",
            with(&|b| {
                b.as_object_mut().unwrap().remove("kernel");
            }),
            "invalid_field",
            "kernel",
        ),
        (
            "unknown field",
            with(&|b| b["sample_set"]["colour"] = json!(1)),
            "invalid_field",
            "sample_set.colour",
        ),
    ];
    for (name, body, code, field) in cases {
        let response = app.post_json("/v1/quadratures", &body).await;
        assert_eq!(
            response.status(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "{name}"
        );
        assert_eq!(
            error_of(response).await,
            (code.to_owned(), Some(field.to_owned())),
            "{name}"
        );
    }
}

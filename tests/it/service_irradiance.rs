//! `POST /v1/scenes/{id}/irradiance` end to end, and a table of bad requests.

use crate::common::{
    TINY_SCENE, assert_same_answer_without_the_kept_work, error_of, spawn_app_with_scenes,
};
use reqwest::StatusCode;
use serde_json::{Value, json};

fn request(normal: [f64; 3], samples: u32) -> Value {
    json!({
        "points": [{"position": [0.0, 0.0, 5.0], "normal": normal}],
        "estimator": {"method": "mc", "samples": samples, "decomposition": "hemisphere"},
        "max_depth": 1,
        "seed": 7,
    })
}

#[tokio::test]
async fn open_sky_gives_pi_times_radiance_and_counts_rays() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    // Above the only shape, facing up: the whole hemisphere sees radiance 1, so E = π.
    let response = app
        .post_json("/v1/scenes/tiny/irradiance", &request([0.0, 0.0, 2.0], 16))
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    let body: Value = response.json().await.unwrap();
    for channel in body["irradiance"][0].as_array().unwrap() {
        assert!(
            (channel.as_f64().unwrap() - std::f64::consts::PI).abs() < 1e-9,
            "{body}"
        );
    }
    assert!(body["rays"].as_u64().unwrap() >= 16);
    assert_eq!(body["std_dev"].as_array().unwrap().len(), 1);

    let metrics = app.get("/metrics").await.text().await.unwrap();
    assert!(
        metrics.lines().any(|l| l.starts_with("rays_traced_total")),
        "{metrics}"
    );
}

/// The same request gives the same numbers; the first on a scene also
/// counts the rays of the work it did for every later one (the kernel fit of
/// an `"auto"` lengthscale, the calibration of the error bars), and says so.
#[tokio::test]
async fn same_request_same_numbers_and_the_first_counts_its_calibration() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    for method in ["mc", "qmc", "bmc"] {
        let mut body = request([0.3, 0.1, 1.0], 32);
        body["points"] = json!([
            {"position": [0.2, -0.1, 0.0], "normal": [0.0, 0.0, 1.0]},
            {"position": [0.0, 0.0, 1.0], "normal": [0.3, 0.2, 1.0]}
        ]);
        body["max_depth"] = json!(4);
        body["estimator"]["method"] = json!(method);
        body["estimator"]["decomposition"] = json!("split");
        let mut answers = Vec::new();
        for _ in 0..2 {
            let response = app.post_json("/v1/scenes/tiny/irradiance", &body).await;
            assert_eq!(response.status(), StatusCode::OK);
            answers.push(response.json::<Value>().await.unwrap());
        }
        let (first, second) = (&answers[0], &answers[1]);
        assert!(first.get("calibration").is_some(), "{first}");
        assert_same_answer_without_the_kept_work(first, second);
        // Two points of 32 paths each; the calibration runs the estimator
        // four times on 96 training points, and the first calibration of
        // the scene also traces their reference (4,096 paths each), which
        // the others share.
        assert!(second["rays"].as_u64() >= Some(2 * 32), "{second}");
        let reference = if method == "mc" { 96 * 4096 } else { 0 };
        let calibrating = first["amortised_rays"].as_u64().unwrap();
        assert!(calibrating >= 4 * 96 * 32 + reference, "{method}: {first}");
    }
}

/// `light_samples` sets the split direct part's samples apart from the
/// hemisphere's: with direct light only the answer is the light samples'
/// alone, so 16 directions with 256 light samples answer as 256 directions,
/// to the bit, for either fixed rule.
#[tokio::test]
async fn light_samples_set_the_direct_part_apart_from_the_directions() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let mut answers = Vec::new();
    for estimator in [
        json!({"method": "qmc", "samples": 256}),
        json!({"method": "qmc", "samples": 16, "light_samples": 256}),
        json!({"method": "bmc", "samples": 16, "light_samples": 256}),
        json!({"method": "qmc", "samples": 16}),
    ] {
        let mut body = request([0.3, 0.2, 1.0], 0);
        body["points"][0]["position"] = json!([0.2, -0.1, 0.0]);
        body["estimator"] = estimator;
        body["estimator"]["decomposition"] = json!("split");
        body["estimator"]["calibrate"] = json!(false);
        let response = app.post_json("/v1/scenes/tiny/irradiance", &body).await;
        assert_eq!(response.status(), StatusCode::OK);
        let answer: Value = response.json().await.unwrap();
        answers.push((answer["irradiance"].clone(), answer["std_dev"].clone()));
    }
    assert_eq!(answers[0], answers[1]);
    assert_eq!(answers[0], answers[2]);
    assert_ne!(answers[0], answers[3]);
}

#[tokio::test]
async fn bad_requests_get_their_status_code_and_field() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |config| {
        config.limits.max_points = 4;
        config.limits.max_samples = 64;
        config.limits.max_body_bytes = 2048;
    })
    .await;
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut body = request([0.0, 0.0, 1.0], 8);
        edit(&mut body);
        body
    };
    let cases: Vec<(&str, Value, StatusCode, &str, Option<&str>)> = vec![
        (
            "zero normal",
            request([0.0, 0.0, 0.0], 8),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("points[0].normal"),
        ),
        (
            "too many samples",
            request([0.0, 0.0, 1.0], 65),
            StatusCode::UNPROCESSABLE_ENTITY,
            "limit_exceeded",
            Some("estimator.samples"),
        ),
        (
            "zero samples",
            request([0.0, 0.0, 1.0], 0),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("estimator.samples"),
        ),
        (
            "light samples under the hemisphere decomposition",
            with(&|b| b["estimator"]["light_samples"] = json!(8)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("estimator.light_samples"),
        ),
        (
            "zero light samples",
            with(&|b| {
                b["estimator"]["decomposition"] = json!("split");
                b["estimator"]["light_samples"] = json!(0);
            }),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("estimator.light_samples"),
        ),
        (
            "too many light samples",
            with(&|b| {
                b["estimator"]["decomposition"] = json!("split");
                b["estimator"]["light_samples"] = json!(65);
            }),
            StatusCode::UNPROCESSABLE_ENTITY,
            "limit_exceeded",
            Some("estimator.light_samples"),
        ),
        (
            "unknown method",
            with(&|b| b["estimator"]["method"] = json!("magic")),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("estimator.method"),
        ),
        (
            "max_depth 0",
            with(&|b| b["max_depth"] = json!(0)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("max_depth"),
        ),
        (
            "no points",
            with(&|b| b["points"] = json!([])),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("points"),
        ),
        (
            "too many points",
            with(&|b| {
                b["points"] = json!(vec![json!({"position": [0, 0, 1], "normal": [0, 0, 1]}); 5])
            }),
            StatusCode::UNPROCESSABLE_ENTITY,
            "limit_exceeded",
            Some("points"),
        ),
        (
            "position as string",
            with(&|b| b["points"][0]["position"] = json!("here")),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("points[0].position"),
        ),
        (
            // A missing estimator is the default one; a wrong one is named.
            "estimator not an object",
            with(&|b| b["estimator"] = json!(5)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("estimator"),
        ),
        (
            "unknown field",
            with(&|b| b["sede"] = json!(1)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("sede"),
        ),
        (
            "negative seed",
            with(&|b| b["seed"] = json!(-1)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_field",
            Some("seed"),
        ),
        (
            "body over the limit",
            with(&|b| b["padding"] = json!("x".repeat(4096))),
            StatusCode::PAYLOAD_TOO_LARGE,
            "payload_too_large",
            None,
        ),
    ];
    for (name, body, status, code, field) in cases {
        let response = app.post_json("/v1/scenes/tiny/irradiance", &body).await;
        assert_eq!(response.status(), status, "{name}");
        assert_eq!(
            error_of(response).await,
            (code.to_owned(), field.map(str::to_owned)),
            "{name}"
        );
    }

    let malformed = app
        .client
        .post(app.url("/v1/scenes/tiny/irradiance"))
        .header("content-type", "application/json")
        .body("{\"points\": [")
        .send()
        .await
        .unwrap();
    assert_eq!(malformed.status(), StatusCode::BAD_REQUEST);
    assert_eq!(error_of(malformed).await, ("malformed_json".into(), None));

    let unknown = app
        .post_json("/v1/scenes/nope/irradiance", &request([0.0, 0.0, 1.0], 8))
        .await;
    assert_eq!(unknown.status(), StatusCode::NOT_FOUND);
    assert_eq!(error_of(unknown).await, ("not_found".into(), None));
}

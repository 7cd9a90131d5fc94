//! `POST /v1/scenes/{id}/irradiance` with the `mc`, `qmc` and `bmc`
//! estimators on the bundled Cornell box, the `"auto"` lengthscale and its
//! report in `GET /v1/scenes/{id}`.

use crate::common::{
    TestApp, answer_and_cost, assert_same_answer_without_the_kept_work, error_of,
    spawn_app_with_scenes,
};
use bmc_irradiance::testing::agrees;
use reqwest::StatusCode;
use serde_json::{Value, json};

const CORNELL: &str = include_str!("../../scenes/cornell-box.json");

async fn cornell_app() -> TestApp {
    spawn_app_with_scenes(&[("cornell-box.json", CORNELL)], |_| {}).await
}

fn request(estimator: Value) -> Value {
    json!({
        "points": [
            {"position": [0.2, 0.4, -0.999], "normal": [0, 0, 1]},
            {"position": [-0.999, 0.1, 0.2], "normal": [1, 0, 0]}
        ],
        "estimator": estimator,
        "max_depth": 3,
        "seed": 11,
    })
}

async fn irradiance(app: &TestApp, estimator: Value) -> Value {
    post_irradiance(app, &request(estimator)).await
}

/// The 200 answer to a whole irradiance request body.
async fn post_irradiance(app: &TestApp, body: &Value) -> Value {
    let response = app
        .post_json("/v1/scenes/cornell-box/irradiance", body)
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    response.json().await.unwrap()
}

fn luminance(body: &Value, point: usize, field: &str) -> f64 {
    let c: Vec<f64> = body[field][point]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

#[tokio::test]
async fn the_three_estimators_agree_within_their_uncertainty() {
    let app = cornell_app().await;
    let reference = irradiance(
        &app,
        json!({"method": "mc", "samples": 4096, "calibrate": false}),
    )
    .await;
    for estimator in [
        json!({"method": "mc", "samples": 64}),
        json!({"method": "qmc", "samples": 64}),
        json!({"method": "qmc", "samples": 64, "sample_set": {"kind": "fibonacci"}}),
        json!({"method": "bmc", "samples": 64, "kernel": {"lengthscale": 0.5}}),
        json!({"method": "bmc", "samples": 64,
               "sample_set": {"kind": "stratified", "seed": 3},
               "kernel": {"kind": "matern52", "lengthscale": 0.4, "noise": 0.01}}),
    ] {
        let body = irradiance(&app, estimator.clone()).await;
        assert!(body["rays"].as_u64().unwrap() >= 2 * 64, "{body}");
        for point in 0..2 {
            let (e, r) = (
                luminance(&body, point, "irradiance"),
                luminance(&reference, point, "irradiance"),
            );
            let sigma =
                luminance(&body, point, "std_dev").hypot(luminance(&reference, point, "std_dev"));
            assert!(e > 0.0 && sigma > 0.0, "{estimator} {body}");
            // Both standard deviations are rough for N = 64; 5σ is a
            // generous but still failing-when-wrong bound.
            assert!(
                agrees(e, r, sigma, 5.0, 0.0),
                "{estimator}: {e} vs {r} ± {sigma}"
            );
        }
        let is_bmc = estimator["method"] == "bmc";
        assert_eq!(body["lengthscale"].is_number(), is_bmc, "{body}");
    }
    // Hemisphere mode: the small bright light is sampled only by chance at
    // N = 64 (split mode exists for that), so only check it runs.
    let hemisphere = irradiance(
        &app,
        json!({"method": "bmc", "samples": 64, "decomposition": "hemisphere"}),
    )
    .await;
    assert!(luminance(&hemisphere, 0, "irradiance").is_finite());
}

#[tokio::test]
async fn point_requests_fill_the_factorisation_cache() {
    let app = cornell_app().await;
    let estimator = json!({"method": "bmc", "samples": 24,
                           "kernel": {"lengthscale": 0.45, "noise": 0.002}});
    let first = irradiance(&app, estimator.clone()).await;
    assert_eq!(first["lengthscale"], json!(0.45));
    // The same weights through /v1/quadratures: already cached by the point request.
    let quadrature: Value = app
        .post_json(
            "/v1/quadratures",
            &json!({
                "sample_set": {"kind": "fibonacci_cosine", "count": 24},
                "kernel": {"kind": "squared_exponential", "lengthscale": 0.45, "variance": 1.0, "noise": 0.002},
                "density": {"kind": "lambert"},
                "prior_mean": "gls"
            }),
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(quadrature["cached"], json!(true), "{quadrature}");
    // Same request, same numbers (the cache changes nothing but the cost).
    assert_same_answer_without_the_kept_work(&first, &irradiance(&app, estimator).await);
}

#[tokio::test]
async fn auto_lengthscale_is_fitted_once_reported_and_dropped_with_the_scene() {
    let app = cornell_app().await;
    let summary: Value = app
        .get("/v1/scenes/cornell-box")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(summary["fitted_kernels"], json!([]));

    let first = irradiance(&app, json!({"method": "bmc", "samples": 32})).await;
    let lengthscale = first["lengthscale"].as_f64().unwrap();
    assert!((0.05..5.0).contains(&lengthscale), "{first}");
    let explicit = irradiance(
        &app,
        json!({"method": "bmc", "samples": 32, "kernel": {"lengthscale": "auto"}}),
    )
    .await;
    // The same numbers; naming the default is another configuration, whose
    // error bars are calibrated apart (on the kept fit).
    assert_eq!(answer_and_cost(&explicit).0, answer_and_cost(&first).0);
    assert!(first["amortised_rays"].as_u64() > explicit["amortised_rays"].as_u64());

    // No family named: every family was fitted on the same values and the
    // response names the one of largest marginal likelihood.
    let summary: Value = app
        .get("/v1/scenes/cornell-box")
        .await
        .json()
        .await
        .unwrap();
    let fits = summary["fitted_kernels"].as_array().unwrap();
    let families: Vec<&str> = fits.iter().map(|f| f["kernel"].as_str().unwrap()).collect();
    assert_eq!(fits.len(), 3, "{summary}");
    for family in ["squared_exponential", "matern32", "matern52"] {
        assert!(families.contains(&family), "{summary}");
    }
    let likelihood = |f: &Value| f["log_marginal_likelihood"].as_f64().unwrap();
    let best = fits
        .iter()
        .max_by(|a, b| likelihood(a).total_cmp(&likelihood(b)))
        .unwrap();
    assert_eq!(first["kernel"], best["kernel"], "{first} {summary}");
    assert_eq!(best["lengthscale"].as_f64().unwrap(), lengthscale);
    for fit in fits {
        assert_eq!(fit["decomposition"], "split");
        assert_eq!(fit["sample_set"]["count"], 32);
        assert_eq!(fit["sample_set"]["kind"], "fibonacci_cosine");
        // ℓ and the noise ratio are inside their ranges: path-traced
        // training radiance is noisy, so the noise ratio is of order one.
        assert!(fit["noise_ratio"].as_f64().unwrap() > 0.1, "{fit}");
        assert_eq!(fit["at_bound"], false, "{fit}");
    }

    // A named family is fitted alone and used as named.
    let se = irradiance(
        &app,
        json!({"method": "bmc", "samples": 32,
               "kernel": {"kind": "squared_exponential", "lengthscale": "auto"}}),
    )
    .await;
    assert_eq!(se["kernel"], "squared_exponential");
    let se_fit = fits
        .iter()
        .find(|f| f["kernel"] == "squared_exponential")
        .unwrap();
    assert_eq!(se["lengthscale"], se_fit["lengthscale"]);

    // Posting the scene again replaces it: the new one starts without fits.
    let replaced = app
        .post_json(
            "/v1/scenes?replace=true",
            &serde_json::from_str::<Value>(CORNELL).unwrap(),
        )
        .await;
    assert_eq!(replaced.status(), StatusCode::OK);
    let summary: Value = app
        .get("/v1/scenes/cornell-box")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(summary["fitted_kernels"], json!([]));
}

#[tokio::test]
async fn bad_estimator_options_name_their_field() {
    let app = cornell_app().await;
    let cases = [
        (
            json!({"method": "qmc", "samples": 16, "sample_set": {"kind": "uniform"}}),
            "estimator.sample_set.kind",
        ),
        (
            json!({"method": "mc", "samples": 16, "kernel": {"lengthscale": 0.5}}),
            "estimator.kernel",
        ),
        (
            json!({"method": "mc", "samples": 16, "sample_set": {"kind": "fibonacci"}}),
            "estimator.sample_set",
        ),
        (
            json!({"method": "bmc", "samples": 16, "kernel": {"lengthscale": "fast"}}),
            "estimator.kernel.lengthscale",
        ),
        (
            json!({"method": "bmc", "samples": 16, "kernel": {"lengthscale": -1.0}}),
            "estimator.kernel.lengthscale",
        ),
        (
            json!({"method": "bmc", "samples": 16, "kernel": {"noise": -1.0}}),
            "estimator.kernel.noise",
        ),
        (
            json!({"method": "bmc", "samples": 16, "kernel": {"variance": 0.0}}),
            "estimator.kernel.variance",
        ),
        (
            json!({"method": "bmc", "samples": 16, "kernel": {"kind": "rbf"}}),
            "estimator.kernel.kind",
        ),
        (
            json!({"method": "bmc", "samples": 16, "sample_set": {"kind": "sobol"}}),
            "estimator.sample_set.kind",
        ),
    ];
    for (estimator, field) in cases {
        let response = app
            .post_json(
                "/v1/scenes/cornell-box/irradiance",
                &request(estimator.clone()),
            )
            .await;
        assert_eq!(
            response.status(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "{estimator}"
        );
        let (code, got) = error_of(response).await;
        assert_eq!(
            (code.as_str(), got.as_deref()),
            ("invalid_field", Some(field)),
            "{estimator}"
        );
    }
}

/// The bundled overcast scene with its map, on a fresh server.
async fn overcast_app() -> TestApp {
    overcast_app_on(None).await
}

/// [`overcast_app`] keeping its tiles in `data_dir`, if given.
async fn overcast_app_on(data_dir: Option<&std::path::Path>) -> TestApp {
    let dir = tempfile::tempdir().unwrap();
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for name in ["overcast.json", "overcast.exr"] {
        std::fs::copy(scenes.join(name), dir.path().join(name)).unwrap();
    }
    crate::common::spawn_app_in(dir, |c| {
        if let Some(data) = data_dir {
            c.cache.data_dir = data.to_owned();
        }
    })
    .await
}

/// The 200 answer of the overcast scene to `estimator` at `points`
/// (paths of 2 segments).
async fn overcast_irradiance(app: &TestApp, points: &Value, estimator: Value, seed: u64) -> Value {
    overcast_at_depth(app, points, estimator, seed, 2).await
}

async fn overcast_at_depth(
    app: &TestApp,
    points: &Value,
    estimator: Value,
    seed: u64,
    max_depth: u32,
) -> Value {
    let body =
        json!({"points": points, "estimator": estimator, "max_depth": max_depth, "seed": seed});
    let response = app.post_json("/v1/scenes/overcast/irradiance", &body).await;
    let status = response.status();
    let body = response.json::<Value>().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{body}");
    body
}

/// Under the hemisphere decomposition (the overcast scene's `auto`) the
/// records move each point's indirect part: the values less the sky each
/// direction sees directly (docs/math.md §10.7); and the direct-light twins
/// of the records move the direct part, the whole estimate of direct light
/// alone (§10.8).
#[tokio::test]
async fn the_records_prior_moves_the_indirect_part_of_a_hemisphere_estimate() {
    let data = tempfile::tempdir().unwrap();
    let app = overcast_app_on(Some(data.path())).await;
    let points = json!([
        {"position": [-1.0, 0.0, 2.0], "normal": [0, 1, 0]},
        {"position": [0.5, 0.0, 3.0], "normal": [0, 1, 0]},
        {"position": [1.5, 0.0, -1.0], "normal": [0, 1, 0]}
    ]);
    let post = |estimator: Value| overcast_irradiance(&app, &points, estimator, 5);
    // The whole 320×240 image in 64-pixel tiles.
    for ty in 0..4 {
        for tx in 0..5 {
            let response = app
                .get(&format!(
                    "/v1/scenes/overcast/tiles/{tx}/{ty}.png?preset=preview"
                ))
                .await;
            assert_eq!(response.status(), StatusCode::OK);
        }
    }
    let with = post(json!({"method": "bmc", "samples": 32, "records_prior": true})).await;
    let without = post(json!({"method": "bmc", "samples": 32, "records_prior": false})).await;
    let reference = post(json!({"method": "mc", "samples": 4096, "calibrate": false})).await;
    assert_eq!(with["decomposition"], "hemisphere", "{with}");
    // Preview records cover the first point only (draft tiles left none
    // that serve these points).
    assert_eq!(with["records_prior_points"], 1, "{with}");
    let (e, s) = (
        luminance(&with, 0, "irradiance"),
        luminance(&with, 0, "std_dev"),
    );
    // It moves the estimate; under an open sky the indirect part is a small
    // share of the error, so the error bar hardly narrows.
    assert_ne!(e, luminance(&without, 0, "irradiance"), "{with} {without}");
    let r = luminance(&reference, 0, "irradiance");
    let sigma = s.hypot(luminance(&reference, 0, "std_dev"));
    assert!(agrees(e, r, sigma, 4.0, 0.0), "{e} vs {r} ± {sigma}");
    // Points no prior covers keep the rule's estimate and error bar.
    for point in 1..3 {
        assert_eq!(with["irradiance"][point], without["irradiance"][point]);
        assert_eq!(with["std_dev"][point], without["std_dev"][point]);
    }
    assert_eq!(with["direct_records_points"], 1, "{with}");
    assert!(without.get("direct_records_points").is_none(), "{without}");
    // Each prior's variance is scaled by a factor fitted with the
    // calibration (docs/math.md §10.9), reported beside it.
    for prior in ["records", "direct"] {
        let scale = with["calibration"]["prior_scales"][prior].as_f64();
        assert!(scale.is_some_and(|s| s > 0.0), "{with}");
    }
    assert!(
        without["calibration"].get("prior_scales").is_none(),
        "{without}"
    );

    // Direct light only: no indirect part, and the twins carry the sky the
    // first point sees past the occluders, which its 32 directions sample
    // only coarsely.
    let sky = |estimator: Value| overcast_at_depth(&app, &points, estimator, 5, 1);
    let with = sky(json!({"method": "bmc", "samples": 32, "records_prior": true})).await;
    let without = sky(json!({"method": "bmc", "samples": 32, "records_prior": false})).await;
    let reference = sky(json!({"method": "mc", "samples": 4096, "calibrate": false})).await;
    assert_eq!(with["records_prior_points"], 0, "{with}");
    assert_eq!(with["direct_records_points"], 1, "{with}");
    let (e, s) = (
        luminance(&with, 0, "irradiance"),
        luminance(&with, 0, "std_dev"),
    );
    assert_ne!(e, luminance(&without, 0, "irradiance"), "{with} {without}");
    assert!(s < luminance(&without, 0, "std_dev"), "{with} {without}");
    let r = luminance(&reference, 0, "irradiance");
    let sigma = s.hypot(luminance(&reference, 0, "std_dev"));
    assert!(agrees(e, r, sigma, 4.0, 0.0), "{e} vs {r} ± {sigma}");
    for point in 1..3 {
        assert_eq!(with["irradiance"][point], without["irradiance"][point]);
    }

    // By default `bmc` leans on the records (`"auto"`), and says which
    // served each point: the content-keyed ones (here the reproducible
    // tiles'; a query of 3 points places none of its own).
    let default =
        overcast_irradiance(&app, &points, json!({"method": "bmc", "samples": 32}), 5).await;
    let asked = overcast_irradiance(
        &app,
        &points,
        json!({"method": "bmc", "samples": 32, "records_prior": true}),
        5,
    )
    .await;
    assert_eq!(default["irradiance"], asked["irradiance"], "{default}");
    assert_eq!(default["prior_used"][0]["indirect"], "records", "{default}");
    assert_eq!(default["prior_used"][0]["direct"], "records", "{default}");
    assert_eq!(default["prior_used"][1], json!({}), "{default}");
    // `qmc` stays plain unless asked.
    let qmc = overcast_irradiance(&app, &points, json!({"method": "qmc", "samples": 32}), 5).await;
    assert!(qmc.get("prior_used").is_none(), "{qmc}");

    // The same records give the same numbers, bit for bit, on another
    // replica (here: one that imported them) and after a restart.
    async fn answer(app: &TestApp, points: &Value) -> [Value; 3] {
        let body =
            overcast_irradiance(app, points, json!({"method": "bmc", "samples": 32}), 5).await;
        ["irradiance", "std_dev", "prior_used"].map(|field| body[field].clone())
    }
    let here = answer(&app, &points).await;
    let export = app
        .get("/v1/scenes/overcast/records")
        .await
        .bytes()
        .await
        .unwrap();
    let replica = overcast_app().await;
    let imported = replica
        .client
        .post(replica.url("/v1/scenes/overcast/records"))
        .header("content-type", "application/vnd.bmc-records")
        .body(export.to_vec())
        .send()
        .await
        .unwrap();
    assert_eq!(imported.status(), StatusCode::OK);
    assert_eq!(answer(&replica, &points).await, here);
    drop(app);
    let restarted = overcast_app_on(Some(data.path())).await;
    assert_eq!(answer(&restarted, &points).await, here);
}

/// A query of many points places records among them (docs/math.md
/// §10.11): each point is served by records, their rays are counted as
/// work kept for later, a repeat costs none of it and gives the same
/// numbers, and the estimates agree with a reference within their bars; a
/// query of few points places none.
#[tokio::test]
async fn a_query_of_many_points_places_records_among_them() {
    let app = overcast_app().await;
    let grid: Vec<Value> = (0..64)
        .map(|i| {
            let (x, z) = (f64::from(i % 8), f64::from(i / 8));
            json!({"position": [-2.0 + 0.5 * x, 0.0, 1.0 + 0.3 * z], "normal": [0, 1, 0]})
        })
        .collect();
    let few = json!(grid[..3]);
    let grid = json!(grid);
    let bmc = json!({"method": "bmc", "samples": 16});
    let sparse = overcast_irradiance(&app, &few, bmc.clone(), 5).await;
    assert_eq!(sparse["prior_used"], json!([{}, {}, {}]), "{sparse}");

    let first = overcast_irradiance(&app, &grid, bmc.clone(), 5).await;
    assert_eq!(first["records_prior_points"], 64, "{first}");
    // The twins cover every point too; the conflict test (§10.8) leaves to
    // its own samples a point whose direct part and twins disagree beyond
    // three standard deviations, which near a record's own place, where the
    // twins' prior is narrowest, happens to a few.
    let combined = first["direct_records_points"].as_u64().unwrap();
    assert!((56..=64).contains(&combined), "{first}");
    for used in first["prior_used"].as_array().unwrap() {
        assert_eq!(used["indirect"], "records", "{used}");
    }
    let again = overcast_irradiance(&app, &grid, bmc, 5).await;
    assert!(first["amortised_rays"].as_u64().unwrap() > 0, "{first}");
    assert_eq!(again["amortised_rays"], 0, "{again}");
    assert_eq!(again["irradiance"], first["irradiance"]);
    assert_eq!(again["std_dev"], first["std_dev"]);
    let reference = overcast_irradiance(
        &app,
        &grid,
        json!({"method": "mc", "samples": 4096, "calibrate": false}),
        6,
    )
    .await;
    let within = (0..64)
        .filter(|&i| {
            let (e, s) = (
                luminance(&first, i, "irradiance"),
                luminance(&first, i, "std_dev"),
            );
            let sigma = s.hypot(luminance(&reference, i, "std_dev"));
            agrees(e, luminance(&reference, i, "irradiance"), sigma, 3.0, 0.0)
        })
        .count();
    assert!(within >= 60, "{within} of 64 within 3σ");
}

#[tokio::test]
async fn auto_decomposition_prior_and_calibration_are_reported() {
    let app = overcast_app().await;
    let point = json!([{"position": [2.5, 0.0, 1.5], "normal": [0, 1, 0]}]);
    let post = |estimator: Value| overcast_irradiance(&app, &point, estimator, 3);
    // A scene lit only by a smooth sky: `auto` integrates it through the
    // hemisphere, BMC with the environment prior and calibrated error bars.
    let bmc = post(json!({"method": "bmc", "samples": 32})).await;
    assert_eq!(bmc["decomposition"], "hemisphere", "{bmc}");
    assert_eq!(bmc["prior"], "environment");
    assert!(bmc["calibration"]["scale"].as_f64().unwrap() > 0.0, "{bmc}");
    // Plain MC and QMC: no prior. MC's error bars are calibrated too, with
    // the term for light that all 32 samples missed (docs/math.md §10.5);
    // `"calibrate": false` returns its own sample variance of the mean.
    let mc = post(json!({"method": "mc", "samples": 32})).await;
    assert_eq!(mc["prior"], "none");
    let unseen = mc["calibration"]["unseen"].as_f64().unwrap();
    assert!(
        (unseen - (0.75f64 / (33.0 * 34.0)).sqrt()).abs() < 1e-12,
        "{mc}"
    );
    let mc_model = post(json!({"method": "mc", "samples": 32, "calibrate": false})).await;
    assert!(mc_model.get("calibration").is_none(), "{mc_model}");
    assert_eq!(
        mc_model["irradiance"], mc["irradiance"],
        "only the error bars differ"
    );
    assert!(bmc["calibration"].get("unseen").is_none(), "{bmc}");
    let qmc_cv = post(json!({"method": "qmc", "samples": 32, "prior": "environment"})).await;
    assert_eq!(qmc_cv["prior"], "environment");
    // Split named explicitly: the prior does not apply to indirect light.
    let split = post(json!({"method": "bmc", "samples": 32, "decomposition": "split"})).await;
    assert_eq!(split["decomposition"], "split");
    assert_eq!(split["prior"], "none");
    // The estimates agree within their error bars.
    let reference = post(json!({"method": "mc", "samples": 4096, "calibrate": false})).await;
    for body in [&bmc, &mc, &qmc_cv, &split] {
        let (e, r) = (
            luminance(body, 0, "irradiance"),
            luminance(&reference, 0, "irradiance"),
        );
        let s = luminance(body, 0, "std_dev").hypot(luminance(&reference, 0, "std_dev"));
        assert!((e - r).abs() <= 4.0 * s, "{e} vs {r} ± {s}: {body}");
    }
}

#[tokio::test]
async fn error_targets_add_batches_until_met_or_capped() {
    let app = cornell_app().await;
    let ask = |target: Value| {
        let mut body = request(json!({"method": "qmc", "samples": 32}));
        body["target"] = target;
        let app = &app;
        async move {
            app.post_json("/v1/scenes/cornell-box/irradiance", &body)
                .await
        }
    };
    let response = ask(json!({"relative_error": 0.05, "max_samples": 2048})).await;
    assert_eq!(response.status(), StatusCode::OK);
    let body: Value = response.json().await.unwrap();
    for i in 0..2 {
        let samples = body["samples"][i].as_u64().unwrap();
        let reached = body["relative_error"][i].as_f64().unwrap();
        let met = body["target_met"][i].as_bool().unwrap();
        assert!(
            samples.is_multiple_of(32) && (32..=2048).contains(&samples),
            "{body}"
        );
        // Met exactly when the reported error is within the target; a point
        // stops early only when met.
        assert_eq!(met, reached <= 0.05, "{body}");
        assert!(met || samples == 2048, "{body}");
        // The reported error is 1.96 σ of the luminance over the estimate.
        let (e, s) = (
            luminance(&body, i, "irradiance"),
            luminance(&body, i, "std_dev"),
        );
        assert!(
            (1.959_964 * s / e - reached).abs() < 1e-3 * reached.max(1e-3),
            "{body}"
        );
    }
    assert!(
        body["samples"][0].as_u64().unwrap() > 32,
        "one batch is not enough: {body}"
    );
    // A cap of one batch: one batch, and not met.
    let capped: Value = ask(json!({"relative_error": 0.001, "max_samples": 32}))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(capped["samples"][0], 32);
    assert_eq!(capped["target_met"][0], false);
    // BMC (its default `records_prior` included) takes a target: batches of
    // its 32 set directions and 32 fresh ones for the residual correction,
    // whose mean meets the records prior (none cover these two points), and
    // an answer within its error bar of a reference.
    let mut body = request(json!({"method": "bmc", "samples": 32}));
    body["target"] = json!({"relative_error": 0.05, "max_samples": 4096});
    let response = app
        .post_json("/v1/scenes/cornell-box/irradiance", &body)
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    let bmc: Value = response.json().await.unwrap();
    assert_eq!(bmc["records_prior_points"], 0, "{bmc}");
    let reference: Value = app
        .post_json(
            "/v1/scenes/cornell-box/irradiance",
            &request(json!({"method": "mc", "samples": 4096, "calibrate": false})),
        )
        .await
        .json()
        .await
        .unwrap();
    for i in 0..2 {
        let samples = bmc["samples"][i].as_u64().unwrap();
        let met = bmc["target_met"][i].as_bool().unwrap();
        assert!(
            samples.is_multiple_of(64) && (64..=4096).contains(&samples),
            "{bmc}"
        );
        assert_eq!(
            met,
            bmc["relative_error"][i].as_f64().unwrap() <= 0.05,
            "{bmc}"
        );
        assert!(met || samples == 4096, "{bmc}");
        let (e, r) = (
            luminance(&bmc, i, "irradiance"),
            luminance(&reference, i, "irradiance"),
        );
        let s = luminance(&bmc, i, "std_dev").hypot(luminance(&reference, i, "std_dev"));
        assert!((e - r).abs() <= 4.0 * s, "{e} vs {r} ± {s}: {bmc}");
    }
    // A cap below one such batch names the field.
    body["target"] = json!({"relative_error": 0.05, "max_samples": 48});
    let response = app
        .post_json("/v1/scenes/cornell-box/irradiance", &body)
        .await;
    assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(
        error_of(response).await.1.as_deref(),
        Some("target.max_samples")
    );
    // Bad targets name their field.
    for (target, field) in [
        (json!({"relative_error": 0.0}), "target.relative_error"),
        (
            json!({"relative_error": 0.1, "confidence": 1.0}),
            "target.confidence",
        ),
        (
            json!({"relative_error": 0.1, "max_samples": 16}),
            "target.max_samples",
        ),
        (
            json!({"relative_error": 0.1, "max_samples": 1_000_000}),
            "target.max_samples",
        ),
    ] {
        let response = ask(target).await;
        assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY);
        let (_, got) = error_of(response).await;
        assert_eq!(got.as_deref(), Some(field));
    }
}

#[tokio::test]
async fn the_records_prior_uses_records_that_rendered_tiles_left() {
    let app = cornell_app().await;
    let with_records = json!({"method": "bmc", "samples": 32, "records_prior": true});
    let plain = json!({"method": "bmc", "samples": 32, "records_prior": false});
    // No records yet: the plain estimator's numbers, and it says so.
    let before = irradiance(&app, with_records.clone()).await;
    assert_eq!(before["records_prior_points"], 0, "{before}");
    let without = irradiance(&app, plain.clone()).await;
    assert_eq!(before["irradiance"], without["irradiance"]);
    assert_eq!(before["std_dev"], without["std_dev"]);
    assert!(without.get("records_prior_points").is_none(), "{without}");

    // A person looks at the image: the draft tiles (paths of 64 segments
    // from the camera, so 63 from the records) leave records in the cache.
    for ty in 0..4 {
        for tx in 0..4 {
            let response = app
                .get(&format!(
                    "/v1/scenes/cornell-box/tiles/{tx}/{ty}.png?preset=draft"
                ))
                .await;
            assert_eq!(response.status(), StatusCode::OK);
        }
    }
    // At the scene's usual depth (the records' paths go on to 63 segments,
    // where the rest is negligible and within their calibration).
    let at_depth = |estimator: &Value, max_depth: u32| {
        let mut body = request(estimator.clone());
        body["max_depth"] = json!(max_depth);
        body
    };
    let after = post_irradiance(&app, &at_depth(&with_records, 16)).await;
    assert_eq!(after["records_prior_points"], 2, "{after}");
    // Split mode light-samples the direct part, and so do the records'
    // twins (docs/math.md §10.8).
    assert_eq!(after["direct_records_points"], 2, "{after}");
    let without = post_irradiance(&app, &at_depth(&plain, 16)).await;
    let mc = json!({"method": "mc", "samples": 4096});
    let reference = post_irradiance(&app, &at_depth(&mc, 16)).await;
    for point in 0..2 {
        let (e, s) = (
            luminance(&after, point, "irradiance"),
            luminance(&after, point, "std_dev"),
        );
        // The records carry information the 32 samples lack: a smaller
        // posterior standard deviation, which still covers the reference.
        assert!(
            s < luminance(&without, point, "std_dev"),
            "{after} {without}"
        );
        let r = luminance(&reference, point, "irradiance");
        let sigma = s.hypot(luminance(&reference, point, "std_dev"));
        assert!(agrees(e, r, sigma, 4.0, 0.0), "{e} vs {r} ± {sigma}");
    }

    // Deeper paths than any record holds: no prior.
    let deep = at_depth(&with_records, 65);
    let body = post_irradiance(&app, &deep).await;
    assert_eq!(body["records_prior_points"], 0, "{body}");

    // Direct light only: there is no indirect part for the records to move,
    // but their light-sampled twins serve the direct part (§10.8), which
    // they narrow.
    let direct_only = |records_prior: bool| {
        let mut body = request(
            json!({"method": "bmc", "samples": 32, "records_prior": records_prior, "calibrate": false}),
        );
        body["max_depth"] = json!(1);
        body
    };
    let direct = post_irradiance(&app, &direct_only(true)).await;
    assert_eq!(direct["records_prior_points"], 0, "{direct}");
    assert_eq!(direct["direct_records_points"], 2, "{direct}");
    let plain = post_irradiance(&app, &direct_only(false)).await;
    assert_ne!(direct["irradiance"], plain["irradiance"]);
    for point in 0..2 {
        let (with, without) = (
            luminance(&direct, point, "std_dev"),
            luminance(&plain, point, "std_dev"),
        );
        assert!(with < without, "{direct} {plain}");
    }

    // Plain MC stays plain.
    let response = app
        .post_json(
            "/v1/scenes/cornell-box/irradiance",
            &request(json!({"method": "mc", "samples": 32, "records_prior": true})),
        )
        .await;
    assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(
        error_of(response).await.1.as_deref(),
        Some("estimator.records_prior")
    );
    // A target with the prior: the batches' mean meets the records and
    // their twins once (docs/math.md §10.6), and the answer still covers
    // the reference.
    let reference = irradiance(&app, mc).await;
    let mut targeted = request(json!({"method": "qmc", "samples": 32, "records_prior": true}));
    targeted["target"] = json!({"relative_error": 0.05});
    let body = post_irradiance(&app, &targeted).await;
    assert_eq!(body["records_prior_points"], 2, "{body}");
    assert_eq!(body["direct_records_points"], 2, "{body}");
    for point in 0..2 {
        let met = body["target_met"][point].as_bool().unwrap();
        assert_eq!(
            met,
            body["relative_error"][point].as_f64().unwrap() <= 0.05,
            "{body}"
        );
        let e = luminance(&body, point, "irradiance");
        let r = luminance(&reference, point, "irradiance");
        let sigma =
            luminance(&body, point, "std_dev").hypot(luminance(&reference, point, "std_dev"));
        assert!(agrees(e, r, sigma, 4.0, 0.0), "{e} vs {r} ± {sigma}");
    }
}

//! What one client must not be able to do to the service: keep workers busy
//! past its deadline, hold connections open, grow memory through labels or
//! keys it chooses, wedge the pool unseen, or change state without the token.
//! Each test ends by showing the service healthy with its scenes.

use std::time::{Duration, Instant};

use crate::common::{TINY_SCENE, error_of, spawn_app_with_scenes, test_config};
use bmc_irradiance::service::{Application, Config};
use reqwest::{Method, StatusCode};
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const CORNELL: &str = include_str!("../../scenes/cornell-box.json");

/// Irradiance at `n` points on the Cornell box's floor with 4096 samples
/// each: minutes of work on two cores.
fn slow_irradiance(n: usize) -> Value {
    let points: Vec<Value> = (0..n)
        .map(|i| {
            let x = -0.9 + 1.8 * (i as f64 / n as f64);
            json!({"position": [x, -0.999, 0.1], "normal": [0, 1, 0]})
        })
        .collect();
    json!({"points": points, "estimator": {"method": "mc", "samples": 4096}, "max_depth": 16})
}

/// Polls `/health` until no CPU job runs; the time it took.
async fn until_idle(app: &crate::common::TestApp) -> Duration {
    let start = Instant::now();
    loop {
        let body = app.health().await;
        if body["cpu"]["running"] == 0 && body["cpu"]["queued"] == 0 {
            return start.elapsed();
        }
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "still busy: {body}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test]
async fn work_stops_when_its_deadline_passes_or_its_client_leaves() {
    let app = spawn_app_with_scenes(&[("cornell-box.json", CORNELL)], |c| {
        c.limits.request_deadline_secs = 2;
    })
    .await;
    let body = slow_irradiance(2000);

    // Deadline: 504, then the workers are free again within a second.
    let response = app
        .post_json("/v1/scenes/cornell-box/irradiance", &body)
        .await;
    assert_eq!(response.status(), StatusCode::GATEWAY_TIMEOUT);
    assert_eq!(error_of(response).await.0, "deadline_exceeded");
    let idle = until_idle(&app).await;
    assert!(idle < Duration::from_secs(1), "idle after {idle:?}");

    // Disconnect: the client gives up after half a second.
    let gone = app
        .client
        .post(app.url("/v1/scenes/cornell-box/irradiance"))
        .json(&body)
        .timeout(Duration::from_millis(500))
        .send()
        .await;
    assert!(gone.unwrap_err().is_timeout());
    let idle = until_idle(&app).await;
    assert!(idle < Duration::from_secs(1), "idle after {idle:?}");

    // And it still answers real work.
    let small = json!({"points": [{"position": [0, -0.999, 0], "normal": [0, 1, 0]}],
                       "estimator": {"method": "mc", "samples": 16}});
    let response = app
        .post_json("/v1/scenes/cornell-box/irradiance", &small)
        .await;
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(app.health().await["scenes"], 1);
}

/// Reads from `stream` until the server closes it; false if it stays open for `wait`.
async fn closed_within(stream: &mut TcpStream, wait: Duration) -> bool {
    let mut buf = [0u8; 1024];
    let read = tokio::time::timeout(wait, async {
        loop {
            match stream.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(_) => {}
            }
        }
    });
    read.await.is_ok()
}

#[tokio::test]
async fn silent_and_half_sent_connections_are_closed_and_capped() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |c| {
        c.server.header_read_timeout_secs = 1;
        c.server.max_connections = 8;
    })
    .await;
    let addr = app.base.trim_start_matches("http://").to_owned();
    let mut silent = Vec::new();
    for _ in 0..20 {
        silent.push(TcpStream::connect(&addr).await.unwrap());
    }
    let mut half = TcpStream::connect(&addr).await.unwrap();
    half.write_all(b"GET /health HTTP/1.1\r\nHost: x\r\nX-Slow: ")
        .await
        .unwrap();
    // Every one of them is closed: beyond the cap at once, the others
    // when the header-read timeout passes.
    for stream in silent.iter_mut().chain(std::iter::once(&mut half)) {
        assert!(closed_within(stream, Duration::from_secs(5)).await);
    }
    // A kept-alive connection that goes quiet after a request is closed too.
    let mut idle = TcpStream::connect(&addr).await.unwrap();
    idle.write_all(b"GET /health HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    assert!(closed_within(&mut idle, Duration::from_secs(5)).await);

    assert_eq!(app.health().await["scenes"], 1);
    let metrics = app.get("/metrics").await.text().await.unwrap();
    assert!(
        metrics.contains("http_connections_refused_total"),
        "{metrics}"
    );
}

#[tokio::test]
async fn shutdown_ends_within_its_window_despite_a_stalled_connection() {
    let dir = tempfile::tempdir().unwrap();
    let config = test_config(&dir, |c: &mut Config| {
        c.server.header_read_timeout_secs = 3600;
        c.server.shutdown_grace_secs = 1;
    });
    let app = Application::build(config).await.unwrap();
    let addr = app.local_addr();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(app.run_until_stopped(async {
        let _ = stopped.await;
    }));
    let mut stalled = TcpStream::connect(addr).await.unwrap();
    stalled
        .write_all(b"GET /health HTTP/1.1\r\nHost: x\r\nX-Half: ")
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    stop.send(()).unwrap();
    let ended = tokio::time::timeout(Duration::from_secs(10), server).await;
    assert!(ended.is_ok(), "shutdown did not end");
    ended.unwrap().unwrap().unwrap();
}

#[tokio::test]
async fn made_up_methods_do_not_grow_the_metrics() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    // One made-up method first, so its `other` series exists before the flood.
    let first = Method::from_bytes(b"PROBE").unwrap();
    let _ = app.client.request(first, app.url("/health")).send().await;
    let before = app.get("/metrics").await.text().await.unwrap().len();
    for i in 0..300 {
        let method = Method::from_bytes(format!("M{i:04}{}", "X".repeat(1000)).as_bytes()).unwrap();
        let response = app
            .client
            .request(method, app.url("/health"))
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);
    }
    let metrics = app.get("/metrics").await.text().await.unwrap();
    assert!(!metrics.contains("M0001"), "a method name became a label");
    assert!(metrics.contains(r#"method="other""#));
    // 300 KB of method names later, the exposition has barely grown (the
    // recorder is process-wide, so other tests' series may come and go).
    assert!(
        metrics.len() < before + 16 * 1024,
        "{before} → {} bytes",
        metrics.len()
    );
    assert_eq!(app.health().await["scenes"], 1);
}

#[tokio::test]
async fn oversized_request_heads_get_json_errors() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let long_path = format!("/v1/scenes/{}", "a".repeat(9 * 1024));
    let response = app.get(&long_path).await;
    assert_eq!(response.status(), StatusCode::URI_TOO_LONG);
    assert_eq!(error_of(response).await.0, "uri_too_long");

    let response = app
        .client
        .get(app.url("/health"))
        .header("x-padding", "p".repeat(40 * 1024))
        .send()
        .await
        .unwrap();
    assert_eq!(
        response.status(),
        StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE
    );
    assert_eq!(error_of(response).await.0, "headers_too_large");
    assert_eq!(app.health().await["scenes"], 1);
}

#[tokio::test]
async fn mutating_routes_need_the_configured_token() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |c| {
        c.server.auth_token = "s3cret".into();
    })
    .await;
    let mut doc: Value = serde_json::from_str(TINY_SCENE).unwrap();
    doc["name"] = json!("other");
    let attempts = [
        (Method::POST, "/v1/scenes", Some(&doc)),
        (Method::DELETE, "/v1/scenes/tiny", None),
        (Method::DELETE, "/v1/scenes/tiny/cache", None),
    ];
    for (method, path, body) in &attempts {
        for token in [
            None,
            Some("Bearer wrong"),
            Some("s3cret"),
            Some("Basic s3cret"),
        ] {
            let mut request = app.client.request(method.clone(), app.url(path));
            if let Some(token) = token {
                request = request.header("authorization", token);
            }
            if let Some(body) = body {
                request = request.json(body);
            }
            let response = request.send().await.unwrap();
            assert_eq!(
                response.status(),
                StatusCode::UNAUTHORIZED,
                "{method} {path}"
            );
            assert_eq!(response.headers()["www-authenticate"], "Bearer");
            assert_eq!(error_of(response).await.0, "unauthorized");
        }
    }
    // Nothing changed; reads and queries need no token.
    assert_eq!(app.health().await["scenes"], 1);
    let query = json!({"points": [{"position": [0, 0, 0], "normal": [0, 0, 1]}],
                       "estimator": {"method": "mc", "samples": 4}});
    let response = app.post_json("/v1/scenes/tiny/irradiance", &query).await;
    assert_eq!(response.status(), StatusCode::OK);
    // With the token, they work (the scheme's name in any case, RFC 9110 §11.1).
    let response = app
        .client
        .post(app.url("/v1/scenes"))
        .header("authorization", "bearer s3cret")
        .json(&doc)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::CREATED);
    let response = app
        .client
        .delete(app.url("/v1/scenes/other"))
        .bearer_auth("s3cret")
        .send()
        .await
        .unwrap();
    assert!(response.status().is_success());
    assert_eq!(app.health().await["scenes"], 1);
}

/// The queries: POST routes that compute and change nothing a client can
/// name, open to every caller. Any other route with a method that may
/// change state must sit under the guard, so a route added without it
/// fails here.
const QUERIES: [&str; 4] = [
    "POST /v1/scenes/{id}/irradiance",
    "POST /v1/scenes/{id}/tiles",
    "POST /v1/scenes/{id}/radiance",
    "POST /v1/quadratures",
];

#[tokio::test]
async fn every_route_with_a_mutating_method_refuses_a_missing_token() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |c| {
        c.server.auth_token = "s3cret".into();
    })
    .await;
    let doc: Value = app.get("/openapi.json").await.json().await.unwrap();
    let mut guarded = Vec::new();
    for (path, operations) in doc["paths"].as_object().expect("paths") {
        for method in ["post", "put", "patch", "delete"] {
            if operations.get(method).is_none() {
                continue;
            }
            let route = format!("{} {path}", method.to_uppercase());
            if QUERIES.contains(&route.as_str()) {
                continue;
            }
            let concrete = path.replace("{id}", "tiny");
            let method = Method::from_bytes(method.to_uppercase().as_bytes()).unwrap();
            let response = app
                .client
                .request(method, app.url(&concrete))
                .json(&json!({}))
                .send()
                .await
                .unwrap();
            assert_eq!(response.status(), StatusCode::UNAUTHORIZED, "{route}");
            assert_eq!(error_of(response).await.0, "unauthorized", "{route}");
            guarded.push(route);
        }
    }
    guarded.sort();
    assert_eq!(
        guarded,
        [
            "DELETE /v1/scenes/{id}",
            "DELETE /v1/scenes/{id}/cache",
            "POST /v1/scenes",
            "POST /v1/scenes/{id}/records",
        ]
    );
    assert_eq!(app.health().await["scenes"], 1);
}

/// Pages of other sites cannot change state, token or not: browsers send a
/// multipart or `text/plain` POST cross-site without a preflight. Pages of
/// the service's own origin and of `server.allowed_origins` can; clients
/// that are not browsers send no `Origin` and are unaffected.
#[tokio::test]
async fn pages_of_other_origins_cannot_change_state() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |c| {
        c.server.allowed_origins = "https://app.example, http://localhost:5173/".into();
    })
    .await;
    let mut doc: Value = serde_json::from_str(TINY_SCENE).unwrap();
    doc["name"] = json!("other");
    let boundary = "x-boundary";
    let multipart = format!(
        "--{boundary}\r\ncontent-disposition: form-data; name=\"scene\"; filename=\"scene.json\"\r\ncontent-type: application/json\r\n\r\n{doc}\r\n--{boundary}--\r\n"
    );
    let forged = |method: Method, path: &str| app.client.request(method, app.url(path));
    let attempts = [
        forged(Method::POST, "/v1/scenes")
            .header(
                "content-type",
                format!("multipart/form-data; boundary={boundary}"),
            )
            .body(multipart.clone()),
        forged(Method::POST, "/v1/scenes/tiny/records")
            .header("content-type", "text/plain")
            .body("BMCR"),
        forged(Method::DELETE, "/v1/scenes/tiny"),
        forged(Method::DELETE, "/v1/scenes/tiny/cache"),
    ];
    for attempt in attempts {
        for (name, value) in [
            ("origin", "https://evil.example"),
            ("origin", "null"),
            ("origin", "https://app.example.evil.example"),
            ("sec-fetch-site", "cross-site"),
        ] {
            let response = attempt
                .try_clone()
                .unwrap()
                .header(name, value)
                .send()
                .await
                .unwrap();
            assert_eq!(response.status(), StatusCode::FORBIDDEN, "{name}: {value}");
            let (code, field) = error_of(response).await;
            assert_eq!(code, "cross_origin");
            assert_eq!(field.as_deref(), Some("Origin"));
        }
    }
    assert_eq!(app.health().await["scenes"], 1);
    // Reads and queries from any page still work.
    let query = json!({"points": [{"position": [0, 0, 0], "normal": [0, 0, 1]}],
                       "estimator": {"method": "mc", "samples": 4}});
    let response = app
        .client
        .post(app.url("/v1/scenes/tiny/irradiance"))
        .header("origin", "https://evil.example")
        .json(&query)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    // The service's own pages, the allowed origins and plain clients may.
    let own = app.base.clone();
    for origin in [
        Some(own.as_str()),
        Some("http://localhost:5173"),
        Some("https://app.example"),
        None,
    ] {
        let mut post = app
            .client
            .post(app.url("/v1/scenes"))
            .header(
                "content-type",
                format!("multipart/form-data; boundary={boundary}"),
            )
            .body(multipart.clone());
        let mut delete = app.client.delete(app.url("/v1/scenes/other"));
        if let Some(origin) = origin {
            post = post.header("origin", origin);
            delete = delete.header("origin", origin);
        }
        let response = post.send().await.unwrap();
        assert_eq!(response.status(), StatusCode::CREATED, "{origin:?}");
        assert!(
            delete.send().await.unwrap().status().is_success(),
            "{origin:?}"
        );
    }
    assert_eq!(app.health().await["scenes"], 1);
}

#[tokio::test]
async fn a_job_stuck_past_its_deadlines_makes_health_fail() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.json"), TINY_SCENE).unwrap();
    let config = test_config(&dir, |c: &mut Config| c.limits.request_deadline_secs = 1);
    let app = Application::build(config).await.unwrap();
    let base = format!("http://{}", app.local_addr());
    let pool = app.state().pool.clone();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    tokio::spawn(app.run_until_stopped(async {
        let _ = stopped.await;
    }));
    // A job that ignores its cancel flag (as a bug would) for 3 s.
    let stuck = tokio::spawn(async move {
        pool.run(|_| std::thread::sleep(Duration::from_secs(3)))
            .await
    });
    let client = reqwest::Client::new();
    let status = |path: &'static str| {
        let (client, base) = (client.clone(), base.clone());
        async move {
            let response = client.get(format!("{base}{path}")).send().await.unwrap();
            let code = response.status();
            let body: Value = response.json().await.unwrap();
            (code, body)
        }
    };
    let (code, body) = status("/health").await;
    assert_eq!(
        (code, body["status"].as_str()),
        (StatusCode::OK, Some("ok"))
    );
    assert_eq!(body["cpu"]["running"], 1);
    // Two deadlines later the job counts as stuck.
    tokio::time::sleep(Duration::from_millis(2300)).await;
    for path in ["/health", "/ready"] {
        let (code, body) = status(path).await;
        assert_eq!(code, StatusCode::SERVICE_UNAVAILABLE, "{path}");
        assert_eq!(body["status"], "wedged", "{path}");
        assert!(body["cpu"]["oldest_job_secs"].as_f64().unwrap() > 2.0);
    }
    stuck.await.unwrap().unwrap();
    let (code, body) = status("/health").await;
    assert_eq!(
        (code, body["status"].as_str()),
        (StatusCode::OK, Some("ok"))
    );
    let _ = stop.send(());
}

#[tokio::test]
async fn fits_for_seeds_a_fibonacci_set_ignores_are_kept_once() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    for seed in 1..=3 {
        let body = json!({
            "points": [{"position": [0, 0, 0], "normal": [0, 0, 1]}],
            "estimator": {"method": "bmc", "samples": 16,
                          "sample_set": {"kind": "fibonacci_cosine", "seed": seed},
                          "kernel": {"kind": "squared_exponential", "lengthscale": "auto"}},
        });
        let response = app.post_json("/v1/scenes/tiny/irradiance", &body).await;
        assert_eq!(response.status(), StatusCode::OK);
    }
    let scene: Value = app.get("/v1/scenes/tiny").await.json().await.unwrap();
    assert_eq!(
        scene["fitted_kernels"].as_array().unwrap().len(),
        1,
        "{scene}"
    );
}

#[tokio::test]
async fn cache_stats_count_the_bytes_of_the_records_rule() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let tile = json!({"x": 0, "y": 0, "width": 8, "height": 8, "format": "json",
                      "estimator": {"method": "cache", "samples": 64}});
    let response = app.post_json("/v1/scenes/tiny/tiles", &tile).await;
    assert_eq!(response.status(), StatusCode::OK);
    let stats: Value = app.get("/v1/scenes/tiny/cache").await.json().await.unwrap();
    let rule_bytes = stats["caches"][0]["rule_bytes"].as_u64().unwrap_or(0);
    // The factor alone is 64² doubles.
    assert!(rule_bytes >= 64 * 64 * 8, "{stats}");
}

/// Sends `head` and then `body` in `chunks` parts, `pause` apart, over a
/// raw connection; the status of the answer (0 when none came).
async fn send_slowly(addr: &str, head: String, body: &[u8], chunks: usize, pause: Duration) -> u16 {
    let mut stream = TcpStream::connect(addr).await.unwrap();
    stream.write_all(head.as_bytes()).await.unwrap();
    for part in body.chunks(body.len().div_ceil(chunks)) {
        tokio::time::sleep(pause).await;
        if stream.write_all(part).await.is_err() {
            break;
        }
    }
    let mut answer = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(20), stream.read_to_end(&mut answer)).await;
    let text = String::from_utf8_lossy(&answer);
    text.split_whitespace()
        .nth(1)
        .and_then(|code| code.parse().ok())
        .unwrap_or(0)
}

/// The deadline counts from the end of the body's arrival: an upload that
/// takes longer than the deadline to arrive is still served. A body that
/// stops arriving is cut off after the pause allowed, with a 4xx.
#[tokio::test]
async fn a_slow_upload_keeps_its_deadline_and_a_stalled_one_is_cut_off() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |c| {
        c.limits.request_deadline_secs = 1;
        c.server.header_read_timeout_secs = 2;
    })
    .await;
    let addr = app.base.trim_start_matches("http://").to_owned();
    let mut doc: Value = serde_json::from_str(TINY_SCENE).unwrap();
    doc["name"] = json!("slow");
    // Padded with spaces to 200 kB, sent in 5 parts over 2.5 s.
    let mut body = doc.to_string().into_bytes();
    body.resize(200_000, b' ');
    let head = |length: usize| {
        format!(
            "POST /v1/scenes HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {length}\r\nConnection: close\r\n\r\n"
        )
    };
    let status = send_slowly(
        &addr,
        head(body.len()),
        &body,
        5,
        Duration::from_millis(500),
    )
    .await;
    assert_eq!(status, 201);
    // Half the body, then nothing: cut off once the pause passes 2 s.
    let started = std::time::Instant::now();
    let half = &body[..body.len() / 2];
    let status = send_slowly(&addr, head(body.len()), half, 1, Duration::ZERO).await;
    assert!((400..500).contains(&status), "{status}");
    assert!(started.elapsed() < Duration::from_secs(10));
    assert_eq!(app.health().await["scenes"], 2);
}

/// A request hyper cannot parse (a `<` in the path) is answered by hyper
/// itself; it still carries the JSON error body, and the service goes on.
#[tokio::test]
async fn an_unparsable_request_line_gets_a_json_error() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let addr = app.base.trim_start_matches("http://").to_owned();
    for target in ["/v1/scenes/<x>", "/v1/scenes/x>y"] {
        let mut stream = TcpStream::connect(&addr).await.unwrap();
        let request = format!("GET {target} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
        stream.write_all(request.as_bytes()).await.unwrap();
        let mut answer = Vec::new();
        tokio::time::timeout(Duration::from_secs(10), stream.read_to_end(&mut answer))
            .await
            .expect("the connection was not closed")
            .unwrap();
        let answer = String::from_utf8(answer).unwrap();
        assert!(answer.starts_with("HTTP/1.1 400 "), "{target}: {answer}");
        assert!(
            answer.contains("content-type: application/json"),
            "{answer}"
        );
        let body: Value = serde_json::from_str(answer.split("\r\n\r\n").nth(1).unwrap()).unwrap();
        assert_eq!(body["error"]["code"], "malformed_request", "{body}");
    }
    assert_eq!(app.health().await["scenes"], 1);
}

//! The middleware stack on small test-only routes (the product routes are
//! exercised end to end in `tests/`).
use super::*;
use crate::service::extract::ApiJson;
use axum::body::{Body, to_bytes};
use axum::http::{Request as HttpRequest, StatusCode};
use axum::routing::{get, post};
use tower::ServiceExt;

fn limits() -> Limits {
    let mut limits = Config::default_config().limits;
    limits.max_body_bytes = 64;
    limits.request_deadline_secs = 2;
    limits
}

async fn echo(ApiJson(value): ApiJson<serde_json::Value>) -> axum::Json<serde_json::Value> {
    axum::Json(value)
}

async fn error_body(response: Response) -> (StatusCode, serde_json::Value) {
    let status = response.status();
    let bytes = to_bytes(response.into_body(), usize::MAX).await.unwrap();
    (status, serde_json::from_slice(&bytes).unwrap())
}

fn post_json(body: impl Into<Body>) -> HttpRequest<Body> {
    HttpRequest::post("/echo")
        .header("content-type", "application/json")
        .body(body.into())
        .unwrap()
}

#[tokio::test]
async fn oversized_body_is_413_with_json_error() {
    let app = with_middleware(
        Router::new().route("/echo", post(echo)),
        &limits(),
        Duration::from_secs(10),
    );
    let small = app.clone().oneshot(post_json(r#"{"a": 1}"#)).await.unwrap();
    assert_eq!(small.status(), StatusCode::OK);

    let big = format!(r#"{{"a": "{}"}}"#, "x".repeat(100));
    let (status, body) = error_body(app.oneshot(post_json(big)).await.unwrap()).await;
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(body["error"]["code"], "payload_too_large");
}

#[tokio::test]
async fn malformed_json_and_wrong_content_type_get_json_errors() {
    let app = with_middleware(
        Router::new().route("/echo", post(echo)),
        &limits(),
        Duration::from_secs(10),
    );
    let (status, body) = error_body(app.clone().oneshot(post_json("{nope")).await.unwrap()).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(body["error"]["code"], "malformed_json");
    assert!(body["error"]["field"].is_null());

    let form = HttpRequest::post("/echo")
        .header("content-type", "application/x-www-form-urlencoded")
        .body(Body::from("a=1"))
        .unwrap();
    let (status, body) = error_body(app.oneshot(form).await.unwrap()).await;
    assert_eq!(status, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    assert_eq!(body["error"]["code"], "unsupported_media_type");
}

#[tokio::test(start_paused = true)]
async fn request_past_its_deadline_is_504() {
    let slow = || async {
        tokio::time::sleep(Duration::from_secs(3600)).await;
        "done"
    };
    let app = with_middleware(
        Router::new().route("/slow", get(slow)),
        &limits(),
        Duration::from_secs(10),
    );
    let request = HttpRequest::get("/slow").body(Body::empty()).unwrap();
    let (status, body) = error_body(app.oneshot(request).await.unwrap()).await;
    assert_eq!(status, StatusCode::GATEWAY_TIMEOUT);
    assert_eq!(body["error"]["code"], "deadline_exceeded");
}

#[tokio::test]
async fn panicking_handler_is_500_with_json_error() {
    async fn boom() -> &'static str {
        panic!("handler bug")
    }
    let app = with_middleware(
        Router::new().route("/boom", get(boom)),
        &limits(),
        Duration::from_secs(10),
    );
    let request = HttpRequest::get("/boom").body(Body::empty()).unwrap();
    let (status, body) = error_body(app.oneshot(request).await.unwrap()).await;
    assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
    assert_eq!(body["error"]["code"], "internal");
}

#[tokio::test]
async fn graceful_shutdown_lets_an_in_flight_request_finish() {
    use std::sync::Mutex;
    use tokio::sync::oneshot;

    // The handler reports that it started, then waits until the test lets it finish.
    let (started_tx, started_rx) = oneshot::channel::<()>();
    let (finish_tx, finish_rx) = oneshot::channel::<()>();
    let hooks = Arc::new(Mutex::new(Some((started_tx, finish_rx))));
    let slow = move || {
        let hooks = hooks.clone();
        async move {
            let (started, finish) = hooks.lock().unwrap().take().unwrap();
            started.send(()).unwrap();
            finish.await.unwrap();
            "finished"
        }
    };
    let mut config = Config::default_config();
    config.server.bind = "127.0.0.1:0".parse().unwrap();
    let mut app = Application::build(config).await.unwrap();
    app.router = with_middleware(
        Router::new().route("/slow", get(slow)),
        &limits(),
        Duration::from_secs(10),
    );
    let url = format!("http://{}/slow", app.local_addr());

    let (stop_tx, stop_rx) = oneshot::channel::<()>();
    let server = tokio::spawn(app.run_until_stopped(async {
        let _ = stop_rx.await;
    }));
    let client = tokio::spawn(async move {
        let response = reqwest::get(&url).await.unwrap();
        (response.status(), response.text().await.unwrap())
    });
    started_rx.await.unwrap();
    stop_tx.send(()).unwrap();
    // The server must still be serving the in-flight request.
    tokio::task::yield_now().await;
    assert!(!server.is_finished());
    finish_tx.send(()).unwrap();

    let (status, text) = client.await.unwrap();
    assert_eq!(status, reqwest::StatusCode::OK);
    assert_eq!(text, "finished");
    server.await.unwrap().unwrap();
}

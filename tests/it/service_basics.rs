//! End-to-end tests of the service infrastructure routes against the real server.

use crate::common::{error_of, spawn_app};
use reqwest::StatusCode;

#[tokio::test]
async fn health_reports_ok_and_version() {
    let app = spawn_app().await;
    let response = app.get("/health").await;
    assert_eq!(response.status(), StatusCode::OK);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["status"], "ok");
    assert_eq!(body["version"], env!("CARGO_PKG_VERSION"));
}

#[tokio::test]
async fn metrics_count_requests_per_route_template() {
    let app = spawn_app().await;
    assert_eq!(app.get("/health").await.status(), StatusCode::OK);
    assert_eq!(
        app.get("/no/such/route").await.status(),
        StatusCode::NOT_FOUND
    );

    let response = app.get("/metrics").await;
    assert_eq!(response.status(), StatusCode::OK);
    assert!(
        response.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/plain")
    );
    let text = response.text().await.unwrap();
    let has_series = |name: &str, route: &str, status: &str| {
        text.lines().any(|line| {
            line.starts_with(name)
                && line.contains(&format!("route=\"{route}\""))
                && line.contains(&format!("status=\"{status}\""))
                && line.contains("method=\"GET\"")
        })
    };
    assert!(
        has_series("http_requests_total", "/health", "200"),
        "{text}"
    );
    assert!(
        has_series("http_requests_total", "unmatched", "404"),
        "{text}"
    );
    assert!(
        has_series("http_request_duration_seconds_bucket", "/health", "200"),
        "{text}"
    );
    assert!(
        !text.contains("/no/such/route"),
        "concrete paths must not become labels"
    );
}

#[tokio::test]
async fn openapi_lists_every_route() {
    let app = spawn_app().await;
    let response = app.get("/openapi.json").await;
    assert_eq!(response.status(), StatusCode::OK);
    let doc: serde_json::Value = response.json().await.unwrap();
    assert!(doc["openapi"].as_str().unwrap().starts_with("3."));
    assert_eq!(doc["info"]["title"], "bmc-irradiance");
    let paths = doc["paths"].as_object().unwrap();
    for (path, method) in [
        ("/health", "get"),
        ("/metrics", "get"),
        ("/openapi.json", "get"),
        ("/v1/scenes", "get"),
        ("/v1/scenes", "post"),
        ("/v1/scenes/{id}", "get"),
        ("/v1/scenes/{id}", "delete"),
        ("/v1/scenes/{id}/irradiance", "post"),
        ("/v1/quadratures", "post"),
        ("/v1/scenes/{id}/radiance", "post"),
        ("/v1/scenes/{id}/tiles", "post"),
        ("/v1/scenes/{id}/cache", "get"),
        ("/v1/scenes/{id}/cache", "delete"),
    ] {
        assert!(paths[path].get(method).is_some(), "{path} {method} missing");
    }
    assert!(doc["components"]["schemas"]["ErrorBody"].is_object());
}

#[tokio::test]
async fn unknown_route_is_404_json() {
    let app = spawn_app().await;
    let response = app.get("/v0/nothing").await;
    assert_eq!(response.status(), StatusCode::NOT_FOUND);
    assert_eq!(error_of(response).await, ("not_found".into(), None));
}

#[tokio::test]
async fn wrong_method_is_405_json() {
    let app = spawn_app().await;
    let response = app.client.delete(app.url("/health")).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);
    assert_eq!(
        error_of(response).await,
        ("method_not_allowed".into(), None)
    );
}

/// The viewer's files are never sniffed as another type, and its page may
/// load nothing but this service's own script, style and API.
#[tokio::test]
async fn the_viewer_is_served_with_nosniff_and_a_content_security_policy() {
    let app = spawn_app().await;
    for path in ["/", "/viewer.js", "/viewer.css"] {
        let response = app.get(path).await;
        assert_eq!(response.status(), StatusCode::OK, "{path}");
        assert_eq!(
            response.headers()["x-content-type-options"],
            "nosniff",
            "{path}"
        );
        let policy = response.headers()["content-security-policy"]
            .to_str()
            .unwrap();
        for directive in [
            "default-src 'none'",
            "script-src 'self'",
            "connect-src 'self'",
            "frame-ancestors 'none'",
        ] {
            assert!(policy.contains(directive), "{path}: {policy}");
        }
    }
}

//! The browser viewer: three static files embedded in the binary (no build
//! step, nothing fetched from elsewhere), served at `/`, `/viewer.js` and
//! `/viewer.css`. It reads only the public API: `GET /v1/scenes`,
//! `GET /v1/presets`, GET tiles and `GET /v1/scenes/{id}/cache`.

use axum::Router;
use axum::http::{HeaderValue, header};
use axum::response::IntoResponse;
use axum::routing::get;

const INDEX: &str = include_str!("index.html");
const SCRIPT: &str = include_str!("viewer.js");
const STYLE: &str = include_str!("viewer.css");

/// What the viewer's pages may load and do: only this service's own
/// script, style and API (the favicon is an empty `data:` URL), in no frame.
const CONTENT_SECURITY_POLICY: &str = "default-src 'none'; script-src 'self'; style-src 'self'; \
     img-src 'self' data:; connect-src 'self'; base-uri 'none'; form-action 'none'; \
     frame-ancestors 'none'";

/// A static file with its type, never sniffed as another, under the
/// viewer's content security policy; revalidated on every load
/// (`no-cache`), so a new release of the service is picked up at once.
fn asset(content_type: &'static str, body: &'static str) -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(content_type)),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-cache")),
            (
                header::X_CONTENT_TYPE_OPTIONS,
                HeaderValue::from_static("nosniff"),
            ),
            (
                header::CONTENT_SECURITY_POLICY,
                HeaderValue::from_static(CONTENT_SECURITY_POLICY),
            ),
        ],
        body,
    )
}

/// The viewer's routes.
pub fn routes<S: Clone + Send + Sync + 'static>() -> Router<S> {
    Router::new()
        .route(
            "/",
            get(|| async { asset("text/html; charset=utf-8", INDEX) }),
        )
        .route(
            "/viewer.js",
            get(|| async { asset("text/javascript; charset=utf-8", SCRIPT) }),
        )
        .route(
            "/viewer.css",
            get(|| async { asset("text/css; charset=utf-8", STYLE) }),
        )
}

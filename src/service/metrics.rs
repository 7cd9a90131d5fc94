//! Prometheus metrics: names, the process-wide recorder, and the per-route middleware.
//!
//! Metrics go through the `metrics` facade into one process-wide
//! `metrics-exporter-prometheus` recorder (a facade recorder can only be
//! installed once per process, so every [`Metrics`] shares it); `GET /metrics`
//! renders it as Prometheus text. Per-route statistics are labelled by the
//! matched path *template* (`/v1/scenes/{id}`, not the concrete path), method
//! and status, so label cardinality stays bounded; unmatched paths share the
//! route label `unmatched`.

use std::sync::OnceLock;
use std::time::Instant;

use axum::extract::{MatchedPath, Request};
use axum::http::Method;
use axum::middleware::Next;
use axum::response::Response;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

use crate::bmc::cache::QuadratureCache;

/// Counter: requests answered, by `method`, `route`, `status`.
pub const HTTP_REQUESTS: &str = "http_requests_total";
/// Histogram: request latency in seconds, by `method`, `route`, `status`.
pub const HTTP_DURATION: &str = "http_request_duration_seconds";
/// Counter: factorisation-cache lookups that found a cached factorisation.
pub const FACTORISATION_CACHE_HITS: &str = "bmc_factorisation_cache_hits_total";
/// Counter: factorisation-cache lookups that had to factorise.
pub const FACTORISATION_CACHE_MISSES: &str = "bmc_factorisation_cache_misses_total";
/// Gauge: bytes held by the factorisation cache.
pub const FACTORISATION_CACHE_BYTES: &str = "bmc_factorisation_cache_bytes";
/// Counter: rays traced on behalf of requests.
pub const RAYS_TRACED: &str = "rays_traced_total";
/// Gauge: CPU jobs queued or running.
pub const CPU_JOBS_IN_FLIGHT: &str = "cpu_jobs_in_flight";
/// Counter: CPU jobs refused with 503 because every slot was taken.
pub const CPU_JOBS_REJECTED: &str = "cpu_jobs_rejected_total";
/// Counter: connections closed at accept because `server.max_connections` were open.
pub const CONNECTIONS_REFUSED: &str = "http_connections_refused_total";

/// Latency buckets in seconds: from cached lookups (sub-millisecond) to tiles (seconds).
const LATENCY_BUCKETS: [f64; 14] = [
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0,
];

/// Handle to the process-wide recorder; cheap to clone.
#[derive(Clone)]
pub struct Metrics {
    handle: PrometheusHandle,
}

static RECORDER: OnceLock<Result<PrometheusHandle, String>> = OnceLock::new();

impl Metrics {
    /// Installs the process-wide recorder on first call and returns a handle to it.
    ///
    /// Fails only if some other `metrics` recorder was installed in this process first.
    pub fn install() -> Result<Metrics, String> {
        RECORDER
            .get_or_init(|| {
                let handle = PrometheusBuilder::new()
                    .set_buckets_for_metric(Matcher::Full(HTTP_DURATION.into()), &LATENCY_BUCKETS)
                    .map_err(|e| e.to_string())?
                    .install_recorder()
                    .map_err(|e| e.to_string())?;
                describe();
                Ok(handle)
            })
            .clone()
            .map(|handle| Metrics { handle })
    }

    /// Prometheus text exposition of every metric recorded so far.
    pub fn render(&self) -> String {
        self.handle.render()
    }

    /// Drains histogram samples into their buckets; called periodically so that
    /// memory stays flat even when nobody scrapes `/metrics`.
    pub fn run_upkeep(&self) {
        self.handle.run_upkeep();
    }
}

fn describe() {
    use metrics::{Unit, describe_counter, describe_gauge, describe_histogram};
    describe_counter!(HTTP_REQUESTS, "HTTP requests answered");
    describe_histogram!(HTTP_DURATION, Unit::Seconds, "HTTP request latency");
    describe_counter!(
        FACTORISATION_CACHE_HITS,
        "BMC factorisation-cache lookups served from the cache"
    );
    describe_counter!(
        FACTORISATION_CACHE_MISSES,
        "BMC factorisation-cache lookups that factorised"
    );
    describe_gauge!(
        FACTORISATION_CACHE_BYTES,
        Unit::Bytes,
        "Bytes held by the BMC factorisation cache"
    );
    describe_counter!(RAYS_TRACED, "Rays traced for requests");
    describe_gauge!(CPU_JOBS_IN_FLIGHT, "CPU jobs queued or running");
    describe_counter!(
        CPU_JOBS_REJECTED,
        "CPU jobs refused with 503 because the queue was full"
    );
    describe_counter!(
        CONNECTIONS_REFUSED,
        "Connections closed at once because server.max_connections were open"
    );
}

/// Counts one lookup of the quadrature cache: a hit when `cached` says the
/// weights came from the cache; otherwise (computed, or failed) a miss, after
/// which the cache's bytes are refreshed (they only change on inserts).
pub fn record_quadrature_lookup(quadratures: &QuadratureCache, cached: Option<bool>) {
    if cached == Some(true) {
        metrics::counter!(FACTORISATION_CACHE_HITS).increment(1);
    } else {
        metrics::counter!(FACTORISATION_CACHE_MISSES).increment(1);
        let bytes = quadratures.stats().bytes;
        metrics::gauge!(FACTORISATION_CACHE_BYTES).set(bytes as f64);
    }
}

/// The `method` label: the standard methods by name, every other one as
/// `other`. Clients choose the method string, so using it verbatim would let
/// them create label sets, and so memory in the exporter, without bound.
fn method_label(method: &Method) -> &'static str {
    match *method {
        Method::GET => "GET",
        Method::HEAD => "HEAD",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::PATCH => "PATCH",
        Method::OPTIONS => "OPTIONS",
        Method::CONNECT => "CONNECT",
        Method::TRACE => "TRACE",
        _ => "other",
    }
}

/// Middleware recording one count and one latency sample per request.
pub async fn track(request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_owned(), |p| p.as_str().to_owned());
    let method = method_label(request.method());
    let start = Instant::now();
    let response = next.run(request).await;
    let labels = [
        ("method", method.to_owned()),
        ("route", route),
        ("status", response.status().as_u16().to_string()),
    ];
    metrics::counter!(HTTP_REQUESTS, &labels).increment(1);
    metrics::histogram!(HTTP_DURATION, &labels).record(start.elapsed().as_secs_f64());
    response
}

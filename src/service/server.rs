//! The accept loop: HTTP/1.1 connections with a header-read timeout, a cap
//! on open connections and a bounded graceful shutdown.
//!
//! `axum::serve` sets none of these, so a client that opens connections and
//! sends nothing (or stops mid-header) kept them open forever: 1,100 silent
//! connections exhausted a 1,024-descriptor limit and `/health` timed out, and
//! one such connection kept SIGTERM from ever completing. Here:
//! - **Header-read timeout** (`server.header_read_timeout_secs`): hyper closes
//!   a connection whose request head is not complete in time. Its timer also
//!   runs while a kept-alive connection waits for its next request, so it is
//!   the idle timeout as well.
//! - **Connection cap** (`server.max_connections`): a connection accepted
//!   beyond it is closed at once, so descriptors and memory stay bounded and
//!   silent connections make room again within the timeout.
//! - **Shutdown window** (`server.shutdown_grace_secs`): after the signal the
//!   listener closes, in-flight requests may finish, and whatever is still open
//!   when the window ends is dropped.
//!
//! Only HTTP/1.1 is served: hyper's HTTP/2 detection reads the connection
//! preface without any timeout, which would bring the silent-connection hole
//! back; the service sits behind proxies that speak HTTP/1.1 to it anyway.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

use super::config::ServerConfig;
use super::metrics;
use super::parse_errors::JsonParseErrors;

/// Hard cap on a request head (request line and headers) that hyper enforces
/// with its own 431 (given the JSON body by `parse_errors`); heads below it
/// but over `app::MAX_HEAD_BYTES` get 431 from the middleware.
pub const HYPER_MAX_HEAD_BYTES: usize = 64 * 1024;
/// Pause after a failed `accept` (e.g. out of descriptors) before the next,
/// so the loop does not spin while the condition lasts.
const ACCEPT_BACKOFF: Duration = Duration::from_millis(50);

/// Serves `router` on `listener` until `shutdown` resolves (module docs).
pub async fn serve(
    listener: TcpListener,
    router: Router,
    config: &ServerConfig,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let mut http = http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(Duration::from_secs(config.header_read_timeout_secs))
        .max_buf_size(HYPER_MAX_HEAD_BYTES)
        .max_header_size(HYPER_MAX_HEAD_BYTES);
    let connections = Arc::new(Semaphore::new(config.max_connections));
    let graceful = GracefulShutdown::new();
    let service = TowerToHyperService::new(router);
    tokio::pin!(shutdown);
    loop {
        let (stream, _peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(pair) => pair,
                Err(err) => {
                    tracing::warn!(%err, "accept failed");
                    tokio::time::sleep(ACCEPT_BACKOFF).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let Ok(permit) = connections.clone().try_acquire_owned() else {
            ::metrics::counter!(metrics::CONNECTIONS_REFUSED).increment(1);
            drop(stream);
            continue;
        };
        // hyper's own bare 4xx answers get the JSON error body too.
        let stream = TokioIo::new(JsonParseErrors::new(stream));
        let connection = graceful.watch(http.serve_connection(stream, service.clone()));
        tokio::spawn(async move {
            // Errors here are the client's (reset, timeout, bad request
            // line); hyper already answered what it could.
            if let Err(err) = connection.await {
                tracing::debug!(%err, "connection ended with an error");
            }
            drop(permit);
        });
    }
    drop(listener);
    let window = Duration::from_secs(config.shutdown_grace_secs);
    let open = graceful.count();
    tokio::select! {
        () = graceful.shutdown() => {}
        () = tokio::time::sleep(window) => {
            tracing::warn!(open, secs = window.as_secs(), "shutdown window elapsed; dropping open connections");
        }
    }
    Ok(())
}

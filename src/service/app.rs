//! `Application`: the router with its middleware, bound to a listener.
//!
//! Middleware, outermost first:
//! 1. tracing (`tower_http::trace`): one span per request, logged at `debug`
//!    (`RUST_LOG=tower_http=debug` shows every request; off by default so that
//!    logging does not dominate under load);
//! 2. metrics ([`metrics::track`]): count and latency per route template, method, status;
//! 3. panic catcher: a panicking handler answers 500 with the JSON error body;
//! 4. request head size: a target over [`MAX_URI_BYTES`] answers 414 and headers
//!    over [`MAX_HEAD_BYTES`] 431, with the JSON error body (hyper itself cuts
//!    heads off at [`super::server::HYPER_MAX_HEAD_BYTES`] with a 431, and
//!    answers what it cannot parse with a 400, both given the JSON body by
//!    [`super::parse_errors`]);
//! 5. request deadline: a request still running `limits.request_deadline_secs`
//!    after its body arrived is dropped and answered 504 `deadline_exceeded`
//!    (dropping it also cancels its CPU job, see `pool.rs`); 504 rather than
//!    503 because the service did accept the work and the client may retry
//!    with a smaller request. A body that pauses for longer than
//!    `server.header_read_timeout_secs` is cut off;
//! 6. body limit (`DefaultBodyLimit`): bodies over `limits.max_body_bytes` make
//!    [`ApiJson`](super::extract::ApiJson) answer 413 with the JSON error body;
//! 7. on matched routes only, the guard of the routes that change state
//!    (`POST /v1/scenes`, `POST …/records`, every `DELETE`): a browser page of
//!    another origin than the service's own and `server.allowed_origins` gets
//!    403 (browsers send simple cross-site POSTs without a preflight), and with
//!    `server.auth_token` set they need `Authorization: Bearer <token>`, else 401.
//!
//! Connections (timeouts, the connection cap, the shutdown window) are
//! handled below all of this, in [`super::server`].
//!
//! Unknown paths answer 404 and known paths with the wrong method 405, both with
//! the JSON error body.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{Method, Uri, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::{Extension, Router};
use tokio::net::TcpListener;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::config::{Config, Limits};
use super::error::{ApiError, ErrorBody};
use super::irradiance_caches::IrradianceCaches;
use super::metrics::{self, Metrics};
use super::pool::CpuPool;
use super::posted_scenes::PostedScenes;
use super::routes;
use super::scenes::{self, NotInserted, SceneRegistry};
use super::server;
use super::shared_store::SharedStore;
use super::state::AppState;
use super::tile_store::TileStore;
use crate::bmc::cache::QuadratureCache;
use crate::integrator::point_query::PointRecords;

/// How often histogram samples are folded into buckets when nobody scrapes.
const METRICS_UPKEEP_PERIOD: Duration = Duration::from_secs(5);
/// Longest accepted request target (path and query), in bytes.
pub const MAX_URI_BYTES: usize = 8 * 1024;
/// Largest accepted request headers (names and values), in bytes.
pub const MAX_HEAD_BYTES: usize = 32 * 1024;

/// A service bound to its listener, ready to run.
pub struct Application {
    listener: TcpListener,
    router: Router,
    state: Arc<AppState>,
}

impl Application {
    /// Builds the state and router and binds `config.server.bind` (port 0 picks a free port).
    pub async fn build(config: Config) -> anyhow::Result<Application> {
        let pool = CpuPool::new(
            config.server.worker_threads(),
            config.limits.max_queued_jobs,
            config.limits.max_queue_wait_secs,
        )
        .context("cannot start the CPU pool")?;
        let metrics = Metrics::install().map_err(anyhow::Error::msg)?;
        let listener = TcpListener::bind(config.server.bind)
            .await
            .with_context(|| format!("cannot bind {}", config.server.bind))?;
        if config.server.auth_token.is_empty() && !config.server.bind.ip().is_loopback() {
            tracing::warn!(
                bind = %config.server.bind,
                "no server.auth_token: anyone who reaches this address can replace or delete scenes and clear caches"
            );
        }
        // Posted scenes load after the directory's, so they replace directory
        // scenes of the same id, as they did when they were posted.
        let (dir, lenient, posted) = (
            config.scenes.dir.clone(),
            config.scenes.lenient,
            PostedScenes::new(&config.cache.data_dir),
        );
        // Each within the whole scenes budget; together they are held to it
        // as they are registered below.
        let limits = crate::scene::LoadLimits {
            max_bytes: config.scenes.max_scene_bytes,
            budget: "scenes.max_scene_bytes",
            cancel: crate::cancel::Cancel::never(),
        };
        let (loaded, posted) = tokio::task::spawn_blocking(move || {
            let mut loaded = scenes::load_dir(&dir, lenient, &limits);
            loaded.extend(posted.load_all(&dir, &limits));
            (loaded, posted)
        })
        .await
        .context("scene loading panicked")?;
        let registry = SceneRegistry::new(&config.scenes);
        for scene in loaded {
            let id = scene.id.clone();
            // A posted copy replaces the directory's scene of its id.
            if let Err(NotInserted::OverBudget(over)) = registry.insert(scene, true) {
                tracing::error!(%id, %over, "scene skipped: over the scenes budget");
            }
        }
        tracing::info!(scenes = registry.len(), dir = %config.scenes.dir.display(), "scenes loaded");
        let irradiance_caches = IrradianceCaches::new(
            usize::try_from(config.cache.irradiance_bytes).unwrap_or(usize::MAX),
        );
        let point_records = PointRecords::new(
            irradiance_caches.per_cache_bytes(),
            config.cache.irradiance_bytes,
        );
        let quadratures = Arc::new(QuadratureCache::new(config.cache.factorisation_bytes));
        let shared = SharedStore::connect(&config.cluster).context("cluster.redis_url")?;
        let mut tiles = open_tile_store(&config.cache, config.limits.max_tile_area)?;
        // The data directory is this process's now (the tile log's lock):
        // what uploads of an earlier run left behind can go.
        posted.clear_incoming();
        if let Some(shared) = &shared {
            tiles = tiles.sharing_through(shared.outbox());
            if !shared.signs() {
                tracing::warn!(
                    "no cluster.secret: replicas take whatever Redis holds (tile parts, scenes, deletions); set one shared secret on every replica"
                );
            }
            tracing::info!(prefix = %config.cluster.redis_prefix, "sharing tiles and scenes with other replicas through Redis");
        }
        let uploads = Arc::new(tokio::sync::Semaphore::new(
            config.limits.max_concurrent_uploads,
        ));
        let state = Arc::new(AppState {
            uploads,
            quadratures,
            config,
            pool,
            metrics,
            scenes: registry,
            point_records,
            irradiance_caches,
            tiles,
            posted,
            shared,
            import_key: rand::random(),
        });
        let router = router(state.clone());
        Ok(Application {
            listener,
            router,
            state,
        })
    }

    /// The address actually bound (useful with port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.listener
            .local_addr()
            .expect("a bound TCP listener has a local address")
    }

    /// The port actually bound.
    pub fn port(&self) -> u16 {
        self.local_addr().port()
    }

    /// The shared state (tests and the CLI inspect it).
    pub fn state(&self) -> &Arc<AppState> {
        &self.state
    }

    /// Serves until `shutdown` resolves, then stops accepting connections and
    /// waits for in-flight requests to finish.
    pub async fn run_until_stopped(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> std::io::Result<()> {
        let upkeep = {
            let metrics = self.state.metrics.clone();
            tokio::spawn(async move {
                let mut tick = tokio::time::interval(METRICS_UPKEEP_PERIOD);
                loop {
                    tick.tick().await;
                    metrics.run_upkeep();
                }
            })
        };
        let follower = super::replicas::follow(&self.state);
        tracing::info!(addr = %self.local_addr(), "listening");
        let served = server::serve(
            self.listener,
            self.router,
            &self.state.config.server,
            shutdown,
        )
        .await;
        upkeep.abort();
        if let Some(follower) = follower {
            follower.abort();
        }
        tracing::info!("stopped");
        served
    }
}

/// The reproducible tiles' store: on `cache.data_dir/tiles.log` when a data
/// directory is configured (loaded now), in memory otherwise.
fn open_tile_store(
    cache: &super::config::CacheConfig,
    max_tile_area: usize,
) -> anyhow::Result<TileStore> {
    if cache.data_dir.as_os_str().is_empty() {
        return Ok(TileStore::new(cache.tile_bytes, max_tile_area));
    }
    let path = cache.data_dir.join("tiles.log");
    let store = TileStore::open(cache.tile_bytes, max_tile_area, &path)
        .with_context(|| format!("cannot open the tile log {}", path.display()))?;
    let stats = store.stats();
    tracing::info!(log = %path.display(), entries = stats.loaded_entries,
        dropped_bytes = stats.dropped_bytes, "tile log loaded");
    if stats.dropped_bytes > 0 {
        tracing::warn!(log = %path.display(), bytes = stats.dropped_bytes,
            "skipped damaged entries of the tile log (or cut its torn tail)");
    }
    Ok(store)
}

/// The OpenAPI document's header; paths are added by `routes!` registrations.
#[derive(OpenApi)]
#[openapi(
    info(description = "Bayesian Monte Carlo irradiance caching over REST."),
    components(schemas(ErrorBody)),
    tags((name = "service", description = "Health, metrics and this document"),
         (name = "scenes", description = "Scenes and queries on them"),
         (name = "quadratures", description = "BMC quadrature weights"))
)]
struct ApiDoc;

/// The full router: documented routes, fallbacks and middleware. Routes
/// that change state are declared apart, under the guard's `route_layer`;
/// reads and queries (computations that change nothing a client can name)
/// are open.
pub fn router(state: Arc<AppState>) -> Router {
    let guard = Arc::new(MutationGuard {
        token: state.config.server.auth_token.clone(),
        origins: state
            .config
            .server
            .allowed_origins()
            .map(str::to_owned)
            .collect(),
    });
    let state_changing = OpenApiRouter::new()
        .routes(routes!(routes::scenes::post_scene))
        .routes(routes!(routes::scenes::delete_scene))
        .routes(routes!(routes::cache::delete_cache))
        .routes(routes!(routes::records::import_records))
        .route_layer(middleware::from_fn_with_state(guard, guard_mutation));
    let (api_routes, doc) = OpenApiRouter::with_openapi(ApiDoc::openapi())
        .routes(routes!(routes::health::health))
        .routes(routes!(routes::health::ready))
        .routes(routes!(routes::metrics::metrics))
        .routes(routes!(routes::openapi::openapi))
        .routes(routes!(routes::scenes::list_scenes))
        .routes(routes!(routes::scenes::get_scene))
        .routes(routes!(routes::irradiance::irradiance))
        .routes(routes!(routes::tiles::tile))
        .routes(routes!(routes::tile_get::get_tile))
        .routes(routes!(routes::presets::presets))
        .routes(routes!(routes::radiance::radiance))
        .routes(routes!(routes::cache::get_cache))
        .routes(routes!(routes::records::export_records))
        .routes(routes!(routes::quadratures::post_quadrature))
        .merge(state_changing)
        .split_for_parts();
    let limits = state.config.limits.clone();
    let body_stall = Duration::from_secs(state.config.server.header_read_timeout_secs);
    let cors = cors(&state.config.server);
    with_middleware(
        api_routes
            .layer(Extension(Arc::new(doc)))
            .with_state(state)
            .merge(super::viewer::routes()),
        &limits,
        body_stall,
    )
    .layer(cors)
}

/// Cross-origin reads: any page may GET tiles, scenes and statistics (and
/// read the tile headers). Pages may send state-changing requests only from
/// `server.allowed_origins` (the guard refuses the others), so preflights
/// allow those methods and headers only when such origins are configured.
fn cors(server: &super::config::ServerConfig) -> CorsLayer {
    let layer = CorsLayer::new()
        .allow_origin(AllowOrigin::any())
        .expose_headers(super::tile_response::EXPOSED);
    if server.allowed_origins().next().is_some() {
        layer
            .allow_methods([Method::GET, Method::HEAD, Method::POST, Method::DELETE])
            .allow_headers([
                header::IF_NONE_MATCH,
                header::AUTHORIZATION,
                header::CONTENT_TYPE,
            ])
    } else {
        layer
            .allow_methods([Method::GET, Method::HEAD])
            .allow_headers([header::IF_NONE_MATCH])
    }
}

/// Adds the JSON fallbacks and the middleware stack described in the module
/// docs; a request body may pause for at most `body_stall`.
fn with_middleware(routes: Router, limits: &Limits, body_stall: Duration) -> Router {
    routes
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(DefaultBodyLimit::max(limits.max_body_bytes))
        .layer(middleware::from_fn_with_state(
            Deadlines {
                request: limits.request_deadline(),
                body_stall,
            },
            enforce_deadline,
        ))
        .layer(middleware::from_fn(check_head_size))
        .layer(CatchPanicLayer::custom(
            |panic: Box<dyn std::any::Any + Send>| {
                ApiError::from_panic(panic.as_ref()).into_response()
            },
        ))
        .layer(middleware::from_fn(metrics::track))
        .layer(TraceLayer::new_for_http())
}

async fn not_found(uri: Uri) -> ApiError {
    ApiError::NoRoute {
        path: uri.path().to_owned(),
    }
}

async fn method_not_allowed(method: Method) -> ApiError {
    ApiError::MethodNotAllowed {
        method: method.to_string(),
    }
}

/// How long a request may take: [`Limits::request_deadline`] from the
/// moment its body has arrived, and at most `body_stall` between two parts
/// of the body.
#[derive(Clone, Copy)]
struct Deadlines {
    request: Duration,
    body_stall: Duration,
}

/// The request deadline (module docs), counted from the end of the body's
/// arrival: a large upload over a slow link is not the service's work, and
/// must not use up the time its processing gets. A body that pauses for
/// longer than `body_stall` is cut off (the handler reading it fails, 4xx),
/// so a client cannot hold a request open by trickling its body; a body
/// nobody reads stops being waited for after that long too.
async fn enforce_deadline(
    State(deadlines): State<Deadlines>,
    request: Request,
    next: Next,
) -> Response {
    use axum::body::HttpBody;
    let (parts, body) = request.into_parts();
    let (arrived, body_arrived) = tokio::sync::oneshot::channel::<()>();
    let body = if body.is_end_stream() {
        let _ = arrived.send(());
        body
    } else {
        let (mut sender, forwarded) =
            http_body_util::channel::Channel::<axum::body::Bytes, axum::Error>::new(1);
        tokio::spawn(async move {
            use http_body_util::BodyExt;
            let mut body = body;
            loop {
                match tokio::time::timeout(deadlines.body_stall, body.frame()).await {
                    Ok(Some(Ok(frame))) => {
                        let Ok(data) = frame.into_data() else {
                            continue;
                        };
                        // Waiting for the handler to take it is a stall too.
                        let taken =
                            tokio::time::timeout(deadlines.body_stall, sender.send_data(data));
                        if !matches!(taken.await, Ok(Ok(()))) {
                            break;
                        }
                    }
                    Ok(Some(Err(err))) => {
                        sender.abort(err);
                        break;
                    }
                    Ok(None) => break,
                    Err(_) => {
                        sender.abort(axum::Error::new(format!(
                            "the request body paused for more than {} s",
                            deadlines.body_stall.as_secs()
                        )));
                        break;
                    }
                }
            }
            let _ = arrived.send(());
        });
        axum::body::Body::new(forwarded)
    };
    let response = next.run(Request::from_parts(parts, body));
    tokio::pin!(response);
    let deadline = async {
        let _ = body_arrived.await;
        tokio::time::sleep(deadlines.request).await;
    };
    tokio::select! {
        response = &mut response => response,
        () = deadline => ApiError::DeadlineExceeded {
            secs: deadlines.request.as_secs(),
        }
        .into_response(),
    }
}

/// 414 / 431 with the JSON error body for oversized request heads.
async fn check_head_size(request: Request, next: Next) -> Response {
    let target = request
        .uri()
        .path_and_query()
        .map_or(0, |p| p.as_str().len());
    if target > MAX_URI_BYTES {
        return ApiError::UriTooLong {
            len: target,
            limit: MAX_URI_BYTES,
        }
        .into_response();
    }
    let head: usize = request
        .headers()
        .iter()
        .map(|(name, value)| name.as_str().len() + value.len())
        .sum();
    if head > MAX_HEAD_BYTES {
        return ApiError::HeadersTooLarge {
            len: head,
            limit: MAX_HEAD_BYTES,
        }
        .into_response();
    }
    next.run(request).await
}

/// What a request that changes state must satisfy (module docs).
struct MutationGuard {
    /// `server.auth_token`; empty = none.
    token: String,
    /// `server.allowed_origins`, besides the service's own.
    origins: Vec<String>,
}

impl MutationGuard {
    /// Refuses a browser page of a foreign origin (`Origin` naming another
    /// host than the one addressed, or `Sec-Fetch-Site` saying so), whatever
    /// the token: such pages may send simple POSTs without a preflight.
    /// Clients that are not browsers send neither header.
    fn check_origin(&self, request: &Request) -> Result<(), ApiError> {
        let headers = request.headers();
        let origin = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok());
        let fetch_site = headers.get("sec-fetch-site").and_then(|v| v.to_str().ok());
        let Some(origin) = origin else {
            return match fetch_site {
                Some("cross-site" | "same-site") => Err(ApiError::CrossOrigin {
                    origin: "(not sent)".into(),
                }),
                _ => Ok(()),
            };
        };
        let host = headers.get(header::HOST).and_then(|v| v.to_str().ok());
        let same_origin = origin
            .split_once("://")
            .is_some_and(|(_, authority)| Some(authority) == host);
        if same_origin || self.origins.iter().any(|o| o == origin) {
            Ok(())
        } else {
            Err(ApiError::CrossOrigin {
                origin: origin.chars().take(200).collect(),
            })
        }
    }

    /// The bearer token, when one is configured (scheme name case-insensitive).
    fn check_token(&self, request: &Request) -> Result<(), ApiError> {
        if self.token.is_empty() {
            return Ok(());
        }
        let presented = request
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.split_once(' '))
            .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
            .map_or("", |(_, token)| token.trim());
        if constant_time_eq(presented.as_bytes(), self.token.as_bytes()) {
            Ok(())
        } else {
            Err(ApiError::Unauthorized)
        }
    }
}

/// Guards a route that changes state (the `route_layer` of those routes):
/// same-origin or allowed web origins only, and the bearer token when one
/// is configured (module docs).
async fn guard_mutation(
    State(guard): State<Arc<MutationGuard>>,
    request: Request,
    next: Next,
) -> Response {
    match guard
        .check_origin(&request)
        .and_then(|()| guard.check_token(&request))
    {
        Ok(()) => next.run(request).await,
        Err(refusal) => refusal.into_response(),
    }
}

/// Byte equality whose time does not depend on where the inputs differ, so
/// response times do not reveal the token a prefix at a time.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Resolves on SIGINT (Ctrl-C) or SIGTERM.
pub async fn shutdown_signal() {
    let interrupt = async {
        if let Err(err) = tokio::signal::ctrl_c().await {
            tracing::error!(%err, "cannot listen for SIGINT");
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(err) => {
                tracing::error!(%err, "cannot listen for SIGTERM");
                std::future::pending::<()>().await;
            }
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = interrupt => tracing::info!("SIGINT received, shutting down"),
        () = terminate => tracing::info!("SIGTERM received, shutting down"),
    }
}

#[cfg(test)]
mod tests;

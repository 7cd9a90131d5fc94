//! The HTTP service: parses and validates requests, dispatches CPU work to a
//! bounded pool, serialises results. The library modules it serves know
//! nothing about HTTP.
//!
//! Its public surface is how to run it: [`serve`] (or [`run_serve`] with the
//! `serve` subcommand's [`ServeArgs`]) runs it until SIGINT/SIGTERM with a
//! [`Config`] ([`config`]: `config/default.toml` + file + `BMC_<SECTION>__<KEY>`
//! environment + flags); [`Application`] binds the router (middleware,
//! routes, fallbacks) to a listener for embedding and tests, and stops on any
//! future ([`shutdown_signal`] is the one [`serve`] uses). [`ErrorBody`] is
//! the JSON body of every error response, for clients.
//!
//! Inside (private):
//! - `app`: `Application`, the router and its middleware;
//! - `state`: `AppState`, shared by all requests;
//! - `error`: `ApiError`, its JSON body and one `From` per library error;
//! - `extract`: `ApiJson`, a JSON extractor whose errors name the field;
//! - `pool`: `CpuPool`, bounded rayon pool (503 + `Retry-After` when full);
//! - `metrics`: Prometheus names, recorder and per-route middleware;
//! - `scenes`: the scene registry and startup loading;
//! - `tile_store`, `tile_render`: reproducible tiles' memoised parts and passes;
//! - `import_check`: an import's records checked against fresh estimates
//!   of the scene before they are added;
//! - `posted_scenes`: scenes posted at runtime, kept across restarts;
//! - `shared_store`, `replicas`: sharing with other replicas through Redis;
//! - `routes`: one file per resource.

mod app;
pub mod config;
mod error;
mod extract;
mod import_check;
mod integrator;
pub(crate) mod irradiance_caches;
mod metrics;
mod parse_errors;
mod pool;
mod posted_scenes;
mod replicas;
mod routes;
mod scene_changes;
mod scenes;
mod server;
mod shared_store;
mod state;
mod tile_render;
mod tile_response;
mod tile_store;
mod viewer;

pub use app::{Application, shutdown_signal};
pub use config::Config;
pub use error::{ErrorBody, ErrorDetail};
// What `Application::state` hands to tests; the service's internals, not an API.
#[doc(hidden)]
pub use pool::CpuPool;
#[doc(hidden)]
pub use state::AppState;

/// Arguments of `bmc-irradiance serve`.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// TOML file merged over the defaults (config/default.toml); may set any subset of keys.
    /// Environment variables BMC_<SECTION>__<KEY> override both.
    #[arg(long)]
    pub config: Option<std::path::PathBuf>,
    /// Listen address, overriding `server.bind`.
    #[arg(long)]
    pub bind: Option<std::net::SocketAddr>,
}

/// `serve`: loads the configuration layers, initialises logging and runs the service.
pub fn run_serve(args: &ServeArgs) -> anyhow::Result<()> {
    init_tracing();
    let config = Config::load(args.config.as_deref(), std::env::vars(), args.bind)?;
    serve(config)
}

/// Logs to stderr, filtered by `RUST_LOG` (default: `info`), coloured only
/// when stderr is a terminal.
pub fn init_tracing() {
    use std::io::IsTerminal;
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    // Escape codes in a log file or a journal are noise to whoever reads it.
    let ansi = std::io::stderr().is_terminal();
    // Ignore a second initialisation (tests, embedding) instead of failing.
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(ansi)
        .try_init();
}

/// Large allocations (Gram matrices, factors and tables of megabytes) are
/// served by `mmap` and given back to the OS when freed. glibc raises its
/// `mmap` threshold each time such a block is freed, after which blocks of that
/// size come from the per-thread heaps, which return almost nothing: 1,800
/// quadratures of N = 256..1024 then held 1.0 GB of RSS while the
/// factorisation cache held its 256 MiB budget; with the threshold fixed at
/// 256 KiB, 285 MiB (docs/BENCHMARKS.md, "Memory under quadrature churn").
fn return_large_blocks_to_the_os() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        const THRESHOLD: libc::c_int = 256 * 1024;
        // SAFETY: mallopt only changes allocator tuning; it is called before
        // the runtime and the CPU pool start their threads.
        if unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, THRESHOLD) } != 1 {
            tracing::warn!("could not fix the malloc mmap threshold");
        }
    }
}

/// Runs the service with `config` until SIGINT or SIGTERM, on a runtime of
/// `server.runtime_threads` threads (the CPU pool has its own threads).
pub fn serve(config: Config) -> anyhow::Result<()> {
    return_large_blocks_to_the_os();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(config.server.runtime_threads())
        .thread_name("bmc-io")
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let app = Application::build(config).await?;
        app.run_until_stopped(shutdown_signal()).await?;
        Ok(())
    })
}

//! Command-line subcommands as library functions; `main.rs` only dispatches.

pub mod fetch;
pub mod irradiance;
pub mod quadrature;
pub mod render;
pub mod scene_args;
pub mod study;
pub mod upload;

use crate::render::PathDepth;

/// Runs `work` on a rayon pool of `threads` threads (`--threads`), or on the
/// global pool when `None`. Results never depend on the thread count: every
/// per-point and per-pixel random stream is seeded from its index.
pub(crate) fn in_thread_pool<T: Send>(
    threads: Option<usize>,
    work: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    match threads {
        Some(threads) => Ok(rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|err| anyhow::anyhow!("building the thread pool: {err}"))?
            .install(work)),
        None => Ok(work()),
    }
}

/// Parses `--max-depth`: an integer, checked by [`PathDepth::new`] (so an
/// out-of-range depth is refused while the arguments are read, with the
/// library's message).
fn max_depth_parser() -> impl clap::builder::TypedValueParser<Value = PathDepth> {
    use clap::builder::TypedValueParser;
    clap::value_parser!(u32).try_map(PathDepth::new)
}

//! Command-line subcommands as library functions; `main.rs` only dispatches.

pub mod fetch;
pub mod irradiance;
pub mod quadrature;
pub mod render;
pub mod study;

/// Runs `work` on a rayon pool of `threads` threads (`--threads`), or on the
/// global pool when `None`. Results never depend on the thread count: every
/// per-point and per-pixel random stream is seeded from its index.
pub fn in_thread_pool<T: Send>(
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

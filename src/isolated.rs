//! Work that other threads may wait for runs on a rayon pool of its own.
//!
//! A rayon worker that waits inside a `join` runs other queued jobs on top
//! of its own stack. If one of those jobs then blocks on a value the suspended
//! job below it is computing (a cache entry computed once per key: moka's
//! `try_get_with`, a secondary cache being built), neither can finish: the
//! waiter holds the thread the computation needs to resume. So every
//! once-per-key computation that may use rayon goes through [`isolated`]:
//! the calling thread blocks without taking other work, and the computation
//! runs on a pool that nothing else uses while it runs. Waiters may then
//! block plainly, on any thread. Computations may nest (a quadrature needs a
//! factorisation): each takes a pool of its own, and as the keys they wait
//! for form no cycle, none waits for itself.

use std::sync::{Arc, Mutex};

/// Idle pools kept for reuse; a few suffice, as builds are short and rarely
/// run more than one per worker at a time.
const MAX_IDLE_POOLS: usize = 4;

static IDLE: Mutex<Vec<Arc<rayon::ThreadPool>>> = Mutex::new(Vec::new());

/// Runs `work` in parallel on a pool of as many threads as the caller's
/// pool, used by nothing else meanwhile, and returns its result (a panic in
/// `work` is resumed here). The calling thread blocks without running other
/// rayon jobs, so nothing can be stacked on it while `work` runs.
pub(crate) fn isolated<T: Send>(work: impl FnOnce() -> T + Send) -> T {
    let threads = rayon::current_num_threads();
    let Some(pool) = take_pool(threads) else {
        // The OS refused the threads; the work still has to be done.
        return work();
    };
    // `install` from a thread outside every pool blocks that thread on a
    // plain latch; from a worker it would run other jobs while waiting.
    let outcome = std::thread::scope(|s| s.spawn(|| pool.install(work)).join());
    give_back(pool);
    match outcome {
        Ok(value) => value,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

/// [`moka::sync::Cache::try_get_with`] with the value computed by
/// [`isolated`]: concurrent callers of one key compute it once, and may
/// wait for it from any thread.
pub(crate) fn try_get_with<K, V, E>(
    cache: &moka::sync::Cache<K, V>,
    key: K,
    init: impl FnOnce() -> Result<V, E> + Send,
) -> Result<V, Arc<E>>
where
    K: std::hash::Hash + Eq + Send + Sync + 'static,
    V: Clone + Send + Sync + 'static,
    E: Send + Sync + 'static,
{
    cache.try_get_with(key, || isolated(init))
}

fn take_pool(threads: usize) -> Option<Arc<rayon::ThreadPool>> {
    let mut idle = IDLE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(at) = idle.iter().position(|p| p.current_num_threads() == threads) {
        return Some(idle.swap_remove(at));
    }
    drop(idle);
    match rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("bmc-build-{i}"))
        .build()
    {
        Ok(pool) => Some(Arc::new(pool)),
        Err(e) => {
            tracing::warn!(error = %e, "no threads for an isolated computation; running it in place");
            None
        }
    }
}

fn give_back(pool: Arc<rayon::ThreadPool>) {
    let mut idle = IDLE.lock().unwrap_or_else(|e| e.into_inner());
    if idle.len() < MAX_IDLE_POOLS {
        idle.push(pool);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::Duration;

    /// The shape of the deadlock this module prevents, on a pool of two
    /// threads: the first job computes a key with a `join` whose second half
    /// the idle thread steals; jobs asking for the same key arrive while the
    /// first half runs. Without isolation the first job's thread, waiting for
    /// the stolen half, runs one of them, which blocks on the key forever.
    #[test]
    fn jobs_waiting_for_a_key_under_computation_finish() {
        let pool = Arc::new(
            rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .unwrap(),
        );
        let cache: Arc<moka::sync::Cache<u32, u64>> = Arc::new(moka::sync::Cache::new(16));
        let computed = Arc::new(AtomicUsize::new(0));
        let (done, finished) = std::sync::mpsc::channel();
        let job = || {
            let (cache, computed, done) = (cache.clone(), computed.clone(), done.clone());
            move || {
                let value = try_get_with(&cache, 7, || {
                    computed.fetch_add(1, Ordering::Relaxed);
                    let (a, b) = rayon::join(
                        || {
                            std::thread::sleep(Duration::from_millis(20));
                            1u64
                        },
                        || {
                            std::thread::sleep(Duration::from_millis(80));
                            2u64
                        },
                    );
                    Ok::<_, ()>(a + b)
                })
                .unwrap();
                let _ = done.send(value);
            }
        };
        pool.spawn(job());
        std::thread::sleep(Duration::from_millis(5));
        for _ in 0..8 {
            pool.spawn(job());
        }
        let values: Vec<u64> = (0..9)
            .map(|_| {
                finished
                    .recv_timeout(Duration::from_secs(30))
                    .expect("a job waiting for the key never finished")
            })
            .collect();
        assert_eq!(values, vec![3; 9]);
        assert_eq!(computed.load(Ordering::Relaxed), 1, "computed once");
    }

    #[test]
    fn a_panic_reaches_the_caller_and_the_pool_is_reused() {
        let caught = std::panic::catch_unwind(|| isolated(|| panic!("inside")));
        assert!(caught.is_err());
        assert_eq!(isolated(|| rayon::join(|| 1, || 2)), (1, 2));
    }
}

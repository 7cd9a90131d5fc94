//! The bounded CPU pool: heavy work (factorisations, ray tracing) runs on a
//! dedicated rayon pool, never on the async runtime's threads, and at most
//! `limits.max_queued_jobs` jobs may be queued or running at once.
//!
//! Why a semaphore in front of rayon: rayon's queue is unbounded, so under
//! overload it would grow memory without limit while latencies explode. A
//! request that finds every slot taken is answered at once with 503 and
//! `Retry-After` (back-pressure the client can act on) instead.
//!
//! Cancellation: the request deadline (504, see `app.rs`) and client
//! disconnects drop the handler's future, which drops the receiving end of the
//! job's channel. A job that has not started yet sees this and is skipped, so
//! an abandoned request never leaves work queued; a job that already started
//! runs to completion (the library code is not interruptible) and its slot is
//! released when it ends. Per-request limits (points, samples, tile area) keep
//! such a job short.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;

use tokio::sync::{Semaphore, oneshot};

use super::error::ApiError;
use super::metrics;

/// Seconds a client is told to wait (`Retry-After`) when every slot is taken.
/// Jobs are bounded by the request limits to well under a second, so one
/// second is long enough for a slot to free up and short enough not to idle.
pub const RETRY_AFTER_SECS: u64 = 1;

/// A rayon pool behind a fixed number of job slots; cheap to clone (shared).
#[derive(Clone)]
pub struct CpuPool {
    /// Threads that do the CPU work, separate from the async runtime so that
    /// slow jobs never stall request parsing, health checks or metrics.
    threads: Arc<rayon::ThreadPool>,
    /// One permit per job queued or running; exhausting it means 503.
    slots: Arc<Semaphore>,
    /// Total number of slots, for error messages and the in-flight gauge.
    capacity: usize,
}

impl CpuPool {
    /// A pool of `threads` workers accepting at most `capacity` jobs at once.
    pub fn new(threads: usize, capacity: usize) -> Result<Self, rayon::ThreadPoolBuildError> {
        let threads = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("bmc-cpu-{i}"))
            .build()?;
        Ok(CpuPool {
            threads: Arc::new(threads),
            slots: Arc::new(Semaphore::new(capacity)),
            capacity,
        })
    }

    /// Runs `work` on the pool and resolves to its result.
    ///
    /// Fails at once with [`ApiError::Overloaded`] (503 + `Retry-After`) when all
    /// slots are taken, and with [`ApiError::Internal`] if `work` panics (the pool
    /// thread survives). Dropping the returned future before the job starts
    /// cancels it.
    pub async fn run<T, F>(&self, work: F) -> Result<T, ApiError>
    where
        F: FnOnce() -> T + Send + 'static,
        T: Send + 'static,
    {
        let Ok(permit) = self.slots.clone().try_acquire_owned() else {
            ::metrics::counter!(metrics::CPU_JOBS_REJECTED).increment(1);
            return Err(ApiError::Overloaded {
                capacity: self.capacity,
                retry_after_secs: RETRY_AFTER_SECS,
            });
        };
        let (reply, result) = oneshot::channel();
        self.record_in_flight();
        let pool = self.clone();
        self.threads.spawn(move || {
            // Skip the work if the request was abandoned while the job was queued.
            let outcome = (!reply.is_closed()).then(|| {
                // A panic must not take the pool thread (or with rayon's default
                // handler, the process) down; it becomes a 500 for this request.
                catch_unwind(AssertUnwindSafe(work))
            });
            // Free the slot before replying, so a caller that sees its result
            // can immediately submit again.
            drop(permit);
            pool.record_in_flight();
            if let Some(outcome) = outcome {
                let _ = reply.send(outcome);
            }
        });
        match result.await {
            Ok(Ok(value)) => Ok(value),
            Ok(Err(panic)) => Err(ApiError::from_panic(panic.as_ref())),
            Err(_) => Err(ApiError::Internal {
                message: "CPU job ended without a result".into(),
            }),
        }
    }

    /// Jobs queued or running right now.
    pub fn in_flight(&self) -> usize {
        self.capacity - self.slots.available_permits()
    }

    /// The maximum number of jobs queued or running at once.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    fn record_in_flight(&self) {
        ::metrics::gauge!(metrics::CPU_JOBS_IN_FLIGHT).set(self.in_flight() as f64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::mpsc;

    /// Submits a job that blocks until the returned sender is used (or dropped).
    fn blocking_job(
        pool: &CpuPool,
    ) -> (
        mpsc::Sender<()>,
        tokio::task::JoinHandle<Result<(), ApiError>>,
    ) {
        let (release, gate) = mpsc::channel::<()>();
        let pool = pool.clone();
        let handle = tokio::spawn(async move {
            pool.run(move || {
                let _ = gate.recv();
            })
            .await
        });
        (release, handle)
    }

    async fn wait_until_in_flight(pool: &CpuPool, n: usize) {
        while pool.in_flight() != n {
            tokio::task::yield_now().await;
        }
    }

    #[tokio::test]
    async fn returns_the_result_of_the_work() {
        let pool = CpuPool::new(2, 4).unwrap();
        assert_eq!(pool.run(|| 6 * 7).await, Ok(42));
        assert_eq!(pool.in_flight(), 0);
    }

    #[tokio::test]
    async fn saturated_pool_answers_overloaded_then_recovers() {
        let pool = CpuPool::new(1, 2).unwrap();
        let (release_a, a) = blocking_job(&pool);
        let (release_b, b) = blocking_job(&pool);
        wait_until_in_flight(&pool, 2).await;

        let err = pool.run(|| ()).await.unwrap_err();
        assert_eq!(
            err,
            ApiError::Overloaded {
                capacity: 2,
                retry_after_secs: RETRY_AFTER_SECS
            }
        );
        assert_eq!(err.status(), axum::http::StatusCode::SERVICE_UNAVAILABLE);

        release_a.send(()).unwrap();
        release_b.send(()).unwrap();
        assert_eq!(a.await.unwrap(), Ok(()));
        assert_eq!(b.await.unwrap(), Ok(()));
        assert_eq!(pool.run(|| 1).await, Ok(1));
    }

    #[tokio::test]
    async fn abandoned_queued_job_is_skipped_and_frees_its_slot() {
        let pool = CpuPool::new(1, 3).unwrap();
        let (release, running) = blocking_job(&pool);
        wait_until_in_flight(&pool, 1).await;

        let ran = Arc::new(AtomicBool::new(false));
        let flag = ran.clone();
        let queued_pool = pool.clone();
        let queued = tokio::spawn(async move {
            queued_pool
                .run(move || flag.store(true, Ordering::SeqCst))
                .await
        });
        wait_until_in_flight(&pool, 2).await;
        queued.abort();
        assert!(queued.await.unwrap_err().is_cancelled());

        release.send(()).unwrap();
        running.await.unwrap().unwrap();
        // One worker thread and a FIFO injector: this job runs after the abandoned one.
        pool.run(|| ()).await.unwrap();
        assert!(!ran.load(Ordering::SeqCst), "abandoned job must not run");
        assert_eq!(pool.in_flight(), 0);
    }

    #[tokio::test]
    async fn panicking_job_is_an_internal_error_and_the_pool_survives() {
        let pool = CpuPool::new(1, 1).unwrap();
        let err = pool.run(|| -> u32 { panic!("boom") }).await.unwrap_err();
        assert_eq!(err.status(), axum::http::StatusCode::INTERNAL_SERVER_ERROR);
        assert!(err.to_string().contains("boom"));
        assert_eq!(pool.run(|| 5).await, Ok(5));
    }
}

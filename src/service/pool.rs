//! The bounded CPU pool: heavy work (factorisations, ray tracing) runs on a
//! dedicated rayon pool, never on the async runtime's threads.
//!
//! Admission, in two stages:
//! 1. **Slots.** At most `limits.max_queued_jobs` jobs may be queued or
//!    running at once, and a job is admitted only while the queue's expected
//!    wait (admitted jobs times the recent mean job time, over the workers)
//!    is at most `limits.max_queue_wait_secs`. A request refused either way
//!    is answered at once with 503 and a `Retry-After` of that expected wait,
//!    instead of growing rayon's unbounded queue or waiting past its deadline.
//! 2. **A fair queue.** At most one job per worker thread runs at a time;
//!    the others wait, first come first served, on a FIFO semaphore outside
//!    rayon. Handing every job to rayon at once let jobs nest under each
//!    other's `join`s (a worker waiting on its own job's task steals a newer
//!    job's task), so old jobs could not finish before new ones and waited
//!    past their deadline while later ones were served.
//!
//! Writes (loading and unpacking a posted scene, [`CpuPool::run_first`])
//! skip the expected-wait test and the queue: one at a time, each takes the
//! next free worker thread. A scene posted under 32 clients reading tiles
//! was otherwise refused with 503 for as long as they read.
//!
//! Cancellation: the request deadline (504, see `app.rs`) and client
//! disconnects drop the handler's future. A job still waiting in the queue
//! leaves it; a running job's [`Cancel`] flag is set, and the library checks
//! it between pixels, records and points, so the worker is free again within
//! one item's time.
//!
//! Health: the pool knows when each running job started; [`CpuPool::status`]
//! reports the oldest one's age, so `/health` can say the pool is wedged
//! (a job running far past any request's deadline) instead of "ok".

use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::sync::{Semaphore, oneshot};
use utoipa::ToSchema;

use super::error::ApiError;
use super::metrics;
use crate::render::Cancel;

/// Bounds of the `Retry-After` given with 503: at least a second (the
/// header's resolution), at most a minute (a client should look again).
const RETRY_AFTER_SECS: (u64, u64) = (1, 60);
/// Weight of the newest job in the running mean of job durations.
const DURATION_SMOOTHING: f64 = 0.1;

/// A rayon pool behind a fixed number of job slots; cheap to clone (shared).
#[derive(Clone)]
pub struct CpuPool {
    /// Threads that do the CPU work, separate from the async runtime so that
    /// slow jobs never stall request parsing, health checks or metrics.
    threads: Arc<rayon::ThreadPool>,
    /// One permit per job queued or running; exhausting it means 503.
    slots: Arc<Semaphore>,
    /// One permit per worker thread: the running jobs. Tokio's semaphore
    /// grants permits in request order, which makes the queue FIFO.
    running: Arc<Semaphore>,
    /// One permit: the job started ahead of the queue ([`CpuPool::run_first`]).
    first: Arc<Semaphore>,
    /// Total number of slots, for error messages and the in-flight gauge.
    capacity: usize,
    /// Worker threads (= most jobs running at once).
    workers: usize,
    /// Longest expected queue wait at which a job is still admitted, seconds.
    max_wait_secs: f64,
    /// Start times of the running jobs and the mean job duration.
    board: Arc<JobBoard>,
}

/// What the pool is doing, for `/health`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
pub struct PoolStatus {
    /// Jobs running on a worker now.
    pub running: usize,
    /// Jobs admitted and waiting for a worker.
    pub queued: usize,
    /// Seconds the longest-running job has been running (0 when idle).
    pub oldest_job_secs: f64,
}

/// The running jobs' start times, and a running mean of job durations.
#[derive(Default)]
struct JobBoard {
    started: Mutex<HashMap<u64, Instant>>,
    next_id: AtomicU64,
    /// Mean job duration in seconds, as `f64` bits (exponential smoothing).
    mean_secs: AtomicU64,
}

impl JobBoard {
    fn start(&self) -> u64 {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        self.lock().insert(id, Instant::now());
        id
    }

    fn finish(&self, id: u64) {
        let Some(start) = self.lock().remove(&id) else {
            return;
        };
        let secs = start.elapsed().as_secs_f64();
        // Lost updates under a race only perturb an estimate.
        let old = f64::from_bits(self.mean_secs.load(Ordering::Relaxed));
        let new = if old == 0.0 {
            secs
        } else {
            old + DURATION_SMOOTHING * (secs - old)
        };
        self.mean_secs.store(new.to_bits(), Ordering::Relaxed);
    }

    fn oldest(&self) -> Duration {
        self.lock()
            .values()
            .map(Instant::elapsed)
            .max()
            .unwrap_or_default()
    }

    fn mean_secs(&self) -> f64 {
        f64::from_bits(self.mean_secs.load(Ordering::Relaxed))
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Instant>> {
        self.started.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Sets the job's [`Cancel`] when dropped: the handler's future owns it, so
/// a deadline or a disconnect (both drop the future) cancels the job.
struct CancelOnDrop(Cancel);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.cancel();
    }
}

impl CpuPool {
    /// A pool of `threads` workers accepting at most `capacity` jobs at once,
    /// and none while the expected wait exceeds `max_wait_secs`.
    pub fn new(
        threads: usize,
        capacity: usize,
        max_wait_secs: f64,
    ) -> Result<Self, rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("bmc-cpu-{i}"))
            .build()?;
        let workers = pool.current_num_threads();
        Ok(CpuPool {
            threads: Arc::new(pool),
            slots: Arc::new(Semaphore::new(capacity)),
            running: Arc::new(Semaphore::new(workers)),
            first: Arc::new(Semaphore::new(1)),
            capacity,
            workers,
            max_wait_secs,
            board: Arc::default(),
        })
    }

    /// Runs `work` on the pool and resolves to its result. `work` gets the
    /// job's [`Cancel`] flag, set when this future is dropped; it should pass
    /// it to the library calls it makes.
    ///
    /// Fails at once with [`ApiError::Overloaded`] (503 + `Retry-After`) when all
    /// slots are taken, and with [`ApiError::Internal`] if `work` panics (the pool
    /// thread survives). Dropping the returned future before the job starts
    /// takes it out of the queue.
    pub async fn run<T, F>(&self, work: F) -> Result<T, ApiError>
    where
        F: FnOnce(&Cancel) -> T + Send + 'static,
        T: Send + 'static,
    {
        self.submit(work, Turn::Queue).await
    }

    /// [`CpuPool::run`] for the rare jobs that change what the service
    /// holds (loading a posted scene, unpacking it): admitted whatever the
    /// queue's expected wait (a slot is still needed), and started ahead of
    /// every queued job, one such job at a time, as soon as a worker
    /// thread is free. Under a steady load of reads, a write would
    /// otherwise be refused for as long as the load lasts.
    pub async fn run_first<T, F>(&self, work: F) -> Result<T, ApiError>
    where
        F: FnOnce(&Cancel) -> T + Send + 'static,
        T: Send + 'static,
    {
        self.submit(work, Turn::First).await
    }

    async fn submit<T, F>(&self, work: F, turn: Turn) -> Result<T, ApiError>
    where
        F: FnOnce(&Cancel) -> T + Send + 'static,
        T: Send + 'static,
    {
        // The wait of the jobs already admitted, before this one takes a slot.
        let wait = self.expected_wait_secs();
        let admitted = turn == Turn::First || wait <= self.max_wait_secs;
        let slot = match self.slots.clone().try_acquire_owned() {
            Ok(slot) if admitted => slot,
            _ => {
                ::metrics::counter!(metrics::CPU_JOBS_REJECTED).increment(1);
                return Err(ApiError::Overloaded {
                    capacity: self.capacity,
                    retry_after_secs: retry_after_secs(wait),
                });
            }
        };
        self.record_in_flight();
        let _gauge = GaugeOnDrop(self);
        // A queued job waits for a worker's permit in FIFO order; a first
        // one waits only behind the other first ones, and its task enters
        // rayon's queue at once, where the next free thread takes it before
        // any job whose permit comes later.
        let semaphore = match turn {
            Turn::Queue => &self.running,
            Turn::First => &self.first,
        };
        let turn = semaphore
            .clone()
            .acquire_owned()
            .await
            .map_err(|_| ApiError::Internal {
                message: "the CPU pool is closed".into(),
            })?;
        let cancel = Cancel::new();
        let _cancel_on_drop = CancelOnDrop(cancel.clone());
        let (reply, result) = oneshot::channel();
        let board = self.board.clone();
        self.threads.spawn(move || {
            let job = board.start();
            // A panic must not take the pool thread (or with rayon's default
            // handler, the process) down; it becomes a 500 for this request.
            let outcome = catch_unwind(AssertUnwindSafe(|| work(&cancel)));
            board.finish(job);
            // Free the worker and the slot before replying, so a caller that
            // sees its result can immediately submit again.
            drop(turn);
            drop(slot);
            let _ = reply.send(outcome);
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

    /// Running and queued jobs and the age of the oldest running one.
    pub fn status(&self) -> PoolStatus {
        let running = self.workers - self.running.available_permits();
        PoolStatus {
            running,
            queued: self.in_flight().saturating_sub(running),
            oldest_job_secs: self.board.oldest().as_secs_f64(),
        }
    }

    /// Expected wait of a job admitted now: the jobs ahead (all admitted
    /// ones) times the mean job duration, shared by the workers.
    fn expected_wait_secs(&self) -> f64 {
        self.in_flight() as f64 * self.board.mean_secs() / self.workers as f64
    }

    fn record_in_flight(&self) {
        ::metrics::gauge!(metrics::CPU_JOBS_IN_FLIGHT).set(self.in_flight() as f64);
    }
}

/// How a job waits for a worker ([`CpuPool::run`], [`CpuPool::run_first`]).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Turn {
    Queue,
    First,
}

/// `Retry-After` for an expected wait: whole seconds within bounds.
fn retry_after_secs(wait: f64) -> u64 {
    (wait.ceil() as u64).clamp(RETRY_AFTER_SECS.0, RETRY_AFTER_SECS.1)
}

/// Updates the in-flight gauge when a job's future ends, however it ends.
struct GaugeOnDrop<'a>(&'a CpuPool);

impl Drop for GaugeOnDrop<'_> {
    fn drop(&mut self) {
        self.0.record_in_flight();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;
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
            pool.run(move |_| {
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

    async fn wait_until_running(pool: &CpuPool, n: usize) {
        while pool.status().running != n {
            tokio::task::yield_now().await;
        }
    }

    #[tokio::test]
    async fn returns_the_result_of_the_work() {
        let pool = CpuPool::new(2, 4, f64::INFINITY).unwrap();
        assert_eq!(pool.run(|_| 6 * 7).await, Ok(42));
        assert_eq!(pool.in_flight(), 0);
    }

    #[tokio::test]
    async fn saturated_pool_answers_overloaded_then_recovers() {
        let pool = CpuPool::new(1, 2, f64::INFINITY).unwrap();
        let (release_a, a) = blocking_job(&pool);
        let (release_b, b) = blocking_job(&pool);
        wait_until_in_flight(&pool, 2).await;

        let err = pool.run(|_| ()).await.unwrap_err();
        assert!(matches!(err, ApiError::Overloaded { capacity: 2, .. }));
        assert_eq!(err.status(), axum::http::StatusCode::SERVICE_UNAVAILABLE);

        release_a.send(()).unwrap();
        release_b.send(()).unwrap();
        assert_eq!(a.await.unwrap(), Ok(()));
        assert_eq!(b.await.unwrap(), Ok(()));
        assert_eq!(pool.run(|_| 1).await, Ok(1));
    }

    #[tokio::test]
    async fn retry_after_grows_with_the_backlog() {
        let pool = CpuPool::new(1, 3, f64::INFINITY).unwrap();
        // Teach the pool that jobs take about 4 s.
        pool.board
            .mean_secs
            .store(4f64.to_bits(), Ordering::Relaxed);
        let jobs: Vec<_> = (0..3).map(|_| blocking_job(&pool)).collect();
        wait_until_in_flight(&pool, 3).await;
        let Err(ApiError::Overloaded {
            retry_after_secs, ..
        }) = pool.run(|_| ()).await
        else {
            panic!("a full pool answers overloaded");
        };
        // Three jobs ahead of 4 s each on one worker.
        assert_eq!(retry_after_secs, 12);
        for (release, handle) in jobs {
            release.send(()).unwrap();
            handle.await.unwrap().unwrap();
        }
    }

    #[tokio::test]
    async fn a_long_expected_wait_refuses_new_jobs() {
        let pool = CpuPool::new(1, 8, 5.0).unwrap();
        pool.board
            .mean_secs
            .store(2f64.to_bits(), Ordering::Relaxed);
        let (release_a, a) = blocking_job(&pool);
        let (release_b, b) = blocking_job(&pool);
        wait_until_in_flight(&pool, 2).await;
        // Two jobs of 2 s ahead on one worker: 4 s, still admitted.
        let (release_c, c) = blocking_job(&pool);
        wait_until_in_flight(&pool, 3).await;
        // Three ahead: 6 s > 5 s, refused with that wait as Retry-After.
        let err = pool.run(|_| ()).await.unwrap_err();
        assert!(matches!(
            err,
            ApiError::Overloaded {
                retry_after_secs: 6,
                ..
            }
        ));
        for (release, handle) in [(release_a, a), (release_b, b), (release_c, c)] {
            release.send(()).unwrap();
            handle.await.unwrap().unwrap();
        }
    }

    /// A write under a steady load of reads: admitted though the queue's
    /// wait is past the limit, and run before the reads queued ahead of it.
    #[tokio::test]
    async fn a_first_job_is_admitted_and_runs_ahead_of_the_queue() {
        let pool = CpuPool::new(1, 8, 3.0).unwrap();
        pool.board
            .mean_secs
            .store(2f64.to_bits(), Ordering::Relaxed);
        let (release_a, a) = blocking_job(&pool);
        wait_until_running(&pool, 1).await;
        let order = Arc::new(Mutex::new(Vec::new()));
        let queued = {
            let (pool, order) = (pool.clone(), order.clone());
            tokio::spawn(async move { pool.run(move |_| order.lock().unwrap().push("read")).await })
        };
        // One job of 2 s ahead: admitted.
        wait_until_in_flight(&pool, 2).await;
        // Two jobs of 2 s ahead on one worker: a read is refused ...
        assert!(matches!(
            pool.run(|_| ()).await,
            Err(ApiError::Overloaded { .. })
        ));
        // ... a write is not, and runs first once the worker is free.
        let first = {
            let (pool, order) = (pool.clone(), order.clone());
            tokio::spawn(async move {
                pool.run_first(move |_| order.lock().unwrap().push("write"))
                    .await
            })
        };
        wait_until_in_flight(&pool, 3).await;
        release_a.send(()).unwrap();
        a.await.unwrap().unwrap();
        first.await.unwrap().unwrap();
        queued.await.unwrap().unwrap();
        assert_eq!(*order.lock().unwrap(), ["write", "read"]);
    }

    #[tokio::test]
    async fn jobs_run_one_per_worker_in_arrival_order() {
        let pool = CpuPool::new(1, 8, f64::INFINITY).unwrap();
        let (release, first) = blocking_job(&pool);
        wait_until_running(&pool, 1).await;
        let order = Arc::new(Mutex::new(Vec::new()));
        let mut later = Vec::new();
        for k in 0..5 {
            let (job_pool, order) = (pool.clone(), order.clone());
            later.push(tokio::spawn(async move {
                job_pool.run(move |_| order.lock().unwrap().push(k)).await
            }));
            // Each waits in the queue before the next arrives.
            wait_until_in_flight(&pool, k + 2).await;
        }
        let status = pool.status();
        assert_eq!((status.running, status.queued), (1, 5));
        release.send(()).unwrap();
        first.await.unwrap().unwrap();
        for handle in later {
            handle.await.unwrap().unwrap();
        }
        assert_eq!(*order.lock().unwrap(), vec![0, 1, 2, 3, 4]);
    }

    #[tokio::test]
    async fn abandoned_queued_job_is_skipped_and_frees_its_slot() {
        let pool = CpuPool::new(1, 3, f64::INFINITY).unwrap();
        let (release, running) = blocking_job(&pool);
        wait_until_in_flight(&pool, 1).await;

        let ran = Arc::new(AtomicBool::new(false));
        let flag = ran.clone();
        let queued_pool = pool.clone();
        let queued = tokio::spawn(async move {
            queued_pool
                .run(move |_| flag.store(true, Ordering::SeqCst))
                .await
        });
        wait_until_in_flight(&pool, 2).await;
        queued.abort();
        assert!(queued.await.unwrap_err().is_cancelled());
        assert_eq!(pool.in_flight(), 1);

        release.send(()).unwrap();
        running.await.unwrap().unwrap();
        pool.run(|_| ()).await.unwrap();
        assert!(!ran.load(Ordering::SeqCst), "abandoned job must not run");
        assert_eq!(pool.in_flight(), 0);
    }

    #[tokio::test]
    async fn abandoning_a_running_job_cancels_it() {
        let pool = CpuPool::new(1, 2, f64::INFINITY).unwrap();
        let (saw_cancel, seen) = mpsc::channel();
        let job_pool = pool.clone();
        let job = tokio::spawn(async move {
            job_pool
                .run(move |cancel| {
                    while !cancel.is_cancelled() {
                        std::thread::sleep(Duration::from_millis(1));
                    }
                    saw_cancel.send(()).unwrap();
                })
                .await
        });
        wait_until_running(&pool, 1).await;
        assert!(pool.status().oldest_job_secs >= 0.0);
        job.abort();
        let _ = job.await;
        // The job sees its flag and ends; the worker is free again.
        tokio::task::spawn_blocking(move || seen.recv().unwrap())
            .await
            .unwrap();
        assert_eq!(pool.run(|_| 3).await, Ok(3));
        assert_eq!(pool.status().running, 0);
    }

    #[tokio::test]
    async fn panicking_job_is_an_internal_error_and_the_pool_survives() {
        let pool = CpuPool::new(1, 1, f64::INFINITY).unwrap();
        let err = pool.run(|_| -> u32 { panic!("boom") }).await.unwrap_err();
        assert_eq!(err.status(), axum::http::StatusCode::INTERNAL_SERVER_ERROR);
        assert!(err.to_string().contains("boom"));
        assert_eq!(pool.run(|_| 5).await, Ok(5));
    }
}

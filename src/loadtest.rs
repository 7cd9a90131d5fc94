//! Closed-loop HTTP load generator for the service (`bmc-irradiance loadtest`).
//!
//! `clients` async tasks each send one request, wait for the answer, and send
//! the next, until `duration` has passed (closed loop: the offered load adapts to
//! the server's speed, so the measured latency is the service's, not a queue's
//! in the generator). Latencies go into one HDR histogram per client (merged at
//! the end, so clients never contend on a lock). Only loopback URLs are accepted:
//! this tool measures our own service, it is not a traffic generator for others.
//!
//! Scenarios and their request shapes:
//! - `health`: `GET /health` (measures the HTTP stack alone);
//! - `points`: `POST /v1/scenes/{scene}/irradiance` with `points_per_request`
//!   points on the Cornell box floor (y = -1, normal +y), BMC with `samples` samples;
//! - `tiles`: `POST /v1/scenes/{scene}/tiles`, `tile_size`² JSON tiles walking a
//!   256 × 256 image;
//! - `mixed`: each client alternates points and tiles.
//!
//! With `server_pid`, the server's resident set size (`VmRSS` in
//! `/proc/<pid>/status`) is sampled every 200 ms, to check that memory stays flat.

use std::collections::BTreeMap;
use std::fmt;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use hdrhistogram::Histogram;
use serde::Serialize;
use serde_json::{Value, json};

/// Largest accepted number of concurrent clients.
pub const MAX_CLIENTS: usize = 4096;
/// Longest accepted run.
pub const MAX_DURATION: Duration = Duration::from_secs(3600);
/// Side of the square image the `tiles` scenario walks (the Cornell box film size).
const IMAGE_SIDE: u32 = 256;
/// Slowest latency the histograms can hold, in microseconds (one minute).
const MAX_LATENCY_US: u64 = 60_000_000;

/// Which requests the clients send.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Scenario {
    Health,
    Points,
    Tiles,
    Mixed,
}

/// What to run.
#[derive(Debug, Clone)]
pub struct LoadTestOptions {
    /// Base URL of the service, e.g. `http://127.0.0.1:8080` (loopback only).
    pub url: String,
    /// Concurrent closed-loop clients, 1..=[`MAX_CLIENTS`].
    pub clients: usize,
    /// How long clients keep sending, at most [`MAX_DURATION`].
    pub duration: Duration,
    pub scenario: Scenario,
    /// Scene id for the `points`, `tiles` and `mixed` scenarios.
    pub scene: String,
    /// Shading points per `points` request.
    pub points_per_request: usize,
    /// Hemisphere samples per estimate (BMC).
    pub samples: usize,
    /// Tile side in pixels for `tiles`.
    pub tile_size: u32,
    /// Process id of the server, to sample its RSS.
    pub server_pid: Option<u32>,
}

/// Latency percentiles in milliseconds.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Latency {
    pub p50_ms: f64,
    pub p95_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

/// Server resident set size over the run, in KiB.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Rss {
    pub start_kib: u64,
    pub max_kib: u64,
    pub end_kib: u64,
}

/// The outcome of a run.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub scenario: Scenario,
    pub clients: usize,
    /// Wall-clock time from first request to last answer, in seconds.
    pub elapsed_s: f64,
    /// Answered requests (any status).
    pub requests: u64,
    /// Answered requests per second.
    pub throughput_rps: f64,
    pub latency: Latency,
    /// Answers with a 2xx status.
    pub ok: u64,
    /// Answers with 503 (deliberate back-pressure).
    pub overloaded: u64,
    /// Answers with any other status, by status.
    pub other_statuses: BTreeMap<u16, u64>,
    /// Requests that got no HTTP answer (connection or timeout errors).
    pub transport_errors: u64,
    pub server_rss: Option<Rss>,
}

impl Report {
    /// Errors other than deliberate 503s.
    pub fn errors(&self) -> u64 {
        self.other_statuses.values().sum::<u64>() + self.transport_errors
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let l = &self.latency;
        writeln!(
            f,
            "scenario {:?}, {} clients, {:.1} s: {} requests, {:.1} req/s",
            self.scenario, self.clients, self.elapsed_s, self.requests, self.throughput_rps
        )?;
        writeln!(
            f,
            "latency ms: p50 {:.2}  p95 {:.2}  p99 {:.2}  max {:.2}",
            l.p50_ms, l.p95_ms, l.p99_ms, l.max_ms
        )?;
        write!(
            f,
            "status: 2xx {}  503 {}  other {:?}  transport errors {}",
            self.ok, self.overloaded, self.other_statuses, self.transport_errors
        )?;
        if let Some(rss) = &self.server_rss {
            write!(
                f,
                "\nserver RSS KiB: start {}  max {}  end {}",
                rss.start_kib, rss.max_kib, rss.end_kib
            )?;
        }
        Ok(())
    }
}

/// Per-client tallies, merged at the end.
struct Tally {
    latency_us: Histogram<u64>,
    statuses: BTreeMap<u16, u64>,
    transport_errors: u64,
}

impl Tally {
    fn new() -> Tally {
        Tally {
            latency_us: Histogram::new_with_bounds(1, MAX_LATENCY_US, 3)
                .expect("constant histogram bounds are valid"),
            statuses: BTreeMap::new(),
            transport_errors: 0,
        }
    }
}

/// Arguments of `bmc-loadtest`.
#[derive(Debug, clap::Args)]
pub struct LoadTestArgs {
    /// Base URL of the service (loopback only).
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// Concurrent closed-loop clients.
    #[arg(long, default_value_t = 8)]
    pub clients: usize,
    /// How long to send requests, e.g. 30s, 500ms, 2m.
    #[arg(long, default_value = "10s", value_parser = humantime::parse_duration)]
    pub duration: Duration,
    #[arg(long, value_enum, default_value = "health")]
    pub scenario: Scenario,
    /// Scene id used by the points, tiles and mixed scenarios.
    #[arg(long, default_value = "cornell-box")]
    pub scene: String,
    /// Shading points per points request.
    #[arg(long, default_value_t = 16)]
    pub points_per_request: usize,
    /// Hemisphere samples per estimate.
    #[arg(long, default_value_t = 64)]
    pub samples: usize,
    /// Tile side in pixels.
    #[arg(long, default_value_t = 32)]
    pub tile_size: u32,
    /// Sample this process's resident memory (Linux /proc) during the run.
    #[arg(long)]
    pub server_pid: Option<u32>,
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `loadtest`: runs the load test and prints the report on stdout.
pub fn run_loadtest(args: &LoadTestArgs) -> anyhow::Result<()> {
    let options = LoadTestOptions {
        url: args.url.clone(),
        clients: args.clients,
        duration: args.duration,
        scenario: args.scenario,
        scene: args.scene.clone(),
        points_per_request: args.points_per_request,
        samples: args.samples,
        tile_size: args.tile_size,
        server_pid: args.server_pid,
    };
    let report = tokio::runtime::Runtime::new()?.block_on(run(&options))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{report}");
    }
    Ok(())
}

/// Validates the options and runs the load test to completion.
pub async fn run(options: &LoadTestOptions) -> anyhow::Result<Report> {
    let base = check_options(options)?;
    let client = reqwest::Client::builder()
        .pool_max_idle_per_host(options.clients)
        .timeout(Duration::from_secs(120))
        .build()
        .context("cannot build the HTTP client")?;

    let (stop_sampling, sampling_stopped) = tokio::sync::oneshot::channel();
    let rss_sampler = options
        .server_pid
        .map(|pid| tokio::spawn(sample_rss(pid, sampling_stopped)));
    let start = Instant::now();
    let stop_at = start + options.duration;
    let workers: Vec<_> = (0..options.clients)
        .map(|client_index| {
            let client = client.clone();
            let base = base.clone();
            let options = options.clone();
            tokio::spawn(async move { drive(client, base, options, client_index, stop_at).await })
        })
        .collect();
    let mut total = Tally::new();
    for worker in workers {
        let tally = worker.await.context("a load-test client panicked")?;
        total
            .latency_us
            .add(&tally.latency_us)
            .context("merging latency histograms")?;
        for (status, n) in tally.statuses {
            *total.statuses.entry(status).or_default() += n;
        }
        total.transport_errors += tally.transport_errors;
    }
    let elapsed = start.elapsed();
    let _ = stop_sampling.send(());
    let server_rss = match rss_sampler {
        Some(sampler) => Some(sampler.await.context("the RSS sampler panicked")??),
        None => None,
    };
    Ok(report(options, total, elapsed, server_rss))
}

fn report(
    options: &LoadTestOptions,
    total: Tally,
    elapsed: Duration,
    server_rss: Option<Rss>,
) -> Report {
    let ms = |us: u64| us as f64 / 1000.0;
    let h = &total.latency_us;
    let answered: u64 = total.statuses.values().sum();
    let ok = total
        .statuses
        .iter()
        .filter(|(s, _)| (200..300).contains(*s))
        .map(|(_, n)| n)
        .sum();
    let overloaded = total.statuses.get(&503).copied().unwrap_or(0);
    let other_statuses = total
        .statuses
        .into_iter()
        .filter(|(s, _)| !(200..300).contains(s) && *s != 503)
        .collect();
    Report {
        scenario: options.scenario,
        clients: options.clients,
        elapsed_s: elapsed.as_secs_f64(),
        requests: answered,
        throughput_rps: answered as f64 / elapsed.as_secs_f64(),
        latency: Latency {
            p50_ms: ms(h.value_at_quantile(0.50)),
            p95_ms: ms(h.value_at_quantile(0.95)),
            p99_ms: ms(h.value_at_quantile(0.99)),
            max_ms: ms(h.max()),
        },
        ok,
        overloaded,
        other_statuses,
        transport_errors: total.transport_errors,
        server_rss,
    }
}

/// Checks limits and that the URL is loopback; returns the base URL without a trailing `/`.
fn check_options(options: &LoadTestOptions) -> anyhow::Result<String> {
    if !(1..=MAX_CLIENTS).contains(&options.clients) {
        bail!("--clients must be between 1 and {MAX_CLIENTS}");
    }
    if options.duration.is_zero() || options.duration > MAX_DURATION {
        bail!("--duration must be positive and at most {MAX_DURATION:?}");
    }
    if options.points_per_request == 0 || options.samples == 0 || options.tile_size == 0 {
        bail!("--points-per-request, --samples and --tile-size must be positive");
    }
    let url =
        reqwest::Url::parse(&options.url).with_context(|| format!("bad --url {}", options.url))?;
    if url.scheme() != "http" {
        bail!("--url must be plain http, got {}", url.scheme());
    }
    let loopback = match url.host() {
        Some(url::Host::Domain(name)) => name == "localhost",
        Some(url::Host::Ipv4(ip)) => ip.is_loopback(),
        Some(url::Host::Ipv6(ip)) => ip.is_loopback(),
        None => false,
    };
    if !loopback {
        bail!("--url must point at this machine (127.0.0.1, ::1 or localhost)");
    }
    Ok(options.url.trim_end_matches('/').to_owned())
}

/// One closed-loop client: request, wait, record, repeat until `stop_at`.
async fn drive(
    client: reqwest::Client,
    base: String,
    options: LoadTestOptions,
    client_index: usize,
    stop_at: Instant,
) -> Tally {
    let mut tally = Tally::new();
    let mut sequence = 0u64;
    while Instant::now() < stop_at {
        let request = match next_request(&options, client_index, sequence) {
            Planned::Get(path) => client.get(format!("{base}{path}")),
            Planned::Post(path, body) => client.post(format!("{base}{path}")).json(&body),
        };
        let sent = Instant::now();
        let outcome = match request.send().await {
            // Read the whole body: the latency includes serialising and transferring it.
            Ok(response) => {
                let status = response.status().as_u16();
                let retry_after = retry_after(&response);
                response.bytes().await.map(|_| (status, retry_after))
            }
            Err(err) => Err(err),
        };
        match outcome {
            Ok((status, retry_after)) => {
                let us = (sent.elapsed().as_micros() as u64).clamp(1, MAX_LATENCY_US);
                tally.latency_us.saturating_record(us);
                *tally.statuses.entry(status).or_default() += 1;
                // Back-pressure: wait as the service asks before the next request.
                if let Some(wait) = retry_after {
                    let left = stop_at.saturating_duration_since(Instant::now());
                    tokio::time::sleep(wait.min(left)).await;
                }
            }
            Err(_) => tally.transport_errors += 1,
        }
        sequence += 1;
    }
    tally
}

/// The `Retry-After` of a 503, in whole seconds as the service sends it.
fn retry_after(response: &reqwest::Response) -> Option<Duration> {
    if response.status() != reqwest::StatusCode::SERVICE_UNAVAILABLE {
        return None;
    }
    let secs = response
        .headers()
        .get(reqwest::header::RETRY_AFTER)?
        .to_str()
        .ok()?
        .trim()
        .parse()
        .ok()?;
    Some(Duration::from_secs(secs))
}

enum Planned {
    Get(&'static str),
    Post(String, Value),
}

/// The `sequence`-th request of client `client_index`; deterministic, so runs are repeatable.
fn next_request(options: &LoadTestOptions, client_index: usize, sequence: u64) -> Planned {
    let scene = &options.scene;
    let seed = (client_index as u64) << 32 | sequence;
    let points = |seed| {
        Planned::Post(
            format!("/v1/scenes/{scene}/irradiance"),
            points_body(options.points_per_request, options.samples, seed),
        )
    };
    let tile = |index| {
        Planned::Post(
            format!("/v1/scenes/{scene}/tiles"),
            tile_body(options.tile_size, options.samples, index),
        )
    };
    match options.scenario {
        Scenario::Health => Planned::Get("/health"),
        Scenario::Points => points(seed),
        Scenario::Tiles => tile(seed),
        Scenario::Mixed if sequence.is_multiple_of(2) => points(seed),
        Scenario::Mixed => tile(seed),
    }
}

/// Points on a regular grid over the Cornell box floor (y = -1, normal +y).
fn points_body(count: usize, samples: usize, seed: u64) -> Value {
    let side = (count as f64).sqrt().ceil() as usize;
    let coordinate = |i: usize| -0.9 + 1.8 * (i as f64 + 0.5) / side as f64;
    let points: Vec<Value> = (0..count)
        .map(|i| json!({"position": [coordinate(i % side), -1.0, coordinate(i / side)], "normal": [0.0, 1.0, 0.0]}))
        .collect();
    json!({
        "points": points,
        "estimator": {"method": "bmc", "samples": samples},
        "max_depth": 16,
        "seed": seed,
    })
}

/// The `index`-th tile (modulo the tiles of a 256 × 256 image) as a JSON tile request.
fn tile_body(tile_size: u32, samples: usize, index: u64) -> Value {
    let size = tile_size.min(IMAGE_SIDE);
    let per_row = IMAGE_SIDE / size;
    let index = (index % u64::from(per_row * per_row)) as u32;
    json!({
        "x": (index % per_row) * size,
        "y": (index / per_row) * size,
        "width": size,
        "height": size,
        "format": "json",
        "estimator": {"method": "cache", "samples": samples},
        "samples_per_pixel": 1,
    })
}

/// Samples the RSS of `pid` every 200 ms until `stop` fires.
async fn sample_rss(pid: u32, mut stop: tokio::sync::oneshot::Receiver<()>) -> anyhow::Result<Rss> {
    let start_kib = read_rss_kib(pid).await?;
    let mut max_kib = start_kib;
    let mut tick = tokio::time::interval(Duration::from_millis(200));
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = tick.tick() => max_kib = max_kib.max(read_rss_kib(pid).await?),
        }
    }
    let end_kib = read_rss_kib(pid).await?;
    Ok(Rss {
        start_kib,
        max_kib: max_kib.max(end_kib),
        end_kib,
    })
}

/// `VmRSS` of `pid` in KiB, from `/proc/<pid>/status` (Linux).
async fn read_rss_kib(pid: u32) -> anyhow::Result<u64> {
    let path = format!("/proc/{pid}/status");
    let status = tokio::fs::read_to_string(&path)
        .await
        .with_context(|| format!("cannot read {path} (is --server-pid right?)"))?;
    parse_vm_rss(&status).with_context(|| format!("no VmRSS line in {path}"))
}

fn parse_vm_rss(status: &str) -> Option<u64> {
    status
        .lines()
        .find_map(|line| line.strip_prefix("VmRSS:"))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|kib| kib.parse().ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(url: &str) -> LoadTestOptions {
        LoadTestOptions {
            url: url.into(),
            clients: 2,
            duration: Duration::from_secs(1),
            scenario: Scenario::Health,
            scene: "cornell-box".into(),
            points_per_request: 16,
            samples: 64,
            tile_size: 32,
            server_pid: None,
        }
    }

    #[test]
    fn only_loopback_http_urls_are_accepted() {
        for url in [
            "http://127.0.0.1:8080",
            "http://localhost:1/",
            "http://[::1]:80",
        ] {
            assert!(check_options(&options(url)).is_ok(), "{url}");
        }
        for url in [
            "http://10.0.0.1:8080",
            "http://example.com",
            "https://127.0.0.1",
            "nonsense",
        ] {
            assert!(check_options(&options(url)).is_err(), "{url}");
        }
    }

    #[test]
    fn client_count_and_duration_are_bounded() {
        let mut o = options("http://127.0.0.1:8080");
        o.clients = 0;
        assert!(check_options(&o).is_err());
        o.clients = MAX_CLIENTS + 1;
        assert!(check_options(&o).is_err());
        o.clients = 1;
        o.duration = MAX_DURATION + Duration::from_secs(1);
        assert!(check_options(&o).is_err());
    }

    #[test]
    fn points_lie_on_the_floor_and_tiles_inside_the_image() {
        let body = points_body(10, 64, 3);
        let points = body["points"].as_array().unwrap();
        assert_eq!(points.len(), 10);
        for p in points {
            let pos = p["position"].as_array().unwrap();
            assert_eq!(pos[1], -1.0);
            for c in [&pos[0], &pos[2]] {
                assert!(c.as_f64().unwrap().abs() < 1.0);
            }
        }
        for index in 0..200 {
            let tile = tile_body(48, 64, index);
            let x = tile["x"].as_u64().unwrap() + tile["width"].as_u64().unwrap();
            let y = tile["y"].as_u64().unwrap() + tile["height"].as_u64().unwrap();
            assert!(x <= u64::from(IMAGE_SIDE) && y <= u64::from(IMAGE_SIDE));
        }
    }

    #[test]
    fn vm_rss_is_parsed_in_kib() {
        let status = "Name:\tbmc\nVmPeak:\t  9000 kB\nVmRSS:\t  1234 kB\nThreads: 4\n";
        assert_eq!(parse_vm_rss(status), Some(1234));
        assert_eq!(parse_vm_rss("Name: x\n"), None);
    }
}

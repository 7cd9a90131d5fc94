//! Service overhead: BMC point queries (N = 64) computed in-process through the
//! library versus the same requests through the running HTTP service, on the
//! same number of CPU threads.
//!
//! `cargo run --release --example service_overhead -- [threads] [rounds]`
//! (defaults: 2 threads, 30 rounds). Each round sends one request of 256
//! points on the bundled Cornell box (fixed seed, split mode, `max_depth` 4,
//! SE kernel ℓ = 0.5, noise 1e-3, GLS prior mean) both ways, alternating, so
//! that load from other processes affects both equally. The in-process side
//! does what the service's CPU job does — cache lookup of the weights, the
//! estimator, `HemisphereRule::estimate` on a rayon pool of `threads`
//! threads — while the service side adds JSON encoding, HTTP on loopback,
//! validation, the CPU-pool hand-off and JSON decoding in the client.
//! It also times the first request with `"lengthscale": "auto"` (which fits
//! the lengthscale for the scene) against a repeated one.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use bmc_irradiance::bmc::cache::QuadratureCache;
use bmc_irradiance::bmc::estimator::{BayesianEstimator, BmcVariance};
use bmc_irradiance::bmc::report::QuadratureSpec;
use bmc_irradiance::bmc::{Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use bmc_irradiance::estimators::HemisphereRule;
use bmc_irradiance::render::Cancel;
use bmc_irradiance::render::environment_prior::PriorChoice;
use bmc_irradiance::render::{
    IrradianceMethod, IrradianceOptions, PathDepth, QueryPoint, Transport,
};
use bmc_irradiance::scene::Scene;
use bmc_irradiance::service::{Application, Config};
use bmc_irradiance::sphere::{SampleSetKind, SampleSetSpec};
use glam::DVec3;
use serde_json::json;

const SAMPLES: u32 = 64;
const LENGTHSCALE: f64 = 0.5;
const NOISE: f64 = 1e-3;
const MAX_DEPTH: PathDepth = PathDepth::constant(4);
const SEED: u64 = 1;

/// 16 × 16 points on the Cornell box's back wall, facing into the box.
fn points() -> Vec<[f64; 3]> {
    (0..256)
        .map(|i| {
            let (u, v) = ((i % 16) as f64 / 15.0, (i / 16) as f64 / 15.0);
            [-0.9 + 1.8 * u, -0.9 + 1.8 * v, -0.999]
        })
        .collect()
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let threads: usize = args.next().map_or(Ok(2), |a| a.parse())?;
    let rounds: usize = args.next().map_or(Ok(30), |a| a.parse())?;
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");

    // In-process.
    let transport = Transport::new(Arc::new(Scene::load(
        &scenes.join("cornell-box.json"),
        &scenes,
    )?));
    let query: Vec<QueryPoint> = points()
        .into_iter()
        .map(|p| QueryPoint::new(DVec3::from(p), DVec3::Z))
        .collect::<Result<_, _>>()?;
    let cache = QuadratureCache::new(64 << 20);
    let spec = QuadratureSpec {
        sample_set: SampleSetSpec {
            kind: SampleSetKind::FibonacciCosine,
            count: SAMPLES as usize,
            seed: 0,
        },
        kernel: Kernel::new(KernelKind::SquaredExponential, LENGTHSCALE, 1.0, NOISE)?,
        density: Density::Lambert,
        prior_mean: PriorMean::Gls,
        kernel_mean: KernelMeanMethod::Exact,
    };
    let options = IrradianceOptions {
        samples: SAMPLES,
        light_samples: None,
        max_depth: MAX_DEPTH,
        direct_only: false,
        method: IrradianceMethod::Split,
        seed: SEED,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let in_process = || -> anyhow::Result<Duration> {
        let start = Instant::now();
        let (quadrature, _) = spec.quadrature(&cache)?;
        let estimator = BayesianEstimator::new(quadrature, BmcVariance::AmplitudeFit);
        let estimates = pool.install(|| {
            HemisphereRule {
                estimator: &estimator,
                prior: PriorChoice::None,
                indirect_part: false,
            }
            .estimate(&transport, &query, &options, &|| {}, &Cancel::never())
        })?;
        std::hint::black_box(estimates);
        Ok(start.elapsed())
    };

    // Through the service, same CPU thread count.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()?;
    let mut config = Config::default_config();
    config.server.bind = "127.0.0.1:0".parse()?;
    config.server.worker_threads = threads;
    config.scenes.dir = scenes.clone();
    let app = runtime.block_on(Application::build(config))?;
    let url = format!(
        "http://{}/v1/scenes/cornell-box/irradiance",
        app.local_addr()
    );
    runtime.spawn(app.run_until_stopped(std::future::pending()));
    let client = reqwest::Client::new();
    let body = json!({
        "points": points().iter().map(|p| json!({"position": p, "normal": [0, 0, 1]})).collect::<Vec<_>>(),
        "estimator": {"method": "bmc", "samples": SAMPLES, "decomposition": "split",
                      "kernel": {"lengthscale": LENGTHSCALE, "noise": NOISE}},
        "max_depth": MAX_DEPTH,
        "seed": SEED,
    });
    let via_service = || -> anyhow::Result<Duration> {
        runtime.block_on(async {
            let start = Instant::now();
            let response = client.post(&url).json(&body).send().await?;
            anyhow::ensure!(response.status().is_success(), "{}", response.status());
            let value: serde_json::Value = response.json().await?;
            std::hint::black_box(value);
            Ok(start.elapsed())
        })
    };

    // Warm-up: factorisation, caches, connections.
    in_process()?;
    via_service()?;
    // The cost of `"lengthscale": "auto"`: the first request fits, the next reuses.
    let mut auto_body = body.clone();
    auto_body["estimator"]["kernel"] = json!({"lengthscale": "auto"});
    let auto_request = || -> anyhow::Result<(Duration, f64)> {
        runtime.block_on(async {
            let start = Instant::now();
            let response = client.post(&url).json(&auto_body).send().await?;
            let value: serde_json::Value = response.json().await?;
            let lengthscale = value["lengthscale"].as_f64().unwrap_or(f64::NAN);
            Ok((start.elapsed(), lengthscale))
        })
    };
    let (first_auto, lengthscale) = auto_request()?;
    let (second_auto, _) = auto_request()?;
    let (mut local, mut remote) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        local.push(in_process()?);
        remote.push(via_service()?);
    }
    let ms = |d: &[Duration]| {
        let mut v: Vec<f64> = d.iter().map(|d| d.as_secs_f64() * 1e3).collect();
        v.sort_by(f64::total_cmp);
        (v.iter().sum::<f64>() / v.len() as f64, v[v.len() / 2])
    };
    let ((local_mean, local_median), (remote_mean, remote_median)) = (ms(&local), ms(&remote));
    println!("threads {threads}, {rounds} rounds of 256 points, BMC N = {SAMPLES}");
    println!("in-process  mean {local_mean:8.2} ms  median {local_median:8.2} ms");
    println!("service     mean {remote_mean:8.2} ms  median {remote_median:8.2} ms");
    println!(
        "ratio       mean {:.3}  median {:.3}",
        remote_mean / local_mean,
        remote_median / local_median
    );
    println!(
        "\"auto\" lengthscale {lengthscale:.4}: first request (fit + weights) {:.1} ms, repeated {:.1} ms",
        first_auto.as_secs_f64() * 1e3,
        second_auto.as_secs_f64() * 1e3
    );
    Ok(())
}

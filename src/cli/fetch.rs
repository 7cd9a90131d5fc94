//! `bmc-irradiance fetch`: a whole camera image from a running service,
//! assembled from its GET tiles (`/v1/scenes/{id}/tiles/{tx}/{ty}.exr`),
//! several at a time, retrying what is retryable: 503 after its
//! `Retry-After`, 504 and connection failures after a short backoff.

use std::io::Write;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use serde::Deserialize;

use super::render::ImageOutput;
use crate::image::Image;
use crate::image::exr_io::decode_exr;
use crate::integrator::Preset;

/// Command-line arguments of `bmc-irradiance fetch`.
#[derive(Clone, Debug, clap::Args)]
pub struct FetchArgs {
    /// Base URL of the service.
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// Scene id on the service.
    #[arg(long)]
    pub scene: String,
    /// Quality preset.
    #[arg(long, value_enum, default_value_t = Preset::default())]
    pub preset: Preset,
    /// Pass to fetch (0-based; default the preset's last, its final image).
    #[arg(long)]
    pub pass: Option<u32>,
    /// Tile side in pixels.
    #[arg(long, default_value_t = 64)]
    pub size: u32,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Ask for denoised tiles (the GET tiles' `denoise=true`).
    #[arg(long)]
    pub denoise: bool,
    #[command(flatten)]
    pub output: ImageOutput,
    /// Tiles requested at once (about the service's worker count keeps
    /// its queue short).
    #[arg(long, default_value_t = 2)]
    pub concurrency: usize,
    /// Attempts per tile after a 504 or a connection failure before giving
    /// up; a 503 (busy) is retried after its `Retry-After` without counting.
    #[arg(long, default_value_t = 5)]
    pub attempts: u32,
}

/// What `GET /v1/scenes/{id}` tells that is needed here.
#[derive(Deserialize)]
struct SceneInfo {
    /// Camera image `[width, height]`.
    resolution: [u32; 2],
}

/// Runs `fetch`, printing a summary on `out`.
pub fn run_fetch(args: &FetchArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    if args.size == 0 || args.concurrency == 0 || args.attempts == 0 {
        bail!("--size, --concurrency and --attempts must be at least 1");
    }
    let started = Instant::now();
    let (image, rays) = tokio::runtime::Runtime::new()?.block_on(fetch(args))?;
    let elapsed = started.elapsed();
    args.output.write(&image)?;
    writeln!(
        out,
        "{}×{} image of {} ({} preset) in {:.2} s; the service traced {rays} rays for it",
        image.width(),
        image.height(),
        args.scene,
        args.preset,
        elapsed.as_secs_f64()
    )?;
    Ok(())
}

async fn fetch(args: &FetchArgs) -> anyhow::Result<(Image, u64)> {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(120))
        .build()?;
    let base = args.url.trim_end_matches('/');
    let scene_url = format!("{base}/v1/scenes/{}", args.scene);
    let response = client
        .get(&scene_url)
        .send()
        .await
        .with_context(|| format!("cannot reach {scene_url}"))?;
    let info: SceneInfo = ok_or_service_error(response, &scene_url)
        .await?
        .json()
        .await?;
    let [width, height] = info.resolution;
    let tiles: Vec<(u32, u32)> = (0..height.div_ceil(args.size))
        .flat_map(|ty| (0..width.div_ceil(args.size)).map(move |tx| (tx, ty)))
        .collect();
    let mut query = format!(
        "size={}&preset={}&seed={}",
        args.size, args.preset, args.seed
    );
    if args.denoise {
        query.push_str("&denoise=true");
    }
    if let Some(pass) = args.pass {
        query.push_str(&format!("&pass={pass}"));
    }
    let semaphore = std::sync::Arc::new(tokio::sync::Semaphore::new(args.concurrency));
    let mut jobs = tokio::task::JoinSet::new();
    for (tx, ty) in tiles {
        let (client, semaphore) = (client.clone(), semaphore.clone());
        let url = format!("{scene_url}/tiles/{tx}/{ty}.exr?{query}");
        let attempts = args.attempts;
        jobs.spawn(async move {
            let _permit = semaphore.acquire_owned().await?;
            let (bytes, rays) = get_with_retries(&client, &url, attempts).await?;
            anyhow::Ok((tx, ty, decode_exr(&bytes)?, rays))
        });
    }
    let mut image = Image::black(width, height)?;
    let mut rays = 0;
    while let Some(done) = jobs.join_next().await {
        let (tx, ty, tile, tile_rays) = done??;
        image.insert(&tile, tx * args.size, ty * args.size)?;
        rays += tile_rays;
    }
    Ok((image, rays))
}

/// `response` if it is a success, else [`service_error`].
async fn ok_or_service_error(
    response: reqwest::Response,
    url: &str,
) -> anyhow::Result<reqwest::Response> {
    if response.status().is_success() {
        Ok(response)
    } else {
        Err(service_error(response, "GET", url).await)
    }
}

/// A failed answer as an error carrying the service's own message (its JSON
/// error body: message and field) rather than the bare status line.
pub(super) async fn service_error(
    response: reqwest::Response,
    method: &str,
    url: &str,
) -> anyhow::Error {
    let status = response.status();
    let text = response.text().await.unwrap_or_default();
    let said = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|body| {
            let error = body.get("error")?;
            let message = error.get("message")?.as_str()?.to_owned();
            Some(match error.get("field").and_then(|f| f.as_str()) {
                Some(field) => format!("{message} (field `{field}`)"),
                None => message,
            })
        })
        .unwrap_or(text);
    anyhow::anyhow!("{method} {url}: the service answered {status}: {said}")
}

/// Most 503 answers taken for one tile (each waits its `Retry-After`).
const MAX_BUSY_ANSWERS: u32 = 120;

/// The body of a GET and its `x-rays`, retrying 504 and transport failures
/// up to `attempts` times in all, and 503 after its `Retry-After` (up to
/// [`MAX_BUSY_ANSWERS`] times).
async fn get_with_retries(
    client: &reqwest::Client,
    url: &str,
    attempts: u32,
) -> anyhow::Result<(Vec<u8>, u64)> {
    let mut backoff = Duration::from_millis(250);
    let (mut attempt, mut busy) = (1, 0);
    loop {
        let last = attempt >= attempts;
        match client.get(url).send().await {
            Ok(response) if response.status().is_success() => {
                let rays = response
                    .headers()
                    .get("x-rays")
                    .and_then(|v| v.to_str().ok()?.parse().ok())
                    .unwrap_or(0);
                return Ok((response.bytes().await?.to_vec(), rays));
            }
            Ok(response) if response.status() == 503 && busy < MAX_BUSY_ANSWERS => {
                busy += 1;
                let wait = response
                    .headers()
                    .get(reqwest::header::RETRY_AFTER)
                    .and_then(|v| v.to_str().ok()?.trim().parse().ok())
                    .map_or(backoff, Duration::from_secs);
                tokio::time::sleep(wait).await;
                continue;
            }
            Ok(response) if !last && response.status() == 504 => {
                tokio::time::sleep(backoff).await;
            }
            Ok(response) => {
                return Err(service_error(response, "GET", url).await);
            }
            Err(err) if !last => {
                tracing::warn!(%url, %err, "retrying");
                tokio::time::sleep(backoff).await;
            }
            Err(err) => return Err(err).with_context(|| format!("GET {url}")),
        }
        attempt += 1;
        backoff = (backoff * 2).min(Duration::from_secs(8));
    }
}

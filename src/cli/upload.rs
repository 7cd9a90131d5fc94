//! `bmc-irradiance upload`: sends a scene folder (packed here as a gzipped
//! tar) or a zip, tar or `.tar.gz` of one to a running service's
//! `POST /v1/scenes` in one request, and prints the scene's summary.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;

use super::fetch::service_error;
use crate::scene::archive::pack_folder;

/// Command-line arguments of `bmc-irradiance upload`.
#[derive(Clone, Debug, clap::Args)]
pub struct UploadArgs {
    /// A scene folder (the scene file at its root beside its meshes and
    /// textures), or a `.zip`, `.tar` or `.tar.gz` of one.
    pub path: PathBuf,
    /// Base URL of the service.
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// The scene's id (default: an XML scene's file stem when `--file`
    /// names it, else its folder's name; a JSON scene's `name`).
    #[arg(long)]
    pub id: Option<String>,
    /// The scene file, when the folder holds several (`scene_box.xml`).
    #[arg(long)]
    pub file: Option<String>,
    /// Replace the service's scene of the same id; without it an id the
    /// service holds is refused (409) and nothing changes.
    #[arg(long)]
    pub replace: bool,
    /// Approximate what the scene model cannot represent instead of refusing.
    #[arg(long)]
    pub lenient: bool,
    /// Mitsuba 3 XML: the value of a `$NAME` parameter (like `mitsuba -D`).
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = super::scene_args::parse_param)]
    pub params: Vec<(String, String)>,
    /// The service's `server.auth_token`.
    #[arg(long, env = "BMC_SERVER__AUTH_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
}

/// Runs `upload`, printing the scene's summary (JSON) on `out`.
pub fn run_upload(args: &UploadArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let (body, content_type) = if args.path.is_dir() {
        let mut packed = Vec::new();
        pack_folder(&args.path, &mut packed)
            .with_context(|| format!("packing {}", args.path.display()))?;
        (packed, "application/gzip")
    } else {
        let body = std::fs::read(&args.path)
            .with_context(|| format!("reading {}", args.path.display()))?;
        (body, archive_type(&args.path))
    };
    let mut query: Vec<(String, String)> = Vec::new();
    query.extend(args.id.iter().map(|id| ("id".into(), id.clone())));
    query.extend(args.file.iter().map(|f| ("file".into(), f.clone())));
    for (flag, set) in [("lenient", args.lenient), ("replace", args.replace)] {
        if set {
            query.push((flag.into(), "true".into()));
        }
    }
    query.extend(
        args.params
            .iter()
            .map(|(n, v)| (format!("param.{n}"), v.clone())),
    );
    let url = url::Url::parse_with_params(
        &format!("{}/v1/scenes", args.url.trim_end_matches('/')),
        &query,
    )
    .with_context(|| format!("--url {}", args.url))?;
    let summary: serde_json::Value = tokio::runtime::Runtime::new()?.block_on(async {
        let client = reqwest::Client::new();
        let mut request = client
            .post(url.clone())
            .header(reqwest::header::CONTENT_TYPE, content_type)
            .body(body);
        if let Some(token) = &args.token {
            request = request.bearer_auth(token);
        }
        let response = request
            .send()
            .await
            .with_context(|| format!("POST {url}"))?;
        if !response.status().is_success() {
            return Err(service_error(response, "POST", url.as_str()).await);
        }
        Ok::<_, anyhow::Error>(response.json().await?)
    })?;
    writeln!(out, "{}", serde_json::to_string_pretty(&summary)?)?;
    Ok(())
}

/// The media type an archive's file name declares (the service reads the
/// format from the bytes of `application/octet-stream`).
fn archive_type(path: &std::path::Path) -> &'static str {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if name.ends_with(".zip") {
        "application/zip"
    } else if name.ends_with(".tar.gz") || name.ends_with(".tgz") {
        "application/gzip"
    } else if name.ends_with(".tar") {
        "application/x-tar"
    } else {
        "application/octet-stream"
    }
}

//! Spawns the real service on 127.0.0.1:0 for black-box tests.

#![allow(dead_code, unused_imports)] // each test binary uses a different subset of these helpers

use bmc_irradiance::service::{Application, Config};
use tempfile::TempDir;
use tokio::sync::oneshot;

/// A running service; it stops when this value is dropped.
pub struct TestApp {
    /// `http://127.0.0.1:<port>`.
    pub base: String,
    pub client: reqwest::Client,
    /// The scenes directory, deleted on drop.
    pub scenes_dir: TempDir,
    stop: Option<oneshot::Sender<()>>,
}

impl TestApp {
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// The ids of the scenes the service holds (`GET /v1/scenes`), sorted.
    pub async fn scene_ids(&self) -> Vec<String> {
        scene_ids_at(&self.client, &self.base).await
    }

    pub async fn get(&self, path: &str) -> reqwest::Response {
        self.client.get(self.url(path)).send().await.unwrap()
    }

    /// `GET path` as JSON, asserting it answers 200.
    pub async fn get_json(&self, path: &str) -> serde_json::Value {
        let response = self.get(path).await;
        assert_eq!(response.status(), reqwest::StatusCode::OK, "{path}");
        response.json().await.unwrap()
    }

    /// `/health` as JSON, asserting it answers 200.
    pub async fn health(&self) -> serde_json::Value {
        self.get_json("/health").await
    }

    pub async fn delete(&self, path: &str) -> reqwest::Response {
        self.client.delete(self.url(path)).send().await.unwrap()
    }

    pub async fn post_json(&self, path: &str, body: &serde_json::Value) -> reqwest::Response {
        self.client
            .post(self.url(path))
            .json(body)
            .send()
            .await
            .unwrap()
    }
}

impl Drop for TestApp {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
    }
}

/// A configuration for tests: ephemeral port, an empty temporary scenes
/// directory, two CPU threads, no queue-wait admission limit; `adjust` may
/// change anything else.
pub fn test_config(scenes_dir: &TempDir, adjust: impl FnOnce(&mut Config)) -> Config {
    let mut config = Config::default_config();
    config.server.bind = "127.0.0.1:0".parse().unwrap();
    config.server.worker_threads = 2;
    // Debug-build jobs are many times slower than release ones, so the
    // release default would refuse concurrent test clients; tests of
    // admission set it themselves.
    config.limits.max_queue_wait_secs = 3600.0;
    config.scenes.dir = scenes_dir.path().to_owned();
    // Memory only, unless a test persists on purpose.
    config.cache.data_dir = Default::default();
    adjust(&mut config);
    config.validate().unwrap();
    config
}

/// Starts the service with the test configuration.
pub async fn spawn_app() -> TestApp {
    spawn_app_with(|_| {}).await
}

/// Starts the service with the test configuration changed by `adjust`.
pub async fn spawn_app_with(adjust: impl FnOnce(&mut Config)) -> TestApp {
    spawn_app_with_scenes(&[], adjust).await
}

pub use bmc_irradiance::testing::TINY_SCENE;

/// Starts the service after writing `files` (name, contents) into its scenes directory.
pub async fn spawn_app_with_scenes(
    files: &[(&str, &str)],
    adjust: impl FnOnce(&mut Config),
) -> TestApp {
    let scenes_dir = tempfile::tempdir().unwrap();
    for (name, contents) in files {
        std::fs::write(scenes_dir.path().join(name), contents).unwrap();
    }
    spawn_app_in(scenes_dir, adjust).await
}

/// Starts the service on a scenes directory the caller prepared.
pub async fn spawn_app_in(scenes_dir: TempDir, adjust: impl FnOnce(&mut Config)) -> TestApp {
    let config = test_config(&scenes_dir, adjust);
    let app = Application::build(config).await.unwrap();
    let base = format!("http://{}", app.local_addr());
    let (stop, stopped) = oneshot::channel::<()>();
    tokio::spawn(app.run_until_stopped(async {
        let _ = stopped.await;
    }));
    TestApp {
        base,
        client: reqwest::Client::new(),
        scenes_dir,
        stop: Some(stop),
    }
}

/// The JSON error body and its size in bytes, asserting its content type
/// and that it carries a message.
pub async fn error_json(response: reqwest::Response) -> (serde_json::Value, usize) {
    let content_type = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    assert!(
        content_type.starts_with("application/json"),
        "{content_type}"
    );
    let bytes = response.bytes().await.unwrap();
    let body: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
    assert!(body["error"]["message"].is_string(), "{body}");
    (body, bytes.len())
}

/// Asserts the JSON error body shape and returns `(code, field)`.
pub async fn error_of(response: reqwest::Response) -> (String, Option<String>) {
    let (body, _) = error_json(response).await;
    let error = &body["error"];
    (
        error["code"].as_str().unwrap().to_owned(),
        error["field"].as_str().map(str::to_owned),
    )
}

/// Copies the files of `from` into `to`, folders included.
pub fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        let target = to.join(path.file_name().unwrap());
        if path.is_dir() {
            copy_dir(&path, &target);
        } else {
            std::fs::copy(&path, &target).unwrap();
        }
    }
}

/// A point request's answer without its cost (`rays`, `amortised_rays`),
/// and that cost.
pub fn answer_and_cost(answer: &serde_json::Value) -> (serde_json::Value, u64, u64) {
    let mut rest = answer.clone();
    let object = rest.as_object_mut().expect("a JSON object");
    let mut take = |key: &str| {
        object
            .remove(key)
            .and_then(|v| v.as_u64())
            .unwrap_or_else(|| panic!("no {key} in {answer}"))
    };
    let (rays, amortised) = (take("rays"), take("amortised_rays"));
    (rest, rays, amortised)
}

/// Checks that `again`, a point request repeated after `first`, answers the
/// same numbers, that it found the work `first` did for later requests kept
/// (`amortised_rays` 0), and that `first`'s `rays` counted that work on top
/// of the same rays for its points.
pub fn assert_same_answer_without_the_kept_work(
    first: &serde_json::Value,
    again: &serde_json::Value,
) {
    let (first_rest, first_rays, first_amortised) = answer_and_cost(first);
    let (again_rest, again_rays, again_amortised) = answer_and_cost(again);
    assert_eq!(first_rest, again_rest);
    assert_eq!(again_amortised, 0, "{again}");
    assert_eq!(
        first_rays,
        again_rays + first_amortised,
        "{first} then {again}"
    );
}

/// `GET url` as JSON.
pub async fn get_json_at(client: &reqwest::Client, url: &str) -> serde_json::Value {
    client.get(url).send().await.unwrap().json().await.unwrap()
}

/// The ids of the scenes the service at `base` (`http://…`) holds, sorted.
pub async fn scene_ids_at(client: &reqwest::Client, base: &str) -> Vec<String> {
    get_json_at(client, &format!("{base}/v1/scenes"))
        .await
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].as_str().unwrap().to_owned())
        .collect()
}

/// A child process killed on drop.
pub struct Service(pub std::process::Child);

impl Drop for Service {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The service as a process of its own serving `scenes`, so its memory is
/// its own; its address.
pub fn serve(scenes: &std::path::Path, data: &std::path::Path) -> (Service, String) {
    serve_with(scenes, data, &[])
}

/// [`serve`] with more `BMC_…` settings in the environment.
pub fn serve_with(
    scenes: &std::path::Path,
    data: &std::path::Path,
    env: &[(&str, &str)],
) -> (Service, String) {
    use std::io::BufRead;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
        .args(["serve", "--bind", "127.0.0.1:0"])
        .env("BMC_SCENES__DIR", scenes)
        .env("BMC_CACHE__DATA_DIR", data)
        .env("NO_COLOR", "1")
        .env("RUST_LOG", "info")
        .envs(env.iter().copied())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    let addr = loop {
        let line = lines.next().expect("the service exited").unwrap();
        if let Some(rest) = line.split("addr=").nth(1)
            && line.contains("listening")
        {
            break rest.split_whitespace().next().unwrap().to_owned();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (Service(child), addr)
}

/// The most memory process `pid` has held (`VmHWM`), bytes.
pub fn peak_rss(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    let kib: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kib << 10
}

/// Every file under `dir` (recursively) whose extension is one of
/// `extensions`, in directory order.
pub fn files_with(dir: &std::path::Path, extensions: &[&str]) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(dir) = pending.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                pending.push(path);
            } else if path
                .extension()
                .is_some_and(|e| extensions.iter().any(|x| e == *x))
            {
                out.push(path);
            }
        }
    }
    out
}

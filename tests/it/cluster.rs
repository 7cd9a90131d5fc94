//! Three replicas behind a real HAProxy (Debian's `haproxy`, which `.ci/run`
//! installs) with `deploy/haproxy.cfg.in`: eight clients render the Cornell
//! box's tiles through it, the replica that owns the scene is killed in the
//! middle, and every tile still arrives, bit-identical to a single process's
//! render of the same reproducible request. Set `HAPROXY` to use another
//! binary.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::sync::Mutex;

use crate::common::spawn_app_in;

const BIN: &str = env!("CARGO_BIN_EXE_bmc-irradiance");

/// A child process killed on drop.
struct Process(Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A replica on an ephemeral port; its address from the `listening` log line.
fn replica(dir: &Path) -> (Process, String) {
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    std::fs::copy(
        root().join("scenes/cornell-box.json"),
        scenes.join("cornell-box.json"),
    )
    .unwrap();
    let mut child = Command::new(BIN)
        .args(["serve", "--bind", "127.0.0.1:0"])
        .env("BMC_SCENES__DIR", &scenes)
        .env("BMC_CACHE__DATA_DIR", dir.join("data"))
        .env("BMC_SERVER__WORKER_THREADS", "1")
        .env("NO_COLOR", "1")
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let mut lines = stderr.lines();
    let addr = loop {
        let line = lines.next().expect("the replica exited").unwrap();
        if let Some(rest) = line.split("addr=").nth(1)
            && line.contains("listening")
        {
            break rest.split_whitespace().next().unwrap().to_owned();
        }
    };
    // Keep draining the log so the replica never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    (Process(child), addr)
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// One tile through the balancer, retrying what a client of a cluster
/// retries (connection failures, 502/503/504); counts the retries.
async fn tile(client: &reqwest::Client, url: &str, retries: &AtomicU64) -> (Vec<u8>, String) {
    for _ in 0..60 {
        match client.get(url).send().await {
            Ok(r) if r.status().is_success() => {
                let by = r.headers()["x-served-by"].to_str().unwrap().to_owned();
                return (r.bytes().await.unwrap().to_vec(), by);
            }
            Ok(r) if matches!(r.status().as_u16(), 502..=504) => {}
            Ok(r) => panic!("{url}: {}", r.status()),
            Err(_) => {}
        }
        retries.fetch_add(1, Ordering::Relaxed);
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    panic!("{url}: no answer after 60 attempts");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_replica_dies_mid_render_and_the_image_is_still_exact() {
    let haproxy = std::env::var("HAPROXY").unwrap_or_else(|_| "haproxy".into());
    let dirs: Vec<_> = (0..3).map(|_| tempfile::tempdir().unwrap()).collect();
    let mut replicas: Vec<(Option<Process>, String)> = dirs
        .iter()
        .map(|d| {
            let (p, a) = replica(d.path());
            (Some(p), a)
        })
        .collect();
    let front = format!("127.0.0.1:{}", free_port());
    let servers: String = replicas
        .iter()
        .enumerate()
        .map(|(k, (_, addr))| format!("    server r{k} {addr} check\n"))
        .collect();
    let config = std::fs::read_to_string(root().join("deploy/haproxy.cfg.in"))
        .unwrap()
        .replace("@FRONTEND@", &front)
        .replace("@SERVERS@\n", &servers);
    let cfg_dir = tempfile::tempdir().unwrap();
    let cfg = cfg_dir.path().join("haproxy.cfg");
    std::fs::write(&cfg, config).unwrap();
    let _balancer = Process(
        Command::new(&haproxy)
            .arg("-f")
            .arg(&cfg)
            .arg("-db")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {haproxy} ({e}); install Debian's haproxy")),
    );
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(120))
        .build()
        .unwrap();
    let base = format!("http://{front}");
    for _ in 0..100 {
        if client
            .get(format!("{base}/health"))
            .send()
            .await
            .is_ok_and(|r| r.status().is_success())
        {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // Let every replica pass its first readiness checks.
    tokio::time::sleep(Duration::from_millis(1500)).await;

    let urls: Vec<String> = (0..4)
        .flat_map(|ty| (0..4).map(move |tx| (tx, ty)))
        .map(|(tx, ty)| format!("/v1/scenes/cornell-box/tiles/{tx}/{ty}.png?preset=draft"))
        .collect();
    let retries = Arc::new(AtomicU64::new(0));
    let done = Arc::new(Mutex::new(Vec::new()));
    let owner = Arc::new(Mutex::new(None::<String>));
    let mut clients = tokio::task::JoinSet::new();
    for c in 0..8 {
        let (client, base, retries, done, owner) = (
            client.clone(),
            base.clone(),
            retries.clone(),
            done.clone(),
            owner.clone(),
        );
        let mine: Vec<String> = urls.iter().skip(c % 2).step_by(2).cloned().collect();
        clients.spawn(async move {
            for url in mine {
                let (bytes, by) = tile(&client, &format!("{base}{url}"), &retries).await;
                owner.lock().await.get_or_insert(by.clone());
                done.lock().await.push((url, bytes, by));
            }
        });
    }
    // Kill the scene's replica once the render is under way.
    let killed = loop {
        if let Some(by) = owner.lock().await.clone() {
            break by;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    let index: usize = killed.trim_start_matches('r').parse().unwrap();
    drop(replicas[index].0.take());
    while let Some(result) = clients.join_next().await {
        result.unwrap();
    }
    let done = done.lock().await.clone();
    assert_eq!(done.len(), 8 * 8);
    // The owner answered before it died, the others after.
    let by_owner = done.iter().filter(|(_, _, by)| *by == killed).count();
    eprintln!(
        "tiles by the killed owner {killed}: {by_owner} of {}; client retries {}",
        done.len(),
        retries.load(Ordering::Relaxed)
    );
    assert!(by_owner >= 1 && by_owner < done.len());

    // The same requests to one process of our own: the same bytes.
    let single = {
        let dir = tempfile::tempdir().unwrap();
        std::fs::copy(
            root().join("scenes/cornell-box.json"),
            dir.path().join("cornell-box.json"),
        )
        .unwrap();
        spawn_app_in(dir, |_| {}).await
    };
    for (url, bytes, _) in &done {
        let expected = single.get(url).await.bytes().await.unwrap();
        assert_eq!(bytes.as_slice(), &expected[..], "{url}");
    }
    // The survivors answered after the kill.
    let survivors: Vec<_> = replicas.iter().filter(|(p, _)| p.is_some()).collect();
    assert_eq!(survivors.len(), 2);
    let after = client
        .get(format!(
            "{base}/v1/scenes/cornell-box/tiles/0/0.png?preset=draft"
        ))
        .send()
        .await
        .unwrap();
    assert!(after.status().is_success());
    assert_ne!(after.headers()["x-served-by"], killed.as_str());
}

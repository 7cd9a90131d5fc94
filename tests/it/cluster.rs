//! Three replicas sharing a real Redis, behind a real HAProxy (Debian's
//! `redis-server` and `haproxy`, which `.ci/run` installs) with
//! `deploy/haproxy.cfg.in`:
//! - a scene uploaded with its mesh and EXR map through the balancer renders
//!   on every replica, asked directly;
//! - eight clients render the Cornell box's tiles through the balancer, the
//!   replica that owns the scene is killed in the middle, and every tile
//!   still arrives, bit-identical to a single process's render of the same
//!   reproducible request; the survivors merged what the others shared;
//! - with Redis gone, the replicas say so in `/health` and `/metrics` and
//!   go on answering.
//!
//! Set `HAPROXY` or `REDIS_SERVER` to use other binaries.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::sync::Mutex;

use crate::common::spawn_app_in;
use crate::service_upload::with_mesh_and_map;
use bmc_irradiance::testing::BOUNDARY;

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
fn replica(dir: &Path, redis: &str) -> (Process, String) {
    replica_with(dir, redis, &[])
}

/// [`replica`] with more environment variables.
fn replica_with(dir: &Path, redis: &str, env: &[(&str, &str)]) -> (Process, String) {
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
        .env("BMC_CLUSTER__REDIS_URL", redis)
        .envs(env.iter().copied())
        .env("NO_COLOR", "1")
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let mut lines = stderr.lines();
    let mut seen = Vec::new();
    let addr = loop {
        let Some(line) = lines.next() else {
            panic!("the replica exited:\n{}", seen.join("\n"));
        };
        let line = line.unwrap();
        seen.push(line.clone());
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

/// A Redis server on a free loopback port, keeping nothing on disk; waits
/// until it answers `PING`.
fn redis_server() -> (Process, String) {
    let binary = std::env::var("REDIS_SERVER").unwrap_or_else(|_| "redis-server".into());
    let port = free_port();
    let child = Command::new(&binary)
        .args(["--port", &port.to_string(), "--bind", "127.0.0.1"])
        .args(["--save", "", "--appendonly", "no"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {binary} ({e}); install Debian's redis-server"));
    let process = Process(child);
    for _ in 0..100 {
        if let Ok(mut stream) = std::net::TcpStream::connect(("127.0.0.1", port)) {
            use std::io::{Read, Write};
            let mut reply = [0; 7];
            if stream.write_all(b"PING\r\n").is_ok()
                && stream.read_exact(&mut reply).is_ok()
                && &reply == b"+PONG\r\n"
            {
                return (process, format!("redis://127.0.0.1:{port}/0"));
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    panic!("redis-server did not answer on port {port}");
}

/// `/health` of the replica at `addr`.
async fn health(client: &reqwest::Client, addr: &str) -> serde_json::Value {
    crate::common::get_json_at(client, &format!("http://{addr}/health")).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn replicas_share_scenes_and_records_and_survive_a_death() {
    let haproxy = std::env::var("HAPROXY").unwrap_or_else(|_| "haproxy".into());
    let (redis, redis_url) = redis_server();
    let mut redis = Some(redis);
    let dirs: Vec<_> = (0..3).map(|_| tempfile::tempdir().unwrap()).collect();
    let mut replicas: Vec<(Option<Process>, String)> = dirs
        .iter()
        .map(|d| {
            let (p, a) = replica(d.path(), &redis_url);
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

    // A scene uploaded with its assets through the balancer renders on
    // every replica, each asked directly.
    let upload = with_mesh_and_map();
    let posted = client
        .post(format!("{base}/v1/scenes"))
        .header(
            "content-type",
            format!("multipart/form-data; boundary={BOUNDARY}"),
        )
        .body(upload)
        .send()
        .await
        .unwrap();
    assert_eq!(posted.status(), 201);
    // The same bytes from every replica, for a whole preset and for an
    // adaptive pass of a progressive one (docs/math.md §16.5).
    for query in ["preset=draft", "preset=preview&pass=1"] {
        let mut uploaded = Vec::new();
        for (_, addr) in &replicas {
            let url = format!("http://{addr}/v1/scenes/uploaded/tiles/0/0.png?size=16&{query}");
            let response = client.get(&url).send().await.unwrap();
            assert_eq!(response.status(), 200, "{url}");
            uploaded.push(response.bytes().await.unwrap());
        }
        assert!(uploaded.windows(2).all(|w| w[0] == w[1]), "{query}");
    }

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
    // The survivors merged the parts the others shared.
    for (_, addr) in &survivors {
        let shared = &health(&client, addr).await["shared"];
        assert_eq!(shared["connected"], true, "{shared}");
        assert!(shared["parts_merged"].as_u64().unwrap() > 0, "{shared}");
    }

    // Redis gone: the replicas say so and keep answering from their own stores.
    drop(redis.take());
    let addr = &survivors[0].1;
    let mut reported = false;
    for _ in 0..100 {
        if health(&client, addr).await["shared"]["connected"] == false {
            reported = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(reported, "{}", health(&client, addr).await);
    let metrics = client
        .get(format!("http://{addr}/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        metrics.contains("bmc_shared_store_connected 0"),
        "{metrics}"
    );
    let fresh = client
        .get(format!(
            "{base}/v1/scenes/cornell-box/tiles/1/1.png?preset=draft&seed=7"
        ))
        .send()
        .await
        .unwrap();
    assert_eq!(fresh.status(), 200);
}

/// Sends one command to the Redis at `url` (`redis://127.0.0.1:PORT/0`) and
/// returns its first reply line.
fn redis_command(url: &str, args: &[&[u8]]) -> String {
    use std::io::Write;
    let address = url
        .trim_start_matches("redis://")
        .split('/')
        .next()
        .unwrap();
    let mut stream = std::net::TcpStream::connect(address).unwrap();
    let mut request = format!("*{}\r\n", args.len()).into_bytes();
    for arg in args {
        request.extend(format!("${}\r\n", arg.len()).as_bytes());
        request.extend(*arg);
        request.extend(b"\r\n");
    }
    stream.write_all(&request).unwrap();
    let mut line = String::new();
    BufReader::new(stream).read_line(&mut line).unwrap();
    line
}

/// A scene in Redis that does not load (damaged, or written by another
/// release) is a scene this replica does not have: 404 naming it, not a 500
/// on every request, and the replica stays healthy.
#[tokio::test]
async fn a_broken_shared_scene_is_not_found_rather_than_an_error() {
    let (_redis, url) = redis_server();
    let dir = tempfile::tempdir().unwrap();
    let (_replica, addr) = replica(dir.path(), &url);
    let reply = redis_command(&url, &[b"SET", b"bmc:scene:broken", b"not a posted scene"]);
    assert_eq!(reply, "+OK\r\n");
    let client = reqwest::Client::new();
    for _ in 0..2 {
        let response = client
            .get(format!("http://{addr}/v1/scenes/broken"))
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), 404);
        let body: serde_json::Value = response.json().await.unwrap();
        assert_eq!(body["error"]["code"], "not_found", "{body}");
    }
    assert_eq!(status(&client, format!("http://{addr}/health")).await, 200);
}

/// Two replicas on one Redis, a copy of the Cornell box posted to the first.
struct Pair {
    a: (Process, String),
    b: (Process, String),
    client: reqwest::Client,
    _dirs: [tempfile::TempDir; 2],
}

impl Pair {
    /// Replicas `a` and `b` on the Redis at `url` with the environment `env`,
    /// and the Cornell box posted to `a` as `name`.
    async fn with_posted_scene(url: &str, env: &[(&str, &str)], name: &str) -> Pair {
        let dirs = [tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap()];
        let a = replica_with(dirs[0].path(), url, env);
        let b = replica_with(dirs[1].path(), url, env);
        let client = reqwest::Client::new();
        let mut doc: serde_json::Value =
            serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
        doc["name"] = serde_json::json!(name);
        let posted = client
            .post(format!("http://{}/v1/scenes", a.1))
            .json(&doc)
            .send()
            .await
            .unwrap();
        assert_eq!(posted.status(), 201);
        Pair {
            a,
            b,
            client,
            _dirs: dirs,
        }
    }
}

/// The status of a GET of `url`.
async fn status(client: &reqwest::Client, url: String) -> u16 {
    client.get(url).send().await.unwrap().status().as_u16()
}

/// A scene deleted while Redis is stalled is deleted on the other replicas
/// too once Redis answers again: the deletion is sent again until it is
/// taken, instead of being lost with the command that timed out.
#[tokio::test]
async fn a_deletion_during_a_redis_stall_reaches_the_other_replicas() {
    let (redis, url) = redis_server();
    let pair = Pair::with_posted_scene(&url, &[], "extra").await;
    let (a, b, client) = (&pair.a.1, &pair.b.1, &pair.client);
    let scene_on = |addr: &str| status(client, format!("http://{addr}/v1/scenes/extra"));
    assert_eq!(scene_on(b).await, 200, "replica b adopts the scene");

    let signal = |name: &str| {
        let status = Command::new("kill")
            .args([name, &redis.0.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
    };
    signal("-STOP");
    let deleted = client
        .delete(format!("http://{a}/v1/scenes/extra"))
        .send()
        .await
        .unwrap();
    assert_eq!(deleted.status(), 204);
    assert_eq!(scene_on(a).await, 404);
    signal("-CONT");
    for _ in 0..120 {
        if scene_on(b).await == 404 {
            return;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    panic!("replica b still serves the scene deleted on replica a");
}

/// With `cluster.secret`, replicas take only what carries its hash: a
/// scene posted to one is served by the other, while a part and a deletion
/// written to Redis by someone without the secret are refused (counted).
#[tokio::test]
async fn with_a_secret_replicas_refuse_what_redis_holds_unsigned() {
    let (_redis, url) = redis_server();
    let secret = [("BMC_CLUSTER__SECRET", "the replicas' secret")];
    let pair = Pair::with_posted_scene(&url, &secret, "signed").await;
    let (b, client) = (&pair.b.1, &pair.client);
    let scene_on_b = || status(client, format!("http://{b}/v1/scenes/signed"));
    assert_eq!(scene_on_b().await, 200, "replica b adopts the signed scene");

    let parts = format!("bmc:parts:{}", env!("CARGO_PKG_VERSION"));
    let reply = redis_command(
        &url,
        &[
            b"XADD",
            parts.as_bytes(),
            b"*",
            b"o",
            b"forger",
            b"e",
            b"forged part",
        ],
    );
    assert!(reply.starts_with('$'), "{reply}");
    let reply = redis_command(
        &url,
        &[
            b"XADD",
            b"bmc:scenes",
            b"*",
            b"o",
            b"forger",
            b"op",
            b"delete",
            b"id",
            b"signed",
            b"digest",
            b"",
        ],
    );
    assert!(reply.starts_with('$'), "{reply}");
    let refused = || {
        let (client, url) = (client.clone(), format!("http://{b}/health"));
        async move {
            let health: serde_json::Value =
                client.get(url).send().await.unwrap().json().await.unwrap();
            health["shared"]["refused_unsigned"].as_u64().unwrap()
        }
    };
    for _ in 0..80 {
        if refused().await >= 2 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    assert!(refused().await >= 2, "the forged items were not refused");
    assert_eq!(scene_on_b().await, 200, "a forged deletion was taken");
}

//! The README's two commands, read from the README itself and run as a new
//! user runs them: in a fresh `git clone` of this repository, the first
//! (`serve`) until `/health` answers with the bundled scenes, the second
//! (the test command) built on that clone.
//!
//! The clone gets a hard-linked copy of this suite's compiled dependencies
//! (never of this crate's own files, which cargo rewrites), so only this crate
//! and whatever the commands need beyond them are compiled again.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// How long a fresh release build and startup may take on CI's two cores,
/// with the rest of the suite running beside it.
const SERVE_TIMEOUT: Duration = Duration::from_secs(1500);

/// The indented command lines of the README's "The two commands" section,
/// in order: the service's command, then the test command.
fn readme_commands() -> (String, String) {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let section = readme
        .split("\n## ")
        .find(|s| s.starts_with("The two commands"))
        .expect("README has a \"The two commands\" section");
    let commands: Vec<String> = section
        .lines()
        .filter_map(|l| l.strip_prefix("    "))
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect();
    assert_eq!(commands.len(), 2, "{commands:?}");
    (commands[0].clone(), commands[1].clone())
}

#[test]
fn readme_section_names_serve_and_test() {
    let (serve, test) = readme_commands();
    assert!(serve.contains(" serve"), "{serve}");
    assert!(test.starts_with("cargo test"), "{test}");
}

/// This suite's target directory: the test binary lives in
/// `<target>/<profile>/deps/`.
fn suite_target_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.ancestors().nth(3).unwrap().to_path_buf()
}

/// Hard-links every compiled artefact of `from` into `to` except this
/// crate's own (fingerprints, build scripts, outputs, incremental state),
/// which the clone compiles from its own sources.
fn link_dependencies(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.contains("bmc_irradiance")
            || name.contains("bmc-irradiance")
            || name.contains("bmc-loadtest")
            || name.contains("bmc_loadtest")
            || name == "incremental"
            || name.starts_with('.') && name.ends_with("lock")
        {
            continue;
        }
        let kind = entry.file_type().unwrap();
        let target = to.join(entry.file_name());
        if kind.is_dir() {
            link_dependencies(&entry.path(), &target);
        } else if kind.is_file() {
            std::fs::hard_link(entry.path(), &target)
                .or_else(|_| std::fs::copy(entry.path(), &target).map(|_| ()))
                .unwrap();
        }
    }
}

fn shell(command: &str, dir: &Path) -> Command {
    let mut shell = Command::new("sh");
    shell
        .args(["-c", command])
        .current_dir(dir)
        // Every dependency is already in the local registry cache.
        .env("CARGO_NET_OFFLINE", "true")
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("RUSTFLAGS")
        .stdin(Stdio::null());
    shell
}

/// Kills the service (and the `cargo run` around it) however the test ends.
struct Service(Child);

impl Drop for Service {
    fn drop(&mut self) {
        // `sh -c` runs cargo, which runs the binary: end the whole group,
        // by the system call itself. Debian's `kill -TERM -<pgid>` (procps-ng
        // 4.0.2) reads `-<pgid>` as an option and signals the group of its
        // first digit: `kill(-1)`, every process, for a pgid starting with 1.
        if let Ok(group) = libc::pid_t::try_from(self.0.id()) {
            // SAFETY: killpg only sends a signal; the group is the child's own.
            unsafe { libc::killpg(group, libc::SIGTERM) };
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The `addr=` of the service's "listening" log line.
fn listening_addr(line: &str) -> Option<String> {
    if !line.contains("listening") {
        return None;
    }
    let start = line.find("addr=")? + "addr=".len();
    let rest = &line[start..];
    let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
    Some(rest[..end].to_string())
}

#[test]
fn readme_commands_work_on_a_fresh_clone() {
    let (serve, test) = readme_commands();
    let dir = tempfile::tempdir().unwrap();
    let clone = dir.path().join("clone");
    let status = Command::new("git")
        .args(["clone", "--quiet", "--no-hardlinks", ROOT])
        .arg(&clone)
        .status()
        .unwrap();
    assert!(status.success(), "git clone of {ROOT} failed");
    let suite = suite_target_dir();
    for profile in ["debug", "release"] {
        if suite.join(profile).is_dir() {
            link_dependencies(&suite.join(profile), &clone.join("target").join(profile));
        }
    }

    // 1. The service's command, verbatim, on an ephemeral port (set by the
    // environment, as docs/service.md's configuration section allows). Its
    // release build is made cheap through cargo's own environment overrides
    // of the profile: what is tested is the command on a fresh clone, not
    // the optimiser, and a full optimised build would double CI's time.
    use std::os::unix::process::CommandExt;
    let mut command = shell(&serve, &clone);
    command
        .env("CARGO_PROFILE_RELEASE_OPT_LEVEL", "0")
        .env("CARGO_PROFILE_RELEASE_DEBUG", "false")
        .env("CARGO_PROFILE_RELEASE_CODEGEN_UNITS", "256")
        .env("BMC_SERVER__BIND", "127.0.0.1:0")
        .env("BMC_CACHE__DATA_DIR", dir.path().join("data"))
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .process_group(0);
    let mut child = command.spawn().unwrap();
    let stderr = child.stderr.take().unwrap();
    let service = Service(child);
    let (lines, received) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    let started = Instant::now();
    let mut log = Vec::new();
    let addr = loop {
        let left = SERVE_TIMEOUT.saturating_sub(started.elapsed());
        match received.recv_timeout(left) {
            Ok(line) => {
                let addr = listening_addr(&line);
                log.push(line);
                if let Some(addr) = addr {
                    break addr;
                }
            }
            Err(_) => panic!(
                "`{serve}` never listened:\n{}",
                log[log.len().saturating_sub(40)..].join("\n")
            ),
        }
    };
    let health: serde_json::Value = get_json(&format!("http://{addr}/health"));
    assert_eq!(health["status"], "ok", "{health}");
    let bundled = std::fs::read_dir(clone.join("scenes"))
        .unwrap()
        .filter(|e| {
            let path = e.as_ref().unwrap().path();
            path.extension().is_some_and(|x| x == "json")
        })
        .count();
    assert!(bundled >= 4, "{bundled} bundled JSON scenes");
    assert!(
        health["scenes"].as_u64().unwrap() >= bundled as u64,
        "{health}"
    );
    drop(service);

    // 2. The test command, built on the clone: running it would run this
    // test again, inside itself.
    let output = shell(&format!("{test} --no-run"), &clone).output().unwrap();
    assert!(
        output.status.success(),
        "`{test} --no-run` failed on a fresh clone:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A blocking GET with the async client, on a runtime of its own.
fn get_json(url: &str) -> serde_json::Value {
    tokio::runtime::Runtime::new()
        .unwrap()
        .block_on(async { reqwest::get(url).await.unwrap().json().await.unwrap() })
}

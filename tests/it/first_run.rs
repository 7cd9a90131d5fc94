//! What a new user meets first, through the real binary: `--help` of the
//! subcommands that read scene files, and `serve` started where there is no
//! scenes directory, with its log going to a file rather than a terminal.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_bmc-irradiance");

#[test]
fn help_says_scene_files_may_be_xml() {
    for subcommand in ["render", "irradiance", "study-scene"] {
        let output = Command::new(BIN)
            .args([subcommand, "--help"])
            .output()
            .unwrap();
        assert!(output.status.success(), "{subcommand}");
        let help = String::from_utf8_lossy(&output.stdout);
        assert!(
            help.contains("--scene") && help.contains("Mitsuba 3 XML"),
            "{subcommand}: {help}"
        );
        assert!(!help.contains("Scene JSON file"), "{subcommand}: {help}");
    }
}

/// Started outside the repository, `serve` finds no `scenes/`: it warns,
/// naming the directory as configured and absolute and how to point it at
/// scenes; the log, written to a pipe, carries no colour codes.
#[test]
fn serve_without_scenes_warns_plainly() {
    let cwd = tempfile::tempdir().unwrap();
    // The working directory as the process will see it (no symlinks).
    let cwd_path = cwd.path().canonicalize().unwrap();
    let mut child = Command::new(BIN)
        .args(["serve", "--bind", "127.0.0.1:0"])
        .current_dir(&cwd_path)
        .env_clear()
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (lines, received) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    let mut log = Vec::new();
    while let Ok(line) = received.recv_timeout(Duration::from_secs(60)) {
        let listening = line.contains("listening");
        log.push(line);
        if listening {
            break;
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    let _ = reader.join();
    log.extend(received.try_iter());
    let log = log.join("\n");

    assert!(log.contains("listening"), "{log}");
    assert!(
        !log.contains('\u{1b}'),
        "colour codes in a piped log: {log:?}"
    );
    let warning = log
        .lines()
        .find(|l| l.contains("no scenes loaded"))
        .unwrap_or_else(|| panic!("no warning about the scenes directory: {log}"));
    assert!(warning.contains("WARN"), "{warning}");
    assert!(warning.contains("dir=scenes"), "{warning}");
    let absolute = cwd_path.join("scenes");
    assert!(
        warning.contains(&absolute.display().to_string()),
        "{warning}"
    );
    assert!(
        warning.contains("--config") && warning.contains("BMC_SCENES__DIR="),
        "{warning}"
    );
}

/// `render --out` writes the format its extension names, and refuses any
/// other extension before rendering anything.
#[test]
fn render_writes_the_format_out_names() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-box.json");
    let render = |out: &str| {
        Command::new(BIN)
            .args([
                "render",
                "--scene",
                scene,
                "--spp",
                "1",
                "--max-depth",
                "1",
                "--threads",
                "2",
            ])
            .arg("--out")
            .arg(dir.path().join(out))
            .output()
            .unwrap()
    };
    let refused = render("box.txt");
    assert!(!refused.status.success());
    let said = String::from_utf8_lossy(&refused.stderr);
    assert!(said.contains(".exr or .png"), "{said}");
    assert!(!dir.path().join("box.txt").exists());
    assert!(render("box.png").status.success());
    let png = std::fs::read(dir.path().join("box.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    assert!(render("box.EXR").status.success());
    let exr = std::fs::read(dir.path().join("box.EXR")).unwrap();
    assert!(exr.starts_with(&[0x76, 0x2f, 0x31, 0x01]), "not an EXR");
}

/// `fetch` says what the service said when it refuses, not only the status.
#[tokio::test]
async fn fetch_reports_the_services_message() {
    let app = crate::common::spawn_app().await;
    let base = app.base.clone();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let output = tokio::task::spawn_blocking(move || {
        Command::new(BIN)
            .args([
                "fetch", "--url", &base, "--scene", "missing", "--preset", "draft",
            ])
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    })
    .await
    .unwrap();
    assert!(!output.status.success());
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(said.contains("scene `missing` not found"), "{said}");
}

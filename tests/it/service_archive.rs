//! `POST /v1/scenes` with a packed scene folder: the tutorials' Cornell box
//! folder zipped and tarred by the system's own tools uploads in one request
//! and renders; archives that would escape, link, hold special files, flood
//! or explode are refused naming the entry, and the service keeps its scenes.

use std::io::Write;
use std::path::Path;
use std::process::Command;

use crate::common::{TINY_SCENE, TestApp, spawn_app_with_scenes};
use reqwest::StatusCode;
use serde_json::Value;

/// The tutorials' Cornell box folder (`cbox.xml`, `meshes/`, and files it
/// does not use) copied to `<dir>/cbox`.
fn cbox_folder(dir: &Path) {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba-tutorials");
    let target = dir.join("cbox");
    std::fs::create_dir_all(target.join("meshes")).unwrap();
    for entry in walk(&source) {
        let relative = entry.strip_prefix(&source).unwrap();
        std::fs::copy(&entry, target.join(relative)).unwrap();
    }
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(walk(&path));
        } else {
            files.push(path);
        }
    }
    files
}

fn run(command: &mut Command) {
    let status = command.status().unwrap();
    assert!(status.success(), "{command:?}: {status}");
}

async fn post(
    app: &TestApp,
    query: &str,
    content_type: &str,
    body: Vec<u8>,
) -> (StatusCode, Value) {
    let response = app
        .client
        .post(app.url(&format!("/v1/scenes{query}")))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap();
    let status = response.status();
    (status, response.json().await.unwrap())
}

/// The scene renders: the draft tile at the middle of its 256² image has
/// lit pixels.
async fn renders(app: &TestApp, id: &str) {
    let tile: Value = app
        .get(&format!(
            "/v1/scenes/{id}/tiles/8/8.json?preset=draft&size=16"
        ))
        .await
        .json()
        .await
        .unwrap();
    let rgb = tile["rgb"].as_array().unwrap_or_else(|| panic!("{tile}"));
    let lit = rgb.iter().filter(|p| p[0].as_f64().unwrap() > 0.0).count();
    assert_eq!(lit, 256, "{id}: {lit} of 256 pixels lit");
}

#[tokio::test]
async fn a_zipped_or_tarred_scene_folder_uploads_in_one_request() {
    let app = spawn_app_with_scenes(&[], |_| {}).await;
    let work = tempfile::tempdir().unwrap();
    cbox_folder(work.path());
    run(Command::new("zip")
        .args(["-q", "-r", "cbox.zip", "cbox"])
        .current_dir(work.path()));
    run(Command::new("tar")
        .args(["-czf", "cbox.tgz", "-C", "cbox", "."])
        .current_dir(work.path()));
    // As a user zips it: the folder's name is the scene's id.
    let zip = std::fs::read(work.path().join("cbox.zip")).unwrap();
    let (status, summary) = post(&app, "", "application/zip", zip).await;
    assert_eq!(status, StatusCode::CREATED, "{summary}");
    assert_eq!(summary["id"], "cbox");
    renders(&app, "cbox").await;
    // A gzipped tar of the folder's contents (`./cbox.xml`), sent as bytes
    // of no declared format and named by `id`: the same scene.
    let tgz = std::fs::read(work.path().join("cbox.tgz")).unwrap();
    let (status, again) = post(&app, "?id=cbox-tar", "application/octet-stream", tgz).await;
    assert_eq!(status, StatusCode::CREATED, "{again}");
    assert_eq!(again["digest"], summary["digest"]);
    renders(&app, "cbox-tar").await;
    // `file` names the scene file; one the archive lacks is refused.
    let zip = std::fs::read(work.path().join("cbox.zip")).unwrap();
    let (status, error) = post(&app, "?file=scene.xml", "application/zip", zip).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(error["error"]["field"], "file", "{error}");
}

/// A zip of `entries` (name, bytes) made by the test.
fn zip_of(entries: impl IntoIterator<Item = (String, Vec<u8>)>) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    let mut zip = zip::ZipWriter::new(&mut out);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        zip.start_file(name, options).unwrap();
        zip.write_all(&bytes).unwrap();
    }
    zip.finish().unwrap();
    out.into_inner()
}

/// A tar of a scene file and one entry of `kind` named `name`.
fn tar_with(name: &str, kind: tar::EntryType) -> Vec<u8> {
    let mut tar = tar::Builder::new(Vec::new());
    for (name, kind, bytes) in [
        ("scene.json", tar::EntryType::Regular, TINY_SCENE.as_bytes()),
        (name, kind, b"".as_slice()),
    ] {
        let mut header = tar::Header::new_gnu();
        header.set_entry_type(kind);
        header.set_size(bytes.len() as u64);
        header.set_mode(0o644);
        header.as_gnu_mut().unwrap().name[..name.len()].copy_from_slice(name.as_bytes());
        if kind == tar::EntryType::Symlink {
            header.set_link_name("/etc/passwd").unwrap();
        }
        header.set_cksum();
        tar.append(&header, bytes).unwrap();
    }
    tar.into_inner().unwrap()
}

#[tokio::test]
async fn bad_archives_are_refused_naming_the_entry_and_nothing_is_lost() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |config| {
        config.limits.max_unpacked_bytes = 128 << 20;
    })
    .await;
    let scene = || ("scene.json".to_owned(), TINY_SCENE.as_bytes().to_vec());
    // 256 MiB of zeros in about a quarter of a mebibyte.
    let bomb = {
        let mut out = std::io::Cursor::new(Vec::new());
        let mut zip = zip::ZipWriter::new(&mut out);
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .compression_level(Some(9))
            .large_file(true);
        zip.start_file("zeros.bin", options).unwrap();
        let zeros = vec![0u8; 1 << 20];
        for _ in 0..256 {
            zip.write_all(&zeros).unwrap();
        }
        zip.finish().unwrap();
        out.into_inner()
    };
    assert!(bomb.len() < 1 << 20, "{} bytes", bomb.len());
    let flood = zip_of(
        std::iter::once(scene()).chain((0..10_000).map(|i| (format!("f/{i}.txt"), vec![b'x']))),
    );
    let cases: Vec<(&str, &str, Vec<u8>, &str, &str)> = vec![
        (
            "zip bomb",
            "application/zip",
            bomb,
            "archive[0]",
            "max_compression_ratio",
        ),
        (
            "`..` entry",
            "application/zip",
            zip_of([scene(), ("../evil.txt".into(), b"x".to_vec())]),
            "archive[1]",
            "\"../evil.txt\"",
        ),
        (
            "link",
            "application/x-tar",
            tar_with("link", tar::EntryType::Symlink),
            "archive[1]",
            "is a link",
        ),
        (
            "FIFO",
            "application/x-tar",
            tar_with("pipe", tar::EntryType::Fifo),
            "archive[1]",
            "special file",
        ),
        (
            "10,000 entries",
            "application/zip",
            flood,
            "archive[4096]",
            "max_assets",
        ),
    ];
    for (what, content_type, body, field, says) in cases {
        let started = std::time::Instant::now();
        let (status, error) = post(&app, "", content_type, body).await;
        eprintln!("{what}: {status} in {:?}", started.elapsed());
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{what}: {error}");
        assert_eq!(error["error"]["field"], field, "{what}: {error}");
        let message = error["error"]["message"].as_str().unwrap();
        assert!(message.contains(says), "{what}: {message}");
    }
    // Bytes that are no archive at all, declared as one or not.
    let (status, error) = post(&app, "", "application/zip", b"PK but not".to_vec()).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{error}");
    assert_eq!(error["error"]["field"], "body");
    let (status, _) = post(&app, "", "application/octet-stream", b"<scene/>".to_vec()).await;
    assert_eq!(status, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    // The service is healthy and its scene intact.
    assert_eq!(app.get("/health").await.status(), StatusCode::OK);
    assert_eq!(app.scene_ids().await, ["tiny"]);
}

/// `bmc-irradiance upload DIR` packs the folder and sends it: the scene is
/// named after the folder; a folder holding a link is refused, the CLI
/// saying what the service said.
#[tokio::test]
async fn the_cli_uploads_a_scene_folder() {
    let app = spawn_app_with_scenes(&[], |_| {}).await;
    let work = tempfile::tempdir().unwrap();
    cbox_folder(work.path());
    let upload = |folder: std::path::PathBuf| {
        let base = app.base.clone();
        tokio::task::spawn_blocking(move || {
            Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
                .args(["upload", "--url", &base])
                .arg(folder)
                .output()
                .unwrap()
        })
    };
    let output = upload(work.path().join("cbox")).await.unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["id"], "cbox");
    renders(&app, "cbox").await;
    std::os::unix::fs::symlink("/etc/passwd", work.path().join("cbox/meshes/x.obj")).unwrap();
    let output = upload(work.path().join("cbox")).await.unwrap();
    assert!(!output.status.success());
    let said = String::from_utf8_lossy(&output.stderr);
    assert!(
        said.contains("is a link") && said.contains("archive["),
        "{said}"
    );
}

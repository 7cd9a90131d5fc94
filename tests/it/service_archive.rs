//! `POST /v1/scenes` with a packed scene folder: the tutorials' Cornell box
//! folder zipped, tarred and `git archive`d by the system's own tools
//! uploads in one request and renders; archives that would escape, link,
//! hold special files, flood, explode (in a file, in an entry that is not
//! unpacked, in a header) or name an entry twice are refused naming the
//! entry, with the service's memory bounded, and the service keeps its
//! scenes.

use std::io::Write;
use std::path::Path;
use std::process::Command;

use crate::common::{
    TINY_SCENE, TestApp, copy_dir, peak_rss, scene_ids_at, serve, spawn_app_with_scenes,
};
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

/// `bytes` gzipped in members of 16 KiB each, then an empty member: what
/// bgzip writes (in members of 64 KiB, which would hold all of this
/// folder's tar but its padding), `cat a.gz b.gz` and parallel packers.
fn gzip_members(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for chunk in bytes.chunks(16 << 10).chain([&[][..]]) {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(chunk).unwrap();
        out.extend(gz.finish().unwrap());
    }
    out
}

/// The tutorials' Cornell box folder packed as users pack a folder: by
/// `git archive` of the repository that holds it (a pax global header with
/// the commit id first), by GNU tar in its default format and in the pax
/// format (an extended header before every entry), and GNU tar's gzipped
/// in several members. Each uploads as the same scene; the first two
/// render.
#[tokio::test]
async fn what_git_archive_and_tar_write_uploads_and_renders() {
    let app = spawn_app_with_scenes(&[], |_| {}).await;
    let work = tempfile::tempdir().unwrap();
    cbox_folder(work.path());
    let out = |name: &str| work.path().join(name);
    run(Command::new("tar")
        .args(["-czf", "gnu.tgz", "cbox"])
        .current_dir(work.path()));
    run(Command::new("tar")
        .args(["--format=pax", "-czf", "pax.tgz", "cbox"])
        .current_dir(work.path()));
    run(Command::new("tar")
        .args(["-cf", "gnu.tar", "cbox"])
        .current_dir(work.path()));
    // The folder as a repository of its own, archived at its commit.
    let repo = out("repo");
    copy_dir(&out("cbox"), &repo);
    let git = |args: &[&str]| {
        run(Command::new("git")
            .args(["-c", "user.name=test", "-c", "user.email=test@example.com"])
            .args([
                "-c",
                "commit.gpgsign=false",
                "-c",
                "init.defaultBranch=main",
            ])
            .args(args)
            .env_remove("GIT_DIR")
            .env_remove("GIT_WORK_TREE")
            .env_remove("GIT_INDEX_FILE")
            .current_dir(&repo))
    };
    git(&["init", "-q"]);
    git(&["add", "."]);
    git(&["commit", "-q", "-m", "The Cornell box"]);
    git(&[
        "archive",
        "--format=tar.gz",
        "--prefix=cbox/",
        "-o",
        "../git.tgz",
        "HEAD",
    ]);
    let git_tgz = std::fs::read(out("git.tgz")).unwrap();
    // What makes it a `git archive`: the commit id in a pax global header.
    let mut head = Vec::new();
    std::io::Read::read_to_end(
        &mut flate2::read::GzDecoder::new(git_tgz.as_slice()),
        &mut head,
    )
    .unwrap();
    assert_eq!(&head[..17], b"pax_global_header");
    assert_eq!(head[156], b'g');

    let (status, summary) = post(&app, "", "application/gzip", git_tgz).await;
    assert_eq!(status, StatusCode::CREATED, "{summary}");
    assert_eq!(summary["id"], "cbox");
    renders(&app, "cbox").await;
    let members = gzip_members(&std::fs::read(out("gnu.tar")).unwrap());
    for (id, body) in [
        ("cbox-gnu", std::fs::read(out("gnu.tgz")).unwrap()),
        ("cbox-pax", std::fs::read(out("pax.tgz")).unwrap()),
        ("cbox-members", members),
    ] {
        let query = format!("?id={id}");
        let (status, again) = post(&app, &query, "application/octet-stream", body).await;
        assert_eq!(status, StatusCode::CREATED, "{id}: {again}");
        assert_eq!(again["digest"], summary["digest"], "{id}");
    }
    renders(&app, "cbox-gnu").await;
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
    // Two `scene.json`, as Python's `zipfile` writes when asked to: the
    // zip writer here refuses, so the second is renamed in its bytes.
    let named = TINY_SCENE
        .replacen('{', r#"{"name": "twice", "#, 1)
        .into_bytes();
    let mut twice = zip_of([
        ("scene.json".into(), named.clone()),
        ("scene.jsoX".into(), named),
    ]);
    let mut renamed = 0;
    for at in 0..twice.len() - 10 {
        if &twice[at..at + 10] == b"scene.jsoX" {
            twice[at + 9] = b'n';
            renamed += 1;
        }
    }
    assert_eq!(renamed, 2, "the local header and the central directory");
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
        (
            "a name twice",
            "application/zip",
            twice,
            "archive[1]",
            "\"scene.json\" is named twice",
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

/// A tar header of entry `name` of `kind` and `size` bytes, its name
/// written raw.
fn header(name: &str, kind: tar::EntryType, size: u64) -> tar::Header {
    let mut header = tar::Header::new_gnu();
    header.set_entry_type(kind);
    header.set_size(size);
    header.set_mode(0o644);
    header.as_gnu_mut().unwrap().name[..name.len()].copy_from_slice(name.as_bytes());
    header.set_cksum();
    header
}

/// A gzipped tar of a scene file, then entry `name` of `kind` holding `mib`
/// mebibytes of zeros (about a kilobyte packed per mebibyte), then a file.
fn bomb(name: &str, kind: tar::EntryType, mib: u64) -> Vec<u8> {
    let document = TINY_SCENE.replacen('{', r#"{"name": "bomb", "#, 1);
    let mut before = tar::Builder::new(Vec::new());
    let scene = header("scene.json", tar::EntryType::Regular, document.len() as u64);
    before.append(&scene, document.as_bytes()).unwrap();
    let mut before = before.into_inner().unwrap();
    // Without the end-of-archive blocks `into_inner` wrote.
    before.truncate(before.len() - 1024);
    before.extend(header(name, kind, mib << 20).as_bytes());
    let mut after = tar::Builder::new(Vec::new());
    after
        .append(
            &header("after.obj", tar::EntryType::Regular, 1),
            b"#".as_slice(),
        )
        .unwrap();
    bmc_irradiance::testing::gzip_with_zeros(&before, mib, &after.into_inner().unwrap())
}

/// Bombs where nothing is unpacked, against the real binary: 8 GiB of
/// zeros packed in 8 MB as a file a packer adds on its own (skipped) and as
/// a pax global header (skipped), and a pax extended header of 1 GiB (which
/// the tar parser holds in memory). Each is refused naming the entry after
/// a few mebibytes of inflation; the service's memory stays far below what
/// they claim, it stays healthy and keeps its scene.
#[tokio::test]
async fn bombs_in_entries_not_unpacked_are_refused_in_bounded_memory() {
    let scenes = tempfile::tempdir().unwrap();
    std::fs::write(scenes.path().join("tiny.json"), TINY_SCENE).unwrap();
    let data = tempfile::tempdir().unwrap();
    let (service, addr) = serve(scenes.path(), data.path());
    // Only turns a hang into a failure; nothing here is timed.
    let client = reqwest::Client::builder()
        .timeout(std::time::Duration::from_secs(600))
        .build()
        .unwrap();
    let url = |path: &str| format!("http://{addr}{path}");
    let cases = [
        (
            ".DS_Store",
            tar::EntryType::Regular,
            8 << 10,
            "max_compression_ratio",
        ),
        (
            "pax_global_header",
            tar::EntryType::XGlobalHeader,
            8 << 10,
            "max_compression_ratio",
        ),
        (
            "PaxHeaders/after.obj",
            tar::EntryType::XHeader,
            1 << 10,
            "headers",
        ),
    ];
    for (name, kind, mib, says) in cases {
        let body = bomb(name, kind, mib);
        assert!(body.len() < 9 << 20, "{name}: {} bytes", body.len());
        let started = std::time::Instant::now();
        let response = client
            .post(url("/v1/scenes"))
            .header("content-type", "application/gzip")
            .body(body)
            .send()
            .await
            .unwrap();
        let status = response.status();
        let error: Value = response.json().await.unwrap();
        eprintln!("{name}: {status} in {:?}", started.elapsed());
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{name}: {error}");
        assert_eq!(error["error"]["field"], "archive[1]", "{name}: {error}");
        let message = error["error"]["message"].as_str().unwrap();
        assert!(message.contains(says), "{name}: {message}");
    }
    let peak = peak_rss(service.0.id());
    eprintln!("peak RSS {} MiB", peak >> 20);
    // The 1 GiB header alone would take it past this.
    assert!(peak < 512 << 20, "peak RSS {} MiB", peak >> 20);
    let health = client.get(url("/health")).send().await.unwrap();
    assert_eq!(health.status(), StatusCode::OK);
    assert_eq!(scene_ids_at(&client, &url("")).await, ["tiny"]);
}

//! The curl walkthrough `examples/walkthrough.sh` (described in
//! `docs/service.md`) runs top to bottom against a real server with the
//! bundled scenes, leaves the scenes it did not add alone and no file behind,
//! and gives the answer `docs/service.md` shows (the bundled scenes' count);
//! `docs/service.md` lists every route the service documents.

use std::path::Path;

use crate::common::{copy_dir, spawn_app, spawn_app_in};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs the script against a fresh server with the bundled scenes; with
/// `token`, the server requires it and the script gets it as `BMC_TOKEN`.
async fn run_walkthrough(token: Option<&str>) {
    let scenes = tempfile::tempdir().unwrap();
    copy_dir(&root().join("scenes"), scenes.path());
    let app = spawn_app_in(scenes, |config| {
        config.server.auth_token = token.unwrap_or_default().to_owned();
    })
    .await;
    let bundled = app.scene_ids().await;
    assert!(bundled.iter().any(|id| id == "cornell-box"), "{bundled:?}");

    // Where it runs, and where its temporary folder goes.
    let (out, tmp) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let mut command = tokio::process::Command::new("bash");
    command
        .arg(root().join("examples/walkthrough.sh"))
        .arg(&app.base)
        .current_dir(out.path())
        .env("TMPDIR", tmp.path())
        .env_remove("BMC_TOKEN");
    if let Some(token) = token {
        command.env("BMC_TOKEN", token);
    }
    let run = command
        .output()
        .await
        .expect("bash and curl must be installed");
    assert!(
        run.status.success(),
        "{}\n--- stdout\n{}\n--- stderr\n{}",
        run.status,
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    // The health line shows as many scenes as docs/service.md says it does.
    let scenes = format!(r#""scenes":{},"#, bundled.len());
    assert!(stdout.contains(&scenes), "{stdout}");
    let doc = std::fs::read_to_string(root().join("docs/service.md")).unwrap();
    assert!(
        doc.contains(&scenes),
        "docs/service.md's health example: {scenes}"
    );
    assert!(stdout.contains(r#""status":"ok""#), "{stdout}");
    assert!(stdout.contains("image/png, "), "{stdout}");
    assert!(stdout.contains(r#""irradiance""#), "{stdout}");
    assert!(stdout.contains(r#""radiance""#), "{stdout}");
    // The uploaded scenes are gone again, the bundled ones untouched, and
    // nothing is left where it ran.
    assert_eq!(app.scene_ids().await, bundled);
    for dir in [out.path(), tmp.path()] {
        let left: Vec<_> = std::fs::read_dir(dir).unwrap().collect();
        assert!(left.is_empty(), "{left:?}");
    }
}

#[tokio::test]
async fn the_walkthrough_runs_top_to_bottom() {
    run_walkthrough(None).await;
}

#[tokio::test]
async fn the_walkthrough_passes_bmc_token_to_a_guarded_service() {
    run_walkthrough(Some("walkthrough-token")).await;
}

/// `docs/service.md`'s route table has a row for every method and path of
/// the service's OpenAPI document, and no other.
#[tokio::test]
async fn the_service_doc_lists_every_route() {
    let app = spawn_app().await;
    let openapi: serde_json::Value = app.get("/openapi.json").await.json().await.unwrap();
    let mut routes: Vec<String> = Vec::new();
    for (path, item) in openapi["paths"].as_object().unwrap() {
        // The GET tile's last segment is `{ty}.{format}` in the document.
        let path = path.replace("{ty_format}", "{ty}.{format}");
        for method in item.as_object().unwrap().keys() {
            routes.push(format!("{} {path}", method.to_uppercase()));
        }
    }
    let doc = std::fs::read_to_string(root().join("docs/service.md")).unwrap();
    let mut rows: Vec<String> = doc
        .lines()
        .filter_map(|line| line.strip_prefix("| `"))
        .filter_map(|row| row.split_once('`').map(|(route, _)| route.to_owned()))
        .collect();
    routes.sort();
    rows.sort();
    assert_eq!(rows, routes, "docs/service.md's route table");
}

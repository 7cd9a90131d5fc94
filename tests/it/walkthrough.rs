//! The README's curl walkthrough is `examples/walkthrough.sh`: it runs top to
//! bottom against a real server with the bundled scenes, leaves the scenes it
//! did not add alone and no file behind, and the README shows its commands
//! verbatim, with the answers it shows (the bundled scenes' count).

use std::path::Path;

use crate::common::{copy_dir, spawn_app_in};

const MARKER: &str = "# --- walkthrough";

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
    // The health line shows as many scenes as the README says it does.
    let scenes = format!(r#""scenes":{},"#, bundled.len());
    assert!(stdout.contains(&scenes), "{stdout}");
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    assert!(
        readme.contains(&scenes),
        "README.md's health example: {scenes}"
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

#[test]
fn the_readme_shows_the_walkthrough() {
    let script = std::fs::read_to_string(root().join("examples/walkthrough.sh")).unwrap();
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let start = script.find(MARKER).expect("the script has the marker");
    let body = &script[script[start..].find('\n').unwrap() + start + 1..];
    // The README indents code blocks by four spaces.
    let shown: String = body
        .lines()
        .map(|line| {
            if line.is_empty() {
                "\n".to_owned()
            } else {
                format!("    {line}\n")
            }
        })
        .collect();
    assert!(
        readme.contains(&shown),
        "README.md must show examples/walkthrough.sh from its marker on, indented by four spaces"
    );
}

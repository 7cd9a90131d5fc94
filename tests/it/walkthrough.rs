//! The README's curl walkthrough is `examples/walkthrough.sh`: it runs top to
//! bottom against a real server with the bundled scenes, leaves the scenes it
//! did not add alone, and the README shows its commands verbatim.

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

    let out = tempfile::tempdir().unwrap();
    let mut command = tokio::process::Command::new("bash");
    command
        .arg(root().join("examples/walkthrough.sh"))
        .arg(&app.base)
        .current_dir(out.path())
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
    assert!(stdout.contains(r#""status":"ok""#), "{stdout}");
    assert!(stdout.contains(r#""irradiance""#), "{stdout}");
    assert!(stdout.contains(r#""radiance""#), "{stdout}");
    let tile = image::open(out.path().join("tile.png")).expect("tile.png is a PNG");
    assert_eq!((tile.width(), tile.height()), (64, 64));
    // The uploaded scenes are gone again, the bundled ones untouched.
    assert_eq!(app.scene_ids().await, bundled);
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

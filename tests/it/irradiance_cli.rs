//! Runs the real `bmc-irradiance irradiance` binary on the bundled Cornell box.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn manifest_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn write_points(name: &str, text: &str) -> PathBuf {
    let path =
        std::env::temp_dir().join(format!("bmc-irradiance-{name}-{}.csv", std::process::id()));
    std::fs::write(&path, text).expect("write points file");
    path
}

fn run(points: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
        .arg("irradiance")
        .arg("--scene")
        .arg(manifest_dir().join("scenes/cornell-box.json"))
        .arg("--points")
        .arg(points)
        .args(extra)
        .output()
        .expect("binary runs")
}

/// Runs with whitespace-separated `args`, expects success and returns the
/// numeric rows of the CSV written with `--std-error`.
fn run_ok(points: &Path, args: &str) -> Vec<Vec<f64>> {
    let output = run(points, &args.split_whitespace().collect::<Vec<_>>());
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = String::from_utf8(output.stdout).expect("utf-8 output");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,r,g,b,se_r,se_g,se_b"));
    lines
        .map(|l| l.split(',').map(|f| f.parse().expect("number")).collect())
        .collect()
}

#[test]
fn cornell_box_irradiance_is_written_as_csv() {
    let points = write_points(
        "cornell",
        "x,y,z,nx,ny,nz\n0,-0.999,0.8,0,1,0\n-0.999,0,0,1,0,0\n0.999,0,0,-1,0,0\n",
    );
    let direct = run_ok(
        &points,
        "--samples 1024 --direct-only --std-error --threads 2",
    );
    let full = run_ok(&points, "--samples 1024 --max-depth 8 --std-error --seed 3");
    assert_eq!(direct.len(), 3);
    assert_eq!(full.len(), 3);
    for (d, f) in direct.iter().zip(&full) {
        assert_eq!(d[..3], f[..3], "rows keep the input order");
        for c in 3..6 {
            assert!(d[c] > 0.0 && d[c].is_finite(), "{d:?}");
        }
        // Interreflection adds a clearly measurable amount of red and green.
        for c in 3..5 {
            let noise = 4.0 * d[c + 3].hypot(f[c + 3]);
            assert!(f[c] > d[c] + noise, "{d:?} {f:?}");
        }
    }
    std::fs::remove_file(points).ok();
}

#[test]
fn bad_rows_and_bad_options_fail_with_a_message() {
    let points = write_points("bad", "0,0,0,0,1,0\n0,0,0,0,0,0\n");
    let out = run(&points, &["--samples", "4"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("line 2") && stderr.contains("normal"),
        "{stderr}"
    );

    let good = write_points("good", "0,0,0,0,1,0\n");
    let out = run(&good, &["--samples", "0"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("samples"));
    std::fs::remove_file(points).ok();
    std::fs::remove_file(good).ok();
}

/// The CLI and `POST /v1/scenes/{id}/irradiance` take one document (the
/// library's `PointQuerySpec`) and run one `PointQuery`, so the same
/// options and seed give the same numbers, and so do their defaults: a
/// command line and a request that name no estimator, samples or seed. That
/// holds for error targets, and for a query of enough points to place
/// records among them (the records prior), on a service that has rendered
/// nothing of the scene before (the last case: the service keeps them).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cli_and_http_give_the_same_numbers_for_each_estimator() {
    let cornell = include_str!("../../scenes/cornell-box.json");
    let app = crate::common::spawn_app_with_scenes(&[("cornell-box.json", cornell)], |_| {}).await;
    let few = vec![
        [0.0, -0.999, 0.3, 0.0, 1.0, 0.0],
        [-0.999, 0.2, 0.0, 1.0, 0.0, 0.0],
        [0.3, 0.999, -0.2, 0.0, -1.0, 0.0],
    ];
    // A floor grid of 64 points, enough for records to be placed among them.
    let grid: Vec<[f64; 6]> = (0..64)
        .map(|i| {
            let at = |k: usize| -0.875 + 0.25 * k as f64;
            [at(i % 8), -0.999, at(i / 8), 0.0, 1.0, 0.0]
        })
        .collect();
    let cases = [
        (&few, "", serde_json::json!({})),
        (
            &few,
            "--estimator bmc --samples 64 --lengthscale 0.5 --seed 3",
            serde_json::json!({"seed": 3, "estimator": {"method": "bmc", "samples": 64,
                               "kernel": {"lengthscale": 0.5}}}),
        ),
        (
            &few,
            "--estimator bmc --samples 32 --kernel matern52 --sample-set fibonacci \
             --decomposition hemisphere --seed 3",
            serde_json::json!({"seed": 3, "estimator": {"method": "bmc", "samples": 32,
                               "decomposition": "hemisphere", "sample_set": {"kind": "fibonacci"},
                               "kernel": {"kind": "matern52"}}}),
        ),
        (
            &few,
            "--estimator qmc --samples 64 --seed 3",
            serde_json::json!({"seed": 3, "estimator": {"method": "qmc", "samples": 64}}),
        ),
        (
            &few,
            "--estimator mc --samples 64 --seed 3",
            serde_json::json!({"seed": 3, "estimator": {"method": "mc", "samples": 64}}),
        ),
        (
            &few,
            "--samples 32 --target 0.1 --max-samples 256 --max-depth 2",
            serde_json::json!({"max_depth": 2, "estimator": {"samples": 32},
                               "target": {"relative_error": 0.1, "max_samples": 256}}),
        ),
        (
            &grid,
            "--samples 16 --max-depth 2",
            serde_json::json!({"max_depth": 2, "estimator": {"samples": 16}}),
        ),
    ];
    for (rows, args, mut body) in cases {
        let csv: String = rows
            .iter()
            .map(|r| r.map(|v| v.to_string()).join(",") + "\n")
            .collect();
        let points = write_points("cli-vs-http", &csv);
        let cli = tokio::task::spawn_blocking({
            let points = points.clone();
            move || run_ok(&points, &format!("{args} --std-error"))
        })
        .await
        .unwrap();
        std::fs::remove_file(points).ok();
        body["points"] = rows
            .iter()
            .map(|r| serde_json::json!({"position": [r[0], r[1], r[2]], "normal": [r[3], r[4], r[5]]}))
            .collect();
        let response = app
            .post_json("/v1/scenes/cornell-box/irradiance", &body)
            .await;
        assert_eq!(response.status(), reqwest::StatusCode::OK, "{args}");
        let http: serde_json::Value = response.json().await.unwrap();
        if rows.len() == grid.len() {
            let moved = http["records_prior_points"].as_u64().unwrap_or(0);
            assert!(moved > 0, "records placed among the grid serve it: {http}");
        }
        assert_eq!(cli.len(), rows.len(), "{args}");
        for (i, row) in cli.iter().enumerate() {
            let value: Vec<f64> = serde_json::from_value(http["irradiance"][i].clone()).unwrap();
            let std_dev: Vec<f64> = serde_json::from_value(http["std_dev"][i].clone()).unwrap();
            assert_eq!(row[3..6], value[..], "{args}: point {i}");
            assert_eq!(row[6..9], std_dev[..], "{args}: point {i}");
        }
    }
}

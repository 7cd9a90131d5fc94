//! End to end: the real binary's `quadrature` subcommand.

use std::process::Command;

fn bmc_irradiance(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
        .args(args)
        .output()
        .expect("binary runs")
}

#[test]
fn quadrature_json_has_the_contracted_fields_and_gls_weights_sum_to_one() {
    let out = bmc_irradiance(&[
        "quadrature",
        "--set",
        "fibonacci",
        "--samples",
        "64",
        "--kernel",
        "se",
        "--lengthscale",
        "0.5",
        "--density",
        "lambert",
        "--prior-mean",
        "gls",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    let directions = json["directions"].as_array().expect("directions");
    assert_eq!(directions.len(), 64);
    for d in directions {
        let v: Vec<f64> = d
            .as_array()
            .expect("[x,y,z]")
            .iter()
            .map(|c| c.as_f64().expect("number"))
            .collect();
        assert_eq!(v.len(), 3);
        let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        assert!((norm - 1.0).abs() < 1e-12 && v[2] >= 0.0);
    }
    let numbers = |field: &str| -> Vec<f64> {
        json[field]
            .as_array()
            .unwrap_or_else(|| panic!("{field}"))
            .iter()
            .map(|x| x.as_f64().expect("number"))
            .collect()
    };
    assert_eq!(numbers("kernel_means").len(), 64);
    let weights = numbers("weights");
    assert_eq!(weights.len(), 64);
    assert!((weights.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    let prior = json["prior_variance"].as_f64().expect("prior_variance");
    let posterior = json["posterior_variance"]
        .as_f64()
        .expect("posterior_variance");
    assert!(0.0 <= posterior && posterior < prior);
    assert!(json["jitter"].as_f64().expect("jitter") >= 0.0);
    assert!(
        json["condition_estimate"]
            .as_f64()
            .expect("condition_estimate")
            >= 1.0
    );
    assert_eq!(json["cached"], serde_json::Value::Bool(false));
    assert!((json["density_integral"].as_f64().expect("density_integral") - 1.0).abs() < 1e-12);
}

#[test]
fn quadrature_summary_and_phong_and_matern() {
    let out = bmc_irradiance(&[
        "quadrature",
        "--samples",
        "16",
        "--kernel",
        "matern52",
        "--lengthscale",
        "0.8",
        "--density",
        "phong",
        "--exponent",
        "10",
        "--mirror-elevation",
        "0.4",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("weights") && text.contains("posterior variance"),
        "{text}"
    );
}

#[test]
fn bad_parameters_fail_with_the_field_named() {
    for (args, field) in [
        (vec!["quadrature", "--samples", "0"], "samples"),
        (vec!["quadrature", "--lengthscale", "-1"], "lengthscale"),
        (vec!["quadrature", "--lengthscale", "NaN"], "lengthscale"),
        (vec!["quadrature", "--density", "phong"], "exponent"),
        (
            vec!["quadrature", "--density", "phong", "--exponent", "-2"],
            "exponent",
        ),
    ] {
        let out = bmc_irradiance(&args);
        assert!(!out.status.success(), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(field), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// `bmc-irradiance … | head -1`: a reader that closes the pipe early ends
/// the command quietly and successfully, with no error or panic.
#[test]
fn a_closed_output_pipe_ends_the_command_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
        .args(["quadrature", "--samples", "1024", "--json"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("binary runs");
    // Closed long before the factorisation of 1024 directions is written.
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("binary ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    assert!(
        !stderr.contains("Error") && !stderr.contains("panicked"),
        "{stderr}"
    );
}

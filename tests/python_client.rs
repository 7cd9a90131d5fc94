//! The Python package (`python/`, import name `bmc_irradiance`) against the
//! service binary this build made: creates a virtual environment under
//! `target/python-venv` (or reuses it), installs `./python[test]` into it
//! (numpy and pytest from PyPI) and runs `python -m pytest python/tests -q`
//! with `BMC_IRRADIANCE_BIN` naming the binary. The pytest fixtures start
//! the service on ephemeral ports with temporary copies of `scenes/`.
//!
//! The Python client is part of what CI checks: without `python3` (with its
//! `venv` module) or without network access to PyPI this test fails, saying
//! which one is missing, rather than skipping.

use std::path::Path;
use std::process::{Command, Output};
use std::time::Instant;

/// Runs `command`, panicking with `hint` and its output unless it succeeds.
fn run(what: &str, command: &mut Command, hint: &str) -> Output {
    let output = command
        .output()
        .unwrap_or_else(|err| panic!("{what}: cannot run {command:?}: {err}\n{hint}"));
    assert!(
        output.status.success(),
        "{what} failed ({}).\n{hint}\n--- stdout ---\n{}\n--- stderr ---\n{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr),
    );
    output
}

/// Whether the environment's Python runs and has pip (a `python3 -m venv`
/// without `ensurepip`, as on Debian without `python3-venv`, leaves one
/// that has no pip).
fn usable(python: &Path) -> bool {
    Command::new(python)
        .args(["-m", "pip", "--version"])
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn python_client_tests_pass_against_the_service_binary() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let venv = root.join("target").join("python-venv");
    let python = if cfg!(windows) {
        venv.join("Scripts").join("python.exe")
    } else {
        venv.join("bin").join("python")
    };
    let started = Instant::now();
    if !usable(&python) {
        if venv.exists() {
            std::fs::remove_dir_all(&venv).expect("remove the broken virtual environment");
        }
        run(
            "python3 -m venv target/python-venv",
            Command::new("python3").args(["-m", "venv"]).arg(&venv),
            "The Python client's tests need Python 3 with its venv module and pip \
             (Debian: apt-get install python3 python3-venv python3-pip).",
        );
    }
    run(
        "pip install ./python[test]",
        Command::new(&python)
            .args([
                "-m",
                "pip",
                "install",
                "--disable-pip-version-check",
                "--quiet",
            ])
            .arg("./python[test]")
            .current_dir(root),
        "Installing the Python client needs network access to PyPI (numpy, pytest, setuptools).",
    );
    let installed = started.elapsed();
    let pytest = Command::new(&python)
        .args([
            "-m",
            "pytest",
            "python/tests",
            "-q",
            "-p",
            "no:cacheprovider",
        ])
        .current_dir(root)
        .env("BMC_IRRADIANCE_BIN", env!("CARGO_BIN_EXE_bmc-irradiance"))
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .output()
        .expect("run pytest in the virtual environment");
    let report = format!(
        "--- pytest stdout ---\n{}\n--- pytest stderr ---\n{}",
        String::from_utf8_lossy(&pytest.stdout),
        String::from_utf8_lossy(&pytest.stderr),
    );
    assert!(
        pytest.status.success(),
        "python -m pytest python/tests failed ({}):\n{report}",
        pytest.status
    );
    println!(
        "environment ready in {:.1} s, pytest took {:.1} s\n{report}",
        installed.as_secs_f64(),
        (started.elapsed() - installed).as_secs_f64()
    );
}

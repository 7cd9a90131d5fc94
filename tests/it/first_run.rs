//! What a new user meets first, through the real binary: `--help` of the
//! subcommands that read scene files.

use std::process::Command;

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

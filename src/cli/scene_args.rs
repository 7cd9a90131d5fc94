//! The scene file options every subcommand that reads a scene shares:
//! `--scene`, `--scenes-root`, `--lenient` and `--param NAME=VALUE`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;

use crate::scene::formats::DocumentKind;
use crate::scene::{MitsubaOptions, Scene};

/// Which scene file to load, and how.
#[derive(Clone, Debug, clap::Args)]
pub struct SceneArgs {
    /// Scene file: JSON, or Mitsuba 3 XML when it ends in `.xml`.
    #[arg(long)]
    pub scene: PathBuf,
    /// Directory that files referenced by the scene may not escape
    /// (default: the scene file's directory).
    #[arg(long)]
    pub scenes_root: Option<PathBuf>,
    /// Mitsuba 3 XML: approximate what the scene model cannot represent
    /// (each approximation printed on stderr) instead of refusing the scene.
    #[arg(long)]
    pub lenient: bool,
    /// Mitsuba 3 XML: the value of a `$NAME` parameter, overriding the file's
    /// `<default>` (like `mitsuba -D NAME=VALUE`); repeatable.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_param)]
    pub params: Vec<(String, String)>,
}

pub(super) fn parse_param(text: &str) -> Result<(String, String), String> {
    match text.split_once('=') {
        Some((name, value)) if !name.trim().is_empty() => {
            Ok((name.trim().to_owned(), value.to_owned()))
        }
        _ => Err(format!("expected NAME=VALUE, got {text:?}")),
    }
}

impl SceneArgs {
    /// `--scenes-root`, else the scene file's directory (`.` for a bare
    /// file name).
    pub fn scenes_root(&self) -> PathBuf {
        match (&self.scenes_root, self.scene.parent()) {
            (Some(root), _) => root.clone(),
            (None, Some(dir)) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        }
    }

    fn is_xml(&self) -> bool {
        DocumentKind::of_file_name(&self.scene) == Some(DocumentKind::MitsubaXml)
    }

    /// Loads the scene; the approximations `--lenient` made go to `warnings`,
    /// one line each. `--lenient` and `--param` are refused for JSON scenes,
    /// which have neither.
    pub fn load(&self, warnings: &mut dyn Write) -> anyhow::Result<Scene> {
        let root = self.scenes_root();
        let context = || format!("loading scene {}", self.scene.display());
        if !self.is_xml() {
            anyhow::ensure!(
                !self.lenient && self.params.is_empty(),
                "--lenient and --param apply to Mitsuba 3 XML scenes (*.xml) only"
            );
            return Scene::load(&self.scene, &root).with_context(context);
        }
        let options = MitsubaOptions {
            lenient: self.lenient,
            parameters: self.params.iter().cloned().collect(),
        };
        let (scene, approximated) =
            Scene::load_mitsuba_xml(&self.scene, &root, &options).with_context(context)?;
        for warning in approximated.iter() {
            writeln!(warnings, "warning: {}: {warning}", self.scene.display())?;
        }
        let unshown = approximated.total() - approximated.len();
        if unshown > 0 {
            writeln!(warnings, "warning: {unshown} more approximations not shown")?;
        }
        Ok(scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        scene: SceneArgs,
    }

    fn parse(line: &str) -> Result<SceneArgs, clap::Error> {
        Cli::try_parse_from(std::iter::once("x").chain(line.split_whitespace())).map(|c| c.scene)
    }

    #[test]
    fn a_bare_file_name_resolves_in_the_working_directory() {
        assert_eq!(
            parse("--scene cbox.xml").unwrap().scenes_root(),
            PathBuf::from(".")
        );
        assert_eq!(
            parse("--scene a/cbox.xml").unwrap().scenes_root(),
            PathBuf::from("a")
        );
    }

    #[test]
    fn params_are_name_value_pairs() {
        let args = parse("--scene s.xml --param spp=4 --param res=a=b").unwrap();
        assert_eq!(
            args.params,
            vec![("spp".into(), "4".into()), ("res".into(), "a=b".into())]
        );
        assert!(parse("--scene s.xml --param spp").is_err());
        assert!(parse("--scene s.xml --param =4").is_err());
    }

    /// The tutorials' habit: a strict load names the feature and the way
    /// out; `--lenient` loads and says what it approximated.
    #[test]
    fn lenient_loads_what_strict_refuses_and_says_what_it_changed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.xml");
        std::fs::write(
            &path,
            r#"<scene version="3.0.0">
                <default name="w" value="8"/>
                <sensor type="perspective">
                    <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
                    <film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="8"/></film>
                </sensor>
                <emitter type="constant"/>
                <shape type="sphere"><bsdf type="unknown-bsdf"/></shape>
            </scene>"#,
        )
        .unwrap();
        let scene = path.display().to_string();
        let strict = parse(&format!("--scene {scene}")).unwrap();
        let err = match strict.load(&mut Vec::new()) {
            Ok(_) => panic!("a strict load accepted an unknown BSDF"),
            Err(err) => format!("{err:#}"),
        };
        assert!(err.contains("lenient"), "{err}");
        let lenient = parse(&format!("--scene {scene} --lenient --param w=16")).unwrap();
        let mut warnings = Vec::new();
        let loaded = lenient.load(&mut warnings).unwrap();
        assert_eq!(loaded.camera.resolution(), (16, 8));
        let warnings = String::from_utf8(warnings).unwrap();
        assert!(warnings.starts_with("warning: "), "{warnings}");
        let json = parse("--scene s.json --lenient").unwrap();
        assert!(json.load(&mut Vec::new()).is_err());
    }
}

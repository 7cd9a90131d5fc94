//! The `irradiance` subcommand: irradiance at the points of a CSV file,
//! written as CSV to the given writer (stdout in the binary).

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use super::in_thread_pool;
use crate::render::Cancel;
use crate::render::irradiance::{IrradianceMethod, IrradianceOptions};
use crate::render::points_csv::{parse_points, write_irradiance};
use crate::render::transport::Transport;
use crate::scene::Scene;

/// Command-line arguments of `bmc-irradiance irradiance`.
#[derive(Clone, Debug, clap::Args)]
pub struct IrradianceArgs {
    /// Scene JSON file.
    #[arg(long)]
    pub scene: PathBuf,
    /// Directory that files referenced by the scene may not escape
    /// (default: the scene file's directory).
    #[arg(long)]
    pub scenes_root: Option<PathBuf>,
    /// CSV of query points, rows `x,y,z,nx,ny,nz` (header optional).
    #[arg(long)]
    pub points: PathBuf,
    /// Hemisphere directions per point (and light samples in split mode).
    #[arg(long, default_value_t = 4096)]
    pub samples: u32,
    /// Longest light path in segments (1 = direct light only).
    #[arg(long, default_value_t = 16)]
    pub max_depth: u32,
    /// Direct light only (same as --max-depth 1).
    #[arg(long)]
    pub direct_only: bool,
    /// `split`: direct light by light sampling + the rest through the
    /// hemisphere; `hemisphere`: everything through the hemisphere.
    #[arg(long, value_enum, default_value_t = MethodArg::Split)]
    pub method: MethodArg,
    /// Reference mode: 65536 samples and depth 64 (overrides both).
    #[arg(long, conflicts_with_all = ["samples", "max_depth"])]
    pub reference: bool,
    /// Seed of all random streams; same seed, same numbers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Append standard-error columns `se_r,se_g,se_b`.
    #[arg(long)]
    pub std_error: bool,
}

/// Estimator split exposed on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    Split,
    Hemisphere,
}

impl IrradianceArgs {
    /// The library options these arguments ask for.
    pub fn options(&self) -> IrradianceOptions {
        let method = match self.method {
            MethodArg::Split => IrradianceMethod::Split,
            MethodArg::Hemisphere => IrradianceMethod::Hemisphere,
        };
        let base = if self.reference {
            IrradianceOptions::reference(self.seed)
        } else {
            IrradianceOptions {
                samples: self.samples,
                max_depth: self.max_depth,
                seed: self.seed,
                ..IrradianceOptions::default()
            }
        };
        IrradianceOptions {
            method,
            direct_only: self.direct_only,
            ..base
        }
    }
}

/// Runs the subcommand; progress goes to stderr (hidden when it is not a
/// terminal), results to `out`.
pub fn run_irradiance(args: &IrradianceArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let options = args.options();
    options.validate()?;
    let text = std::fs::read_to_string(&args.points)
        .with_context(|| format!("reading points file {}", args.points.display()))?;
    let points = parse_points(&text).with_context(|| format!("in {}", args.points.display()))?;
    let root = match &args.scenes_root {
        Some(root) => root.clone(),
        None => match args.scene.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        },
    };
    let scene = Scene::load(&args.scene, &root)
        .with_context(|| format!("loading scene {}", args.scene.display()))?;
    let transport = Transport::new(Arc::new(scene));

    let progress = ProgressBar::new(points.len() as u64);
    progress.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} points, {elapsed} elapsed, ETA {eta}")
            .context("progress bar template")?,
    );
    let estimate =
        || transport.irradiance_at_points(&points, &options, &|| progress.inc(1), &Cancel::never());
    let estimates = in_thread_pool(args.threads, estimate)??;
    progress.finish_and_clear();
    write_irradiance(out, &points, &estimates, args.std_error).context("writing results")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: IrradianceArgs,
    }

    fn parse(line: &str) -> Result<IrradianceArgs, clap::Error> {
        let words = std::iter::once("irradiance").chain(line.split_whitespace());
        Cli::try_parse_from(words).map(|cli| cli.args)
    }

    #[test]
    fn arguments_map_to_options() {
        let args = parse("--scene s.json --points p.csv --samples 64 --max-depth 3 --seed 9")
            .expect("valid");
        let o = args.options();
        assert_eq!((o.samples, o.max_depth, o.seed), (64, 3, 9));
        assert_eq!(o.method, IrradianceMethod::Split);
        assert!(!o.direct_only);

        let args =
            parse("--scene s.json --points p.csv --reference --direct-only --method hemisphere")
                .expect("valid");
        let expected = IrradianceOptions {
            method: IrradianceMethod::Hemisphere,
            direct_only: true,
            ..IrradianceOptions::reference(1)
        };
        assert_eq!(args.options(), expected);
    }

    #[test]
    fn reference_mode_conflicts_with_explicit_budgets() {
        assert!(parse("--scene s.json --points p.csv --reference --samples 5").is_err());
        assert!(parse("--scene s.json --points p.csv --method sideways").is_err());
    }
}

//! `bmc-irradiance study`: the estimator convergence study on synthetic
//! environments, and `study-scene`: the same estimators on a real scene.

use anyhow::Context;
use clap::Args;

use crate::render::PathDepth;
use crate::study::convergence::{self, StudyOptions};

/// Arguments of `bmc-irradiance study`.
#[derive(Clone, Debug, Args)]
pub struct StudyArgs {
    /// Test environments per family.
    #[arg(long, default_value_t = 20)]
    pub seeds: u64,
    /// Training environments per family for the BMC hyperparameter fit.
    #[arg(long, default_value_t = 40)]
    pub training: u64,
    /// Master seed.
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// Print JSON rows instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
}

/// Runs the study: the text to print on stdout.
pub fn run(args: &StudyArgs) -> anyhow::Result<String> {
    let options = StudyOptions {
        environments: args.seeds,
        training_environments: args.training,
        seed: args.seed,
        ..StudyOptions::default()
    };
    let rows = convergence::run(&options)?;
    Ok(if args.json {
        serde_json::to_string_pretty(&rows)?
    } else {
        convergence::markdown_table(&rows)
    })
}

/// Arguments of `bmc-irradiance study-scene`.
#[derive(Clone, Debug, Args)]
pub struct SceneStudyArgs {
    #[command(flatten)]
    pub scene: super::scene_args::SceneArgs,
    /// Camera-visible query points.
    #[arg(long, default_value_t = 200)]
    pub points: usize,
    /// Request seeds per estimator and N.
    #[arg(long, default_value_t = 6)]
    pub seeds: u64,
    /// Hemisphere samples per point, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [16, 64, 256])]
    pub samples: Vec<u32>,
    #[arg(long, value_enum, default_value_t = crate::render::IrradianceMethod::Auto)]
    pub decomposition: crate::render::IrradianceMethod,
    /// Longest path in segments (1 = direct light only).
    #[arg(long, default_value_t = PathDepth::default(), value_parser = super::max_depth_parser())]
    pub max_depth: PathDepth,
    /// Samples of each point's reference.
    #[arg(long, default_value_t = 16_384)]
    pub reference_samples: u32,
    /// Seed of the points, their reference and the request seeds.
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// `bmc` rows: the kernel (`--kernel`, `--lengthscale`, `--variance`,
    /// `--noise`, as the `irradiance` command takes them).
    #[command(flatten)]
    pub kernel: Option<crate::estimators::KernelSpec>,
    /// Also run `qmc` and `bmc` with the records prior (docs/math.md §10.7),
    /// on records placed by rendering the camera image once with this
    /// preset's cache settings (`draft`, `preview`, `standard`, `final`).
    #[arg(long, value_enum)]
    pub records_from: Option<crate::integrator::Preset>,
    /// With `--records-from`: also run `qmc` and `bmc` with direct-light
    /// records at the records' places as a prior on the direct part, made as
    /// the study's decomposition estimates it (docs/math.md §10.8).
    #[arg(long, requires = "records_from")]
    pub direct_records: bool,
    /// Also write the study's points here (`x,y,z,nx,ny,nz`, the input of
    /// `irradiance --points`), e.g. to compute their reference elsewhere.
    #[arg(long)]
    pub points_out: Option<std::path::PathBuf>,
    /// Run the error-target study instead: each estimator to this relative
    /// error in batches of the first `--samples`, against fixed N.
    #[arg(long)]
    pub target: Option<f64>,
    /// Confidence of `--target`.
    #[arg(long, default_value_t = 0.95)]
    pub confidence: f64,
    /// Sample cap per point of `--target`.
    #[arg(long, default_value_t = 16_384)]
    pub max_samples: u32,
    /// Print JSON rows instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
}

/// Runs the scene study: the text to print on stdout.
pub fn run_scene(args: &SceneStudyArgs) -> anyhow::Result<String> {
    use crate::study::scenes::{self, SceneStudyOptions};
    let scene = args.scene.load(&mut std::io::stderr())?;
    let name = args
        .scene
        .scene
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let transport = crate::render::Transport::new(std::sync::Arc::new(scene));
    let options = SceneStudyOptions {
        points: args.points,
        seeds: args.seeds,
        sample_counts: args.samples.clone(),
        decomposition: args.decomposition,
        max_depth: args.max_depth,
        reference_samples: args.reference_samples,
        seed: args.seed,
        bmc_kernel: args.kernel,
        records_from: args.records_from,
        direct_records: args.direct_records,
    };
    if let Some(path) = &args.points_out {
        let mut out = Vec::new();
        crate::estimators::points_csv::write_points(
            &mut out,
            &scenes::study_points(&transport, &options),
        )?;
        std::fs::write(path, out).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(relative_error) = args.target {
        let target = crate::estimators::error_target::ErrorTarget {
            relative_error,
            confidence: args.confidence,
            max_samples: args.max_samples,
        };
        let batch = args.samples.first().copied().unwrap_or(64);
        let rows = scenes::run_target(&transport, &name, &options, batch, &target)?;
        return Ok(if args.json {
            serde_json::to_string_pretty(&rows)?
        } else {
            scenes::target_markdown_table(&rows)
        });
    }
    let rows = scenes::run(&transport, &name, &options)?;
    Ok(if args.json {
        serde_json::to_string_pretty(&rows)?
    } else {
        scenes::markdown_table(&rows)
    })
}

//! `bmc-irradiance study`: the estimator convergence study.

use clap::Args;

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

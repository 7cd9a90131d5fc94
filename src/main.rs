//! Thin command-line front end; all work lives in the library.

use bmc_irradiance::cli;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "bmc-irradiance",
    version,
    about = "Bayesian Monte Carlo irradiance caching"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the BMC quadrature (directions, kernel means, weights, variances) of one configuration.
    Quadrature(cli::quadrature::QuadratureArgs),
    /// Relative RMSE of MC, QMC and BMC on synthetic environments with known irradiance.
    Study(cli::study::StudyArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let output = match cli.command {
        Command::Quadrature(args) => cli::quadrature::run(&args)?,
        Command::Study(args) => cli::study::run(&args)?,
    };
    println!("{output}");
    Ok(())
}

//! Thin command-line front end; all work lives in the library.

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
enum Command {}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {}
}

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
enum Command {
    /// Irradiance (W/m²) at the points of a CSV file, as CSV on stdout.
    Irradiance(bmc_irradiance::render::irradiance_command::IrradianceArgs),
    /// Render the scene camera's image to EXR (and PNG), tile by tile.
    Render(bmc_irradiance::render::render_command::RenderArgs),
    /// Relative RMSE of an EXR image against a reference EXR.
    Compare(bmc_irradiance::render::render_command::CompareArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Irradiance(args) => bmc_irradiance::render::irradiance_command::run_irradiance(
            &args,
            &mut std::io::stdout().lock(),
        ),
        Command::Render(args) => {
            bmc_irradiance::render::render_command::run_render(&args, &mut std::io::stdout().lock())
        }
        Command::Compare(args) => bmc_irradiance::render::render_command::run_compare(
            &args,
            &mut std::io::stdout().lock(),
        ),
    }
}

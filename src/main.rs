//! Thin command-line front end; all work lives in the library.

use bmc_irradiance::cli;
use std::io::Write;
use std::process::ExitCode;

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
    Irradiance(cli::irradiance::IrradianceArgs),
    /// Run the HTTP service until SIGINT/SIGTERM.
    Serve(bmc_irradiance::service::ServeArgs),
    /// Print the BMC quadrature (directions, kernel means, weights, variances) of one configuration.
    Quadrature(cli::quadrature::QuadratureArgs),
    /// Relative RMSE of MC, QMC and BMC on synthetic environments with known irradiance.
    Study(cli::study::StudyArgs),
    /// Error and calibration of MC, QMC and BMC on a real scene against converged references.
    StudyScene(cli::study::SceneStudyArgs),
    /// Render the scene camera's image to EXR (and PNG), tile by tile.
    Render(cli::render::RenderArgs),
    /// Relative RMSE of an EXR image against a reference EXR.
    Compare(cli::render::CompareArgs),
    /// Fetch a whole camera image from a running service, tile by tile (GET tiles).
    Fetch(cli::fetch::FetchArgs),
    /// Send a scene folder, or a zip, tar or .tar.gz of one, to a running service.
    Upload(cli::upload::UploadArgs),
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader went away (`… | head`): what it wanted was written, as
        // a Unix tool killed by SIGPIPE would have it.
        Err(e) if closed_output(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("Error: {e:?}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Irradiance(args) => {
            cli::irradiance::run_irradiance(&args, &mut std::io::stdout().lock())
        }
        Command::Serve(args) => bmc_irradiance::service::run_serve(&args),
        Command::Quadrature(args) => print_output(cli::quadrature::run(&args)?),
        Command::Study(args) => print_output(cli::study::run(&args)?),
        Command::StudyScene(args) => print_output(cli::study::run_scene(&args)?),
        Command::Render(args) => cli::render::run_render(&args, &mut std::io::stdout().lock()),
        Command::Compare(args) => cli::render::run_compare(&args, &mut std::io::stdout().lock()),
        Command::Fetch(args) => cli::fetch::run_fetch(&args, &mut std::io::stdout().lock()),
        Command::Upload(args) => cli::upload::run_upload(&args, &mut std::io::stdout().lock()),
    }
}

fn print_output(output: String) -> anyhow::Result<()> {
    writeln!(std::io::stdout().lock(), "{output}")?;
    Ok(())
}

/// Whether `e` comes from writing to a pipe whose reader has closed it.
fn closed_output(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

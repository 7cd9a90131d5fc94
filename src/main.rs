//! Thin command-line front end; all work lives in the library.

use std::net::SocketAddr;
use std::path::PathBuf;

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
    /// Run the HTTP service (config: config/default.toml, overridable by
    /// --config, BMC_<SECTION>__<KEY> environment variables and --bind).
    Serve {
        /// TOML file merged over the defaults (may set any subset of keys).
        #[arg(long)]
        config: Option<PathBuf>,
        /// Listen address, overriding `server.bind`.
        #[arg(long)]
        bind: Option<SocketAddr>,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Serve { config, bind } => {
            bmc_irradiance::service::init_tracing();
            let config =
                bmc_irradiance::service::Config::load(config.as_deref(), std::env::vars(), bind)?;
            bmc_irradiance::service::serve(config)
        }
    }
}

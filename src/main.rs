//! Thin command-line front end; all work lives in the library.

use std::net::SocketAddr;
use std::path::PathBuf;

use bmc_irradiance::loadtest::{LoadTestOptions, Scenario};
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
    /// Closed-loop load test of a running service on this machine.
    Loadtest {
        /// Base URL of the service (loopback only).
        #[arg(long, default_value = "http://127.0.0.1:8080")]
        url: String,
        /// Concurrent clients.
        #[arg(long, default_value_t = 8)]
        clients: usize,
        /// How long to send requests, e.g. 30s, 500ms, 2m.
        #[arg(long, default_value = "10s", value_parser = humantime::parse_duration)]
        duration: std::time::Duration,
        #[arg(long, value_enum, default_value = "health")]
        scenario: Scenario,
        /// Scene id used by the points, tiles and mixed scenarios.
        #[arg(long, default_value = "cornell-box")]
        scene: String,
        /// Shading points per points request.
        #[arg(long, default_value_t = 16)]
        points_per_request: usize,
        /// Hemisphere samples per estimate.
        #[arg(long, default_value_t = 64)]
        samples: usize,
        /// Tile side in pixels.
        #[arg(long, default_value_t = 32)]
        tile_size: u32,
        /// Sample this process's resident memory (Linux /proc) during the run.
        #[arg(long)]
        server_pid: Option<u32>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
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
        Command::Loadtest {
            url,
            clients,
            duration,
            scenario,
            scene,
            points_per_request,
            samples,
            tile_size,
            server_pid,
            json,
        } => {
            let options = LoadTestOptions {
                url,
                clients,
                duration,
                scenario,
                scene,
                points_per_request,
                samples,
                tile_size,
                server_pid,
            };
            let report = tokio::runtime::Runtime::new()?
                .block_on(bmc_irradiance::loadtest::run(&options))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                println!("{report}");
            }
            Ok(())
        }
    }
}

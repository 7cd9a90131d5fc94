//! `bmc-loadtest`: the closed-loop load generator, a binary of its own so
//! that the service binary carries no load-generating client.

use clap::Parser;

/// Closed-loop load test of a running service on this machine.
#[derive(Parser)]
#[command(name = "bmc-loadtest", version)]
struct Cli {
    #[command(flatten)]
    args: bmc_irradiance::loadtest::LoadTestArgs,
}

fn main() -> anyhow::Result<()> {
    bmc_irradiance::loadtest::run_loadtest(&Cli::parse().args)
}

//! `bmc-irradiance quadrature`: print the BMC weights of one configuration.

use std::fmt::Write as _;

use crate::bmc::cache::QuadratureCache;
use crate::bmc::report::{QuadratureReport, QuadratureSpec, quadrature_report};
use crate::bmc::{BmcError, Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use crate::sphere::{SampleSetKind, SampleSetSpec};
use clap::{Args, ValueEnum};

/// Density names accepted on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DensityArg {
    /// `1/(2π)`.
    Uniform,
    /// `cos θ/π`.
    Lambert,
    /// Normalised Phong lobe times cosine (needs `--exponent`).
    Phong,
}

/// Prior mean names accepted on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PriorMeanArg {
    /// Zero mean.
    Zero,
    /// Constant mean by generalised least squares.
    Gls,
}

/// Kernel-mean method names accepted on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum KernelMeanArg {
    /// Accurate deterministic quadrature.
    Exact,
    /// Spherical-Gaussian closed form (SE kernel only, approximate).
    #[value(alias = "spherical_gaussian", alias = "spherical-gaussian")]
    Sg,
}

/// Arguments of `bmc-irradiance quadrature`.
#[derive(Clone, Debug, Args)]
pub struct QuadratureArgs {
    /// Sample set.
    #[arg(long, value_enum, default_value = "fibonacci")]
    pub set: SampleSetKind,
    /// Number of sample directions N.
    #[arg(long, default_value_t = 64)]
    pub samples: usize,
    /// Seed of random sample sets (ignored by Fibonacci sets).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Kernel.
    #[arg(long, value_enum, default_value = "se")]
    pub kernel: KernelKind,
    /// Kernel lengthscale ℓ (chordal distance).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub lengthscale: f64,
    /// Kernel variance σ².
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub variance: f64,
    /// Observation noise (or jitter) σ_n² added to the diagonal.
    #[arg(long, default_value_t = 1e-8, allow_negative_numbers = true)]
    pub noise: f64,
    /// Density p.
    #[arg(long, value_enum, default_value = "lambert")]
    pub density: DensityArg,
    /// Phong exponent m (with `--density phong`).
    #[arg(long, allow_negative_numbers = true)]
    pub exponent: Option<f64>,
    /// Polar angle of the Phong mirror direction from the normal (rad).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub mirror_elevation: f64,
    /// Prior mean of the GP.
    #[arg(long, value_enum, default_value = "zero")]
    pub prior_mean: PriorMeanArg,
    /// How kernel means are computed.
    #[arg(long, value_enum, default_value = "exact")]
    pub kernel_mean: KernelMeanArg,
    /// Print JSON instead of a summary.
    #[arg(long)]
    pub json: bool,
}

impl QuadratureArgs {
    /// The density the arguments describe.
    pub fn density(&self) -> Result<Density, BmcError> {
        let density = match self.density {
            DensityArg::Uniform => Density::Uniform,
            DensityArg::Lambert => Density::Lambert,
            DensityArg::Phong => Density::Phong {
                exponent: self.exponent.ok_or_else(|| BmcError::InvalidParameter {
                    field: "exponent",
                    message: "required with --density phong".into(),
                })?,
                mirror_elevation: self.mirror_elevation,
            },
        };
        density.validate()?;
        Ok(density)
    }

    /// The configuration the arguments describe.
    pub fn spec(&self) -> Result<QuadratureSpec, BmcError> {
        Ok(QuadratureSpec {
            sample_set: SampleSetSpec {
                kind: self.set,
                count: self.samples,
                seed: self.seed,
            },
            kernel: Kernel::new(self.kernel, self.lengthscale, self.variance, self.noise)?,
            density: self.density()?,
            prior_mean: match self.prior_mean {
                PriorMeanArg::Zero => PriorMean::Zero,
                PriorMeanArg::Gls => PriorMean::Gls,
            },
            kernel_mean: match self.kernel_mean {
                KernelMeanArg::Exact => KernelMeanMethod::Exact,
                KernelMeanArg::Sg => KernelMeanMethod::SphericalGaussian,
            },
        })
    }
}

/// A few human-readable lines about a report.
pub fn summary(report: &QuadratureReport) -> String {
    let n = report.weights.len();
    let sum: f64 = report.weights.iter().sum();
    let (min, max) = report
        .weights
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &w| {
            (lo.min(w), hi.max(w))
        });
    let mut out = String::new();
    let _ = writeln!(out, "samples            {n}");
    let _ = writeln!(
        out,
        "weights            sum {sum:.12}, min {min:.6e}, max {max:.6e}"
    );
    let _ = writeln!(out, "density integral   {:.12}", report.density_integral);
    let _ = writeln!(out, "prior variance     {:.6e}", report.prior_variance);
    let _ = writeln!(out, "posterior variance {:.6e}", report.posterior_variance);
    let _ = writeln!(
        out,
        "jitter             {:.3e} (condition estimate {:.3e})",
        report.jitter, report.condition_estimate
    );
    let _ = write!(out, "cached             {}", report.cached);
    out
}

/// Runs the subcommand: the text to print on stdout.
pub fn run(args: &QuadratureArgs) -> anyhow::Result<String> {
    let cache = QuadratureCache::new(64 << 20);
    let report = quadrature_report(&args.spec()?, &cache)?;
    Ok(if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        summary(&report)
    })
}

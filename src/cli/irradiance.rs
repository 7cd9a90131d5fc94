//! The `irradiance` subcommand: irradiance at the points of a CSV file,
//! written as CSV to the given writer (stdout in the binary). The estimator
//! is the library's [`EstimatorSpec`], as for `POST /v1/scenes/{id}/irradiance`:
//! the same options and seed give the same numbers through either.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use super::in_thread_pool;
use super::quadrature::{KernelArg, SetArg};
use crate::bmc::cache::QuadratureCache;
use crate::estimators::calibration::Calibrations;
use crate::estimators::lengthscale::FittedKernels;
use crate::estimators::points_csv::{parse_points, write_irradiance};
use crate::estimators::{
    AmortisedRays, DEFAULT_METHOD, DEFAULT_SAMPLES, EstimatorCaches, EstimatorMethod,
    EstimatorSpec, KernelSpec, Lengthscale, RecordsPriorMode,
};
use crate::render::environment_prior::PriorChoice;
use crate::render::{Cancel, IrradianceMethod, IrradianceOptions, PathDepth, Transport};
use crate::service::Config;

/// Command-line arguments of `bmc-irradiance irradiance`.
#[derive(Clone, Debug, clap::Args)]
pub struct IrradianceArgs {
    #[command(flatten)]
    pub scene: super::scene_args::SceneArgs,
    /// CSV of query points, rows `x,y,z,nx,ny,nz` (header optional).
    #[arg(long)]
    pub points: PathBuf,
    /// Hemisphere directions per point (the service's default too).
    #[arg(long, default_value_t = DEFAULT_SAMPLES)]
    pub samples: u32,
    /// Light samples per point for the split direct part (default:
    /// `--samples`); each is one shadow ray.
    #[arg(long, conflicts_with = "reference")]
    pub light_samples: Option<u32>,
    /// Longest light path in segments from the point (1 = direct light
    /// only); default: the scene's depth less the camera's segment (Mitsuba's
    /// integrator `max_depth` − 1), else the service's (16).
    #[arg(long, value_parser = super::max_depth_parser())]
    pub max_depth: Option<PathDepth>,
    /// Direct light only (same as --max-depth 1).
    #[arg(long)]
    pub direct_only: bool,
    /// `split`: direct light by light sampling + the rest through the
    /// hemisphere; `hemisphere`: everything through the hemisphere.
    /// `auto` picks `hemisphere` for a scene lit only by a smooth environment.
    #[arg(long, alias = "method", value_enum, default_value_t = IrradianceMethod::Auto)]
    pub decomposition: IrradianceMethod,
    /// Prior mean of the hemisphere values (default: `environment` for
    /// `bmc`, `none` for `mc` and `qmc`).
    #[arg(long, value_enum)]
    pub prior: Option<PriorChoice>,
    /// Hemisphere estimator: `mc` (cosine-weighted random directions), `qmc`
    /// (spherical Fibonacci, equal weights) or `bmc` (Bayesian quadrature;
    /// the service's default too).
    #[arg(long, value_enum, default_value_t = DEFAULT_METHOD)]
    pub estimator: EstimatorMethod,
    /// `qmc` and `bmc`: the sample set (default fibonacci-cosine).
    #[arg(long, value_enum)]
    pub sample_set: Option<SetArg>,
    /// Seed of a random sample set (uniform, cosine, stratified).
    #[arg(long, default_value_t = 0)]
    pub set_seed: u64,
    /// `bmc`: the kernel family (default: selected by marginal likelihood
    /// with an `auto` lengthscale, else se).
    #[arg(long, value_enum)]
    pub kernel: Option<KernelArg>,
    /// `bmc`: the kernel lengthscale, a number (chordal units) or `auto`
    /// (default: fitted by marginal likelihood).
    #[arg(long)]
    pub lengthscale: Option<Lengthscale>,
    /// `bmc`: the kernel noise σ_n² (default: fitted with `auto`, else 1e-3).
    #[arg(long)]
    pub noise: Option<f64>,
    /// Reference mode: 65536 samples and depth 64 (overrides both).
    #[arg(long, conflicts_with_all = ["samples", "max_depth"])]
    pub reference: bool,
    /// Seed of all random streams; same seed, same numbers (the service's
    /// default too).
    #[arg(long, default_value_t = IrradianceOptions::default().seed)]
    pub seed: u64,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Report the estimator's own error model instead of error bars
    /// calibrated on the scene (docs/math.md §10.5); implied by
    /// `--reference`.
    #[arg(long)]
    pub model_errors: bool,
    /// Append standard-error columns `se_r,se_g,se_b`.
    #[arg(long)]
    pub std_error: bool,
}

impl IrradianceArgs {
    /// The library options these arguments ask for, on a scene whose
    /// default depth from points is `scene_depth` ([`PathDepth::for_points`]).
    pub fn options(&self, scene_depth: PathDepth) -> IrradianceOptions {
        let method = self.decomposition;
        let base = if self.reference {
            IrradianceOptions::reference(self.seed)
        } else {
            IrradianceOptions {
                samples: self.samples,
                light_samples: self.light_samples,
                max_depth: self.max_depth.unwrap_or(scene_depth),
                seed: self.seed,
                ..IrradianceOptions::default()
            }
        };
        IrradianceOptions {
            method,
            direct_only: self.direct_only,
            ..base
        }
    }
}

impl IrradianceArgs {
    /// The estimator these arguments name.
    pub fn estimator(&self) -> EstimatorSpec {
        let bmc_options =
            self.kernel.is_some() || self.lengthscale.is_some() || self.noise.is_some();
        EstimatorSpec {
            method: self.estimator,
            samples: if self.reference {
                IrradianceOptions::reference(self.seed).samples
            } else {
                self.samples
            },
            sample_set: self.sample_set.map(|kind| (kind.into(), self.set_seed)),
            kernel: bmc_options.then(|| KernelSpec {
                kind: self.kernel.map(Into::into),
                lengthscale: self.lengthscale.unwrap_or_default(),
                variance: None,
                noise: self.noise,
            }),
            prior: self.prior,
            // A reference reports its own sample variance: at its sample
            // count nothing is left for a calibration to add (§10.5).
            calibrate: (self.model_errors || self.reference).then_some(false),
            // A run of this command has no irradiance cache to draw on.
            records_prior: RecordsPriorMode::default(),
        }
    }
}

/// Runs the subcommand; progress goes to stderr (hidden when it is not a
/// terminal), results to `out`.
pub fn run_irradiance(args: &IrradianceArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    // Everything but the scene's default depth is checked before it loads.
    args.options(PathDepth::DIRECT).validate()?;
    let estimator = args.estimator().resolve()?;
    let text = std::fs::read_to_string(&args.points)
        .with_context(|| format!("reading points file {}", args.points.display()))?;
    let points = parse_points(&text).with_context(|| format!("in {}", args.points.display()))?;
    let scene = args.scene.load(&mut std::io::stderr())?;
    let options = args.options(PathDepth::for_points(&scene));
    let transport = Transport::new(Arc::new(scene));

    let progress = ProgressBar::new(points.len() as u64);
    progress.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} points, {elapsed} elapsed, ETA {eta}")
            .context("progress bar template")?,
    );
    // Only this run uses the fitted kernel and the weights, so their caches live as long.
    let kernels = FittedKernels::default();
    let calibrations = Calibrations::default();
    let quadratures = QuadratureCache::new(Config::default_config().cache.factorisation_bytes);
    let amortised = AmortisedRays::default();
    let estimate = || {
        let caches = EstimatorCaches {
            kernels: &kernels,
            quadratures: &quadratures,
            calibrations: &calibrations,
            records: None,
            direct: None,
            amortised: &amortised,
        };
        estimator.estimate(
            &transport,
            caches,
            &points,
            &options,
            &|| progress.inc(1),
            &Cancel::never(),
        )
    };
    let estimates = in_thread_pool(args.threads, estimate)??.estimates;
    progress.finish_and_clear();
    write_irradiance(out, &points, &estimates, args.std_error).context("writing results")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: IrradianceArgs,
    }

    fn parse(line: &str) -> Result<IrradianceArgs, clap::Error> {
        let words = std::iter::once("irradiance").chain(line.split_whitespace());
        Cli::try_parse_from(words).map(|cli| cli.args)
    }

    #[test]
    fn arguments_map_to_options() {
        let args = parse("--scene s.json --points p.csv --samples 64 --max-depth 3 --seed 9")
            .expect("valid");
        let o = args.options(PathDepth::default());
        assert_eq!((o.samples, o.max_depth.get(), o.seed), (64, 3, 9));
        assert_eq!(o.method, IrradianceMethod::Auto);
        assert!(!o.direct_only);

        let args =
            parse("--scene s.json --points p.csv --reference --direct-only --method hemisphere")
                .expect("valid");
        let expected = IrradianceOptions {
            method: IrradianceMethod::Hemisphere,
            direct_only: true,
            ..IrradianceOptions::reference(1)
        };
        assert_eq!(args.options(PathDepth::default()), expected);
        // Without --max-depth, the scene's depth.
        let args = parse("--scene s.json --points p.csv").expect("valid");
        assert_eq!(args.options(PathDepth::constant(5)).max_depth.get(), 5);
    }

    /// The rule the service's route applies, from the library: the
    /// hemisphere decomposition takes no light samples, `auto` ignores them.
    #[test]
    fn light_samples_need_a_decomposition_that_takes_them() {
        let options = |line: &str| parse(line).expect("valid").options(PathDepth::default());
        let base = "--scene s.json --points p.csv --light-samples 8";
        let refused = options(&format!("{base} --decomposition hemisphere")).validate();
        assert_eq!(refused.unwrap_err().field(), Some("light_samples"));
        assert!(options(base).validate().is_ok());
        assert!(
            options(&format!("{base} --decomposition split"))
                .validate()
                .is_ok()
        );
    }

    #[test]
    fn reference_mode_conflicts_with_explicit_budgets() {
        assert!(parse("--scene s.json --points p.csv --reference --samples 5").is_err());
        assert!(parse("--scene s.json --points p.csv --method sideways").is_err());
        assert!(parse("--scene s.json --points p.csv --lengthscale short").is_err());
    }

    #[test]
    fn an_out_of_range_depth_is_refused_with_the_library_message() {
        let err = parse("--scene s.json --points p.csv --max-depth 0").unwrap_err();
        assert_eq!(err.kind(), clap::error::ErrorKind::ValueValidation);
        assert!(err.to_string().contains("must be in 1..=1024"), "{err}");
    }

    #[test]
    fn estimator_arguments_map_to_the_library_spec() {
        // Without options, the service's defaults.
        let args = parse("--scene s.json --points p.csv").expect("valid");
        let spec = args.estimator();
        assert_eq!(
            (spec.method, spec.samples),
            (DEFAULT_METHOD, DEFAULT_SAMPLES)
        );
        assert_eq!(args.seed, IrradianceOptions::default().seed);
        let args = parse(
            "--scene s.json --points p.csv --samples 64 --estimator bmc --sample-set fibonacci \
             --kernel matern52 --lengthscale 0.5",
        )
        .expect("valid");
        let spec = args.estimator();
        assert_eq!(spec.method, EstimatorMethod::Bmc);
        assert_eq!(spec.samples, 64);
        assert_eq!(
            spec.sample_set,
            Some((crate::sphere::SampleSetKind::Fibonacci, 0))
        );
        let kernel = spec.kernel.expect("kernel options given");
        assert_eq!(kernel.kind, Some(crate::bmc::KernelKind::Matern52));
        assert_eq!(kernel.lengthscale, Lengthscale::Value(0.5));
        let args = parse("--scene s.json --points p.csv --estimator bmc --lengthscale auto")
            .expect("valid");
        assert_eq!(
            args.estimator().kernel.unwrap().lengthscale,
            Lengthscale::Auto
        );
    }
}

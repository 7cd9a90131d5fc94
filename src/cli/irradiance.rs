//! The `irradiance` subcommand: irradiance at the points of a CSV file, or
//! without one at the scene's irradiance meters (`scene::meter`), written
//! as CSV to the given writer (stdout in the binary). Its options
//! are the library's [`PointQuerySpec`], the body of `POST
//! /v1/scenes/{id}/irradiance`, and it runs the same [`PointQuery`] with
//! the service's default configuration and records held for the run: the
//! same query and seed give the same numbers through either, on a service
//! that has rendered nothing of the scene yet.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use super::in_thread_pool;
use crate::bmc::cache::QuadratureCache;
use crate::estimators::calibration::Calibrations;
use crate::estimators::lengthscale::FittedKernels;
use crate::estimators::points_csv::{parse_points, write_irradiance, write_meters};
use crate::integrator::point_query::{
    HeldRecords, PointQuery, PointQuerySpec, PointRecords, QueryState,
};
use crate::render::{Cancel, IrradianceOptions, PathDepth, PointDoc, Transport};
use crate::scene::meter::meter_value;
use crate::service::Config;
use crate::service::irradiance_caches::per_cache_bytes;

/// Command-line arguments of `bmc-irradiance irradiance`.
#[derive(Clone, Debug, clap::Args)]
pub struct IrradianceArgs {
    #[command(flatten)]
    pub scene: super::scene_args::SceneArgs,
    /// CSV of query points, rows `x,y,z,nx,ny,nz` (header optional).
    /// Without it, the scene's irradiance meters are answered, one row
    /// `meter,r,g,b,se_r,se_g,se_b` each.
    #[arg(long)]
    pub points: Option<PathBuf>,
    #[command(flatten)]
    pub query: PointQuerySpec,
    /// Direct light only (same as --max-depth 1).
    #[arg(long, conflicts_with = "max_depth")]
    pub direct_only: bool,
    /// Reference mode: 65536 samples, depth 64 (or 1 with --direct-only)
    /// and the estimator's own error model (`--calibrate false`).
    #[arg(long, conflicts_with_all = ["samples", "max_depth", "light_samples", "calibrate"])]
    pub reference: bool,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Append standard-error columns `se_r,se_g,se_b`.
    #[arg(long)]
    pub std_error: bool,
}

impl IrradianceArgs {
    /// The query these arguments name, its points still to be read.
    pub fn spec(&self) -> PointQuerySpec {
        let mut spec = self.query.clone();
        if self.reference {
            let reference = IrradianceOptions::reference(spec.seed);
            spec.estimator.samples = Some(reference.samples);
            spec.max_depth = Some(reference.max_depth);
            // A reference reports its own sample variance: at its sample
            // count nothing is left for a calibration to add (§10.5).
            spec.estimator.calibrate = Some(false);
        }
        if self.direct_only {
            spec.max_depth = Some(PathDepth::DIRECT);
        }
        spec
    }
}

/// Runs the subcommand; progress goes to stderr (hidden when it is not a
/// terminal), results to `out`.
pub fn run_irradiance(args: &IrradianceArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let config = Config::default_config();
    let mut spec = args.spec();
    // Everything but the points and the scene's depth is checked before the scene loads.
    spec.estimator.resolve()?;
    if let Some(path) = &args.points {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading points file {}", path.display()))?;
        spec.points = parse_points(&text).with_context(|| format!("in {}", path.display()))?;
    }
    let scene = args.scene.load(&mut std::io::stderr())?;
    // Without points, the scene's meters (kept apart: the scene moves into
    // the transport).
    let meters = match args.points {
        Some(_) => None,
        None => {
            anyhow::ensure!(
                !scene.meters.is_empty(),
                "the scene has no irradiance meters (a shape's <sensor type=\"irradiancemeter\">, \
                 or \"sensor\": {{\"type\": \"irradiancemeter\"}} on a JSON shape); give --points"
            );
            spec.max_depth = spec.max_depth.or(Some(PathDepth::for_meters(&scene)));
            spec.points = scene
                .meters
                .iter()
                .flat_map(|m| scene.meter_points(m))
                .map(|(p, n)| PointDoc {
                    position: p.to_array(),
                    normal: n.to_array(),
                })
                .collect();
            Some(scene.meters.clone())
        }
    };
    let max_samples = config.limits.target_max_samples();
    let query: PointQuery = spec.resolve(&scene, max_samples)?;
    let transport = Transport::new(Arc::new(scene));

    let progress = ProgressBar::new(spec.points.len() as u64);
    progress.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} points, {elapsed} elapsed, ETA {eta}")
            .context("progress bar template")?,
    );
    // What a service keeps between queries lives as long as this run.
    let kernels = FittedKernels::default();
    let calibrations = Calibrations::default();
    let quadratures = Arc::new(QuadratureCache::new(config.cache.factorisation_bytes));
    let irradiance_bytes = usize::try_from(config.cache.irradiance_bytes).unwrap_or(usize::MAX);
    let gatherings = PointRecords::new(
        per_cache_bytes(irradiance_bytes),
        config.cache.irradiance_bytes,
    );
    let store = HeldRecords::default();
    let estimate = || {
        let state = QueryState {
            kernels: &kernels,
            calibrations: &calibrations,
            quadratures: &quadratures,
            store: &store,
            gatherings: &gatherings,
            shared: Vec::new(),
            max_records: config.limits.max_tile_area,
        };
        query.estimate(&transport, state, &|| progress.inc(1), &Cancel::never())
    };
    let answer = in_thread_pool(args.threads, estimate)??;
    progress.finish_and_clear();
    if let Some(meters) = meters {
        let per_meter = answer.irradiance.len() / meters.len();
        let values: Vec<_> = answer
            .irradiance
            .chunks(per_meter)
            .zip(answer.std_dev.chunks(per_meter))
            .map(|(values, std_dev)| meter_value(values, std_dev))
            .collect();
        write_meters(out, &meters, &values).context("writing results")?;
        return Ok(());
    }
    let std_dev = args.std_error.then_some(answer.std_dev.as_slice());
    write_irradiance(out, &spec.points, &answer.irradiance, std_dev).context("writing results")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::{
        DEFAULT_METHOD, DEFAULT_SAMPLES, EstimatorMethod, EstimatorSpec, Lengthscale,
    };
    use crate::render::IrradianceMethod;
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

    fn spec(line: &str) -> PointQuerySpec {
        parse(&format!("--scene s.json --points p.csv {line}"))
            .expect("valid")
            .spec()
    }

    /// The command line and a request are one document: the same options
    /// parse to the same spec, and none to the request's `{}`.
    #[test]
    fn arguments_are_the_request_document() {
        let none: PointQuerySpec = serde_json::from_str(r#"{"points": []}"#).unwrap();
        assert_eq!(spec(""), none);
        assert_eq!(
            (none.estimator.method(), none.estimator.samples()),
            (DEFAULT_METHOD, DEFAULT_SAMPLES)
        );
        let cases = [
            (
                "--estimator bmc --samples 32 --kernel matern52 --lengthscale 0.5 \
                 --sample-set fibonacci --decomposition hemisphere --max-depth 3 --seed 9",
                r#"{"points": [], "seed": 9, "max_depth": 3, "estimator": {"method": "bmc",
                   "samples": 32, "decomposition": "hemisphere", "sample_set": {"kind": "fibonacci"},
                   "kernel": {"kind": "matern52", "lengthscale": 0.5}}}"#,
            ),
            (
                "--estimator qmc --light-samples 8 --prior environment --calibrate false \
                 --records-prior false --target 0.02 --max-samples 512",
                r#"{"points": [], "estimator": {"method": "qmc", "light_samples": 8,
                   "prior": "environment", "calibrate": false, "records_prior": false},
                   "target": {"relative_error": 0.02, "max_samples": 512}}"#,
            ),
            (
                "--sample-set uniform --set-seed 4 --lengthscale auto --noise 0.01",
                r#"{"points": [], "estimator": {"sample_set": {"kind": "uniform", "seed": 4},
                   "kernel": {"lengthscale": "auto", "noise": 0.01}}}"#,
            ),
        ];
        for (line, json) in cases {
            let wire: PointQuerySpec = serde_json::from_str(json).expect(json);
            assert_eq!(spec(line), wire, "{line}");
        }
    }

    #[test]
    fn reference_and_direct_only_set_the_budget() {
        let reference = spec("--reference --direct-only --method hemisphere --estimator mc");
        let estimator = reference.estimator;
        assert_eq!(
            estimator.samples,
            Some(IrradianceOptions::reference(1).samples)
        );
        assert_eq!(estimator.calibrate, Some(false));
        assert_eq!(estimator.decomposition, IrradianceMethod::Hemisphere);
        assert_eq!(reference.max_depth, Some(PathDepth::DIRECT));
        assert_eq!(spec("--reference").max_depth, Some(PathDepth::constant(64)));
    }

    /// The rule the service applies, from the library: the hemisphere
    /// decomposition takes no light samples, `auto` ignores them.
    #[test]
    fn light_samples_need_a_decomposition_that_takes_them() {
        let transport = crate::testing::cornell(8);
        let resolve = |line: &str| {
            spec(&format!("--light-samples 8 {line}")).resolve(transport.scene(), 4096)
        };
        match resolve("--decomposition hemisphere") {
            Err(crate::estimators::EstimatorError::Invalid { field, .. }) => {
                assert_eq!(field, "light_samples")
            }
            other => panic!("{other:?}"),
        }
        assert!(resolve("").is_ok());
        assert!(resolve("--decomposition split").is_ok());
    }

    #[test]
    fn reference_mode_conflicts_with_explicit_budgets() {
        assert!(parse("--scene s.json --points p.csv --reference --samples 5").is_err());
        assert!(parse("--scene s.json --points p.csv --method sideways").is_err());
        assert!(parse("--scene s.json --points p.csv --lengthscale short").is_err());
        assert!(parse("--scene s.json --points p.csv --direct-only --max-depth 3").is_err());
        // A target's options without the target itself.
        assert!(parse("--scene s.json --points p.csv --confidence 0.9").is_err());
    }

    #[test]
    fn an_out_of_range_depth_is_refused_with_the_library_message() {
        let err = parse("--scene s.json --points p.csv --max-depth 0").unwrap_err();
        assert_eq!(err.kind(), clap::error::ErrorKind::ValueValidation);
        assert!(err.to_string().contains("must be in 1..=1024"), "{err}");
    }

    #[test]
    fn estimator_arguments_map_to_the_library_spec() {
        let args = spec(
            "--samples 64 --estimator bmc --sample-set fibonacci --kernel matern52 --lengthscale 0.5",
        );
        let EstimatorSpec {
            method,
            samples,
            sample_set,
            kernel,
            ..
        } = args.estimator;
        assert_eq!((method, samples), (Some(EstimatorMethod::Bmc), Some(64)));
        assert_eq!(
            sample_set.map(|s| (s.kind(), s.seed())),
            Some((crate::sphere::SampleSetKind::Fibonacci, 0))
        );
        let kernel = kernel.expect("kernel options given");
        assert_eq!(kernel.kind, Some(crate::bmc::KernelKind::Matern52));
        assert_eq!(kernel.lengthscale(), Lengthscale::Value(0.5));
        assert_eq!(
            spec("--lengthscale auto")
                .estimator
                .kernel
                .unwrap()
                .lengthscale(),
            Lengthscale::Auto
        );
        // No kernel option, no kernel: a `qmc` spec stays valid.
        assert_eq!(spec("--estimator qmc").estimator.kernel, None);
    }
}

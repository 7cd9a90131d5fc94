//! The error-target study on a scene (docs/math.md §10.6): each estimator
//! run to an error target in batches, then at fixed `N` up to where as many
//! of its estimates are within the target, against the same references as
//! the real-scene study ([`TargetStudyRow`], [`run_target`],
//! [`target_markdown_table`]).

use serde::Serialize;

use super::{SceneStudyError, SceneStudyOptions, Setup};
use crate::estimators::error_target::ErrorTarget;
use crate::estimators::{EstimatorMethod, EstimatorSpec, RecordsPriorMode};
use crate::render::{Cancel, IrradianceEstimate, IrradianceOptions, Transport};

/// One line of the error-target study: an estimator run to a target, or at
/// a fixed `N`, and how many of its estimates are within the target.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetStudyRow {
    pub scene: String,
    pub estimator: String,
    /// `"target"` or `"fixed"`.
    pub mode: String,
    /// The batch size (target) or the sample count (fixed).
    pub samples: u32,
    /// Share of (point, seed) estimates whose luminance is within the
    /// target's relative error of the reference's.
    pub within: f64,
    /// Target runs: share of estimates that reported the target met.
    pub reported_met: Option<f64>,
    /// Target runs: share of the estimates reported met that are within
    /// the target (what a caller relying on `target_met` gets).
    pub met_within: Option<f64>,
    /// Mean hemisphere samples per point.
    pub mean_samples: f64,
    /// Rays per point, mean over points and seeds.
    pub rays_per_point: f64,
}

/// The error-target study (docs/math.md §10.6): each estimator run to
/// `target` in batches of `batch` samples, then at fixed `N = batch · 2^k`
/// up to the target's `max_samples`, stopping at the first `N` whose share
/// within the target reaches the share the target run reached.
pub fn run_target(
    transport: &Transport,
    scene: &str,
    options: &SceneStudyOptions,
    batch: u32,
    target: &ErrorTarget,
) -> Result<Vec<TargetStudyRow>, SceneStudyError> {
    let setup = Setup::new(transport, options)?;
    let (points, reference, base, caches) = (
        &setup.points,
        &setup.reference,
        setup.base,
        setup.caches(None, None),
    );
    let never = Cancel::never();
    let within = |estimate: &IrradianceEstimate, truth: &IrradianceEstimate| {
        let (e, t) = (
            estimate.irradiance.luminance(),
            truth.irradiance.luminance(),
        );
        (e - t).abs() <= target.relative_error * t.abs()
    };
    let mut rows = Vec::new();
    for (name, method) in [
        ("mc", EstimatorMethod::Mc),
        ("qmc", EstimatorMethod::Qmc),
        ("bmc", EstimatorMethod::Bmc),
    ] {
        let spec = |samples| EstimatorSpec {
            method: Some(method),
            samples: Some(samples),
            records_prior: RecordsPriorMode::Set(false),
            ..EstimatorSpec::default()
        };
        let request = |samples, s: u64| IrradianceOptions {
            samples,
            seed: options.seed ^ (0x9E37_79B9 + s),
            ..base
        };
        let (mut hits, mut met, mut met_hits, mut samples, mut rays, mut count) =
            (0usize, 0usize, 0usize, 0u64, 0u64, 0usize);
        let estimator = spec(batch).resolve()?;
        for s in 0..options.seeds {
            let (_, targeted) = estimator.estimate_to_target(
                transport,
                caches,
                points,
                &request(batch, s),
                target,
                &never,
            )?;
            for (t, truth) in targeted.iter().zip(reference) {
                hits += usize::from(within(&t.estimate, truth));
                met += usize::from(t.met);
                met_hits += usize::from(t.met && within(&t.estimate, truth));
                samples += u64::from(t.samples);
                rays += t.estimate.rays;
                count += 1;
            }
        }
        let target_share = hits as f64 / count as f64;
        rows.push(TargetStudyRow {
            scene: scene.to_owned(),
            estimator: name.to_owned(),
            mode: "target".into(),
            samples: batch,
            within: target_share,
            reported_met: Some(met as f64 / count as f64),
            met_within: Some(met_hits as f64 / met.max(1) as f64),
            mean_samples: samples as f64 / count as f64,
            rays_per_point: rays as f64 / count as f64,
        });
        // Fixed sample sets hold at most `sphere::MAX_SAMPLES` directions,
        // and BMC's weights beyond 2,048 cost minutes of factorisation; MC
        // draws fresh directions and has no such bound.
        let largest = match method {
            EstimatorMethod::Mc => target.max_samples,
            EstimatorMethod::Qmc => target.max_samples.min(crate::sphere::MAX_SAMPLES as u32),
            EstimatorMethod::Bmc => target.max_samples.min(2048),
        };
        let mut n = batch;
        while n <= largest {
            let estimator = spec(n).resolve()?;
            let (mut hits, mut rays, mut count) = (0usize, 0u64, 0usize);
            for s in 0..options.seeds {
                let estimates = estimator.estimate(
                    transport,
                    caches,
                    points,
                    &request(n, s),
                    &|| {},
                    &never,
                )?;
                for (e, truth) in estimates.estimates.iter().zip(reference) {
                    hits += usize::from(within(e, truth));
                    rays += e.rays;
                    count += 1;
                }
            }
            let share = hits as f64 / count as f64;
            rows.push(TargetStudyRow {
                scene: scene.to_owned(),
                estimator: name.to_owned(),
                mode: "fixed".into(),
                samples: n,
                within: share,
                reported_met: None,
                met_within: None,
                mean_samples: f64::from(n),
                rays_per_point: rays as f64 / count as f64,
            });
            if share >= target_share {
                break;
            }
            n = n.saturating_mul(2);
        }
    }
    Ok(rows)
}

/// The target study's rows as a Markdown table.
pub fn target_markdown_table(rows: &[TargetStudyRow]) -> String {
    let mut out = String::from(
        "| scene | estimator | mode | N (batch) | within target | reported met | met and within | \
         samples/point | rays/point |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let share = |s: Option<f64>| s.map_or(String::from("–"), |m| format!("{m:.3}"));
    for row in rows {
        out.push_str(&format!(
            "| {} | {} | {} | {} | {:.3} | {} | {} | {:.0} | {:.0} |\n",
            row.scene,
            row.estimator,
            row.mode,
            row.samples,
            row.within,
            share(row.reported_met),
            share(row.met_within),
            row.mean_samples,
            row.rays_per_point,
        ));
    }
    out
}

//! [`PointQuerySpec`]: a point query as a caller names it, at once the body
//! of `POST /v1/scenes/{id}/irradiance`, the `irradiance` command's
//! arguments (clap flatten; its points come from a CSV file) and the
//! OpenAPI schema. [`PointQuerySpec::resolve`] checks it once against its
//! scene and fills every default; nothing downstream checks again.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::PointQuery;
use crate::estimators::EstimatorError;
use crate::estimators::EstimatorSpec;
use crate::estimators::error_target::TargetSpec;
use crate::render::{DEFAULT_SEED, IrradianceOptions, PathDepth, PointDoc, RenderError};
use crate::scene::Scene;

/// Irradiance `E(x, n)` at points (module docs).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct PointQuerySpec {
    /// 1..=`limits.max_points` points (the command line reads them from
    /// `--points`).
    #[arg(skip)]
    pub points: Vec<PointDoc>,
    /// Default: `bmc` with 64 samples and every other option its default.
    #[serde(default)]
    #[command(flatten)]
    pub estimator: EstimatorSpec,
    /// Longest path in segments from the point (1 = direct light only);
    /// default the scene's depth less the camera's segment (Mitsuba's
    /// integrator `max_depth` − 1), else 16.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<u32>)]
    #[arg(long)]
    pub max_depth: Option<PathDepth>,
    /// Seed of every random stream; same query and seed, same numbers. Default 1.
    #[serde(default = "default_seed")]
    #[arg(long, default_value_t = DEFAULT_SEED)]
    pub seed: u64,
    /// Estimate each point in batches of `estimator.samples` (`bmc`: twice
    /// that, half of them fresh directions for an unbiased correction, and
    /// no records prior) until its calibrated error bar meets this target or
    /// `max_samples` is spent (docs/math.md §10.6). For targets of a few per
    /// cent, batches of a few hundred samples keep the reported
    /// `target_met` honest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[command(flatten)]
    pub target: Option<TargetSpec>,
}

fn default_seed() -> u64 {
    DEFAULT_SEED
}

impl PointQuerySpec {
    /// The query on `scene`, an error target capped at `max_samples` per
    /// point unless it names a cap; errors name the field below the query.
    pub fn resolve(&self, scene: &Scene, max_samples: u32) -> Result<PointQuery, EstimatorError> {
        let estimator = self.estimator.resolve()?;
        let target = self
            .target
            .map(|t| t.resolve(&estimator, max_samples))
            .transpose()?;
        let points = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                p.point()
                    .map_err(|e| invalid_at(&format!("points[{i}]"), e))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let options = IrradianceOptions {
            samples: self.estimator.samples(),
            light_samples: self.estimator.light_samples,
            max_depth: self
                .max_depth
                .unwrap_or_else(|| PathDepth::for_points(scene)),
            direct_only: false,
            method: self.estimator.decomposition,
            seed: self.seed,
        };
        options.validate().map_err(|err| match err {
            RenderError::InvalidOption { field, .. } => EstimatorError::Invalid {
                field: field.into(),
                message: err.to_string(),
            },
            other => other.into(),
        })?;
        Ok(PointQuery {
            points,
            estimator,
            options,
            target,
        })
    }
}

/// A point's error, its field under `at`.
fn invalid_at(at: &str, err: RenderError) -> EstimatorError {
    match err {
        RenderError::InvalidPoint { field, .. } => EstimatorError::InvalidQuery {
            field: format!("{at}.{field}"),
            message: err.to_string(),
        },
        other => other.into(),
    }
}

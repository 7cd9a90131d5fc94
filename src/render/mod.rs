//! Light transport: reflection models, light sampling, incident radiance
//! along a ray and irradiance at points. Knows scenes, never HTTP.
//!
//! Conventions shared by every file here: radiance in W/(m²·sr) and
//! irradiance in W/m², per linear RGB channel ([`Rgb`]); local frames have
//! z = surface normal ([`crate::sphere::Frame`]); surfaces reflect and emit on
//! their front side only, as in Mitsuba 3 (see `bsdf`).
//!
//! Entry points: [`Transport`] (built once per scene) with
//! `incident_radiance`, `hemisphere_samples`, `direct_irradiance`,
//! `irradiance_with_estimator` (any MC/QMC/BMC estimator),
//! `irradiance` and `irradiance_at_points`; `render_tile` and
//! `render_image` for the camera's image (`tile`, `film`).

pub mod bsdf;
pub mod calibration;
pub mod cancel;
pub mod distribution;
pub mod environment_prior;
pub mod environment_sampling;
pub mod error;
pub mod error_target;
pub mod estimators;
pub mod film;
pub mod hemisphere_estimate;
pub mod irradiance;
pub mod lengthscale;
pub mod lights;
pub mod mean;
pub mod path;
pub mod points_csv;
pub mod polygon;
pub mod query;
pub mod rgb;
pub mod sample_points;
pub mod seed;
pub mod strata;
pub mod tile;
pub mod trace_stats;
pub mod transport;
pub mod warp;

pub use bsdf::{Bsdf, BsdfSample};
pub use cancel::Cancel;
pub use error::RenderError;
pub use film::{ImageSettings, RenderedImage};
pub use irradiance::{Decomposition, IrradianceEstimate, IrradianceMethod, IrradianceOptions};
pub use mean::{Evaluation, MeanEstimate};
pub use path::{AveragedPaths, PathDepth, PathLengths, PathLimits, RadianceSample, TraceStats};
pub use query::QueryPoint;
pub use rgb::Rgb;
pub use tile::{CameraRayShader, PixelSample, RenderedTile, TileRequest};
pub use transport::Transport;

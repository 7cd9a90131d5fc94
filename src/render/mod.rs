//! Light transport: light sampling, incident radiance along a ray and
//! irradiance at points, through the scene's reflection models
//! ([`Bsdf`], built from `scene::material`'s plugins) and lights
//! (`scene::emitter`'s). Knows scenes, never HTTP.
//!
//! Conventions shared by every file here: radiance in W/(m²·sr) and
//! irradiance in W/m², per linear RGB channel ([`Rgb`]); local frames have
//! z = surface normal ([`crate::sphere::Frame`]); surfaces reflect and emit on
//! their front side only, as in Mitsuba 3 (see `scene::material`).
//!
//! Entry points: [`Transport`] (built once per scene) with its path
//! kernel ([`PathTracer`], `transport.paths()`: incident radiance along
//! rays), `hemisphere_samples`, `direct_irradiance`, `irradiance` and
//! `irradiance_at_points` (any MC/QMC/BMC rule runs through
//! `estimators::HemisphereRule::estimate`); the pixel loop every
//! integrator's camera tiles go through (`tile`) and the whole image
//! assembled from tiles (`film`). Integrators live in
//! the `integrator` module.

mod cancel;
mod distribution;
pub mod environment_prior;
pub(crate) mod environment_sampling;
mod error;
mod film;
mod guide_buffers;
mod irradiance;
pub(crate) mod lights;
mod mean;
mod path;
mod path_tracer;
mod pixel_variance;
#[doc(hidden)]
pub mod polygon;
mod query;
mod sample_plan;
pub mod seed;
mod shadow_probe;
pub(crate) mod strata;
pub(crate) mod tile;
mod trace_stats;
mod transport;

pub use crate::color::Rgb;
pub use crate::scene::material::{Bsdf, BsdfFlags, LobeSample};
pub use cancel::Cancel;
pub use error::RenderError;
pub use film::{ImageSettings, RenderedImage};
pub use irradiance::{
    DEFAULT_SEED, Decomposition, IndirectPart, IrradianceEstimate, IrradianceMethod,
    IrradianceOptions, SMOOTH_ENVIRONMENT_RELATIVE_VARIANCE, nothing_seen,
};
pub use mean::{Evaluation, MIN_STRATA_BLOCKS, MeanEstimate, StrataVariance};
pub use path::{
    AveragedPaths, FirstSegment, PathDepth, PathLengths, PathLimits, RadianceSample,
    SharedFirstVertex, TraceStats, power_heuristic,
};
pub use path_tracer::PathTracer;
pub use query::{PointDoc, QueryPoint};
pub use sample_plan::SamplePlan;
pub use shadow_probe::SHADOW_PROBES;
pub use tile::{
    CameraRayShader, MAX_SAMPLES_PER_PIXEL, MAX_TILE_PIXELS, PixelSample, RenderedTile,
    TileRequest, pass_seed, pixel_rng, render_tile_with,
};
pub use transport::Transport;

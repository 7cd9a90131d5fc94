//! # bmc-irradiance
//!
//! Bayesian Monte Carlo (BMC) estimation of irradiance and radiance on the
//! hemisphere, with precomputed quadrature weights `w = Q⁻¹ z` and cached
//! factorisations (see `docs/math.md`).
//!
//! ## Public surface
//! The types most programs need are re-exported here: load a [`Scene`], wrap
//! it in a [`Transport`], then estimate irradiance at [`QueryPoint`]s with a
//! [`PointEstimator`] (resolved from an [`EstimatorSpec`], with
//! [`IrradianceOptions`]), or render [`TileRequest`]s of the camera image by
//! path tracing ([`Transport::render_tile`]) or through the irradiance cache
//! ([`CachedIntegrator`], configured by a [`CachedSpec`] or a [`Preset`]);
//! images come back as [`Image`]s. Path lengths are [`PathDepth`]s.
//!
//! The modules, from the front ends down (how they depend on each other is
//! in `docs/ARCHITECTURE.md`):
//! - [`service`]: the HTTP service — [`service::serve`] with a
//!   [`service::Config`], or [`service::Application`] to embed it.
//! - [`cli`]: the binary's subcommands (`irradiance`, `quadrature`, `study`,
//!   `study-scene`, `render`, `compare`, `fetch`) as library functions.
//! - [`loadtest`]: the closed-loop load generator (the `bmc-loadtest` binary).
//! - [`integrator`]: how camera rays are shaded ([`Integrator`], [`Preset`]);
//!   [`integrator::cached`] is the irradiance-cache integrator.
//! - [`cache`]: the irradiance cache's record store — BMC records with
//!   variance and gradients, a concurrent spatial index, interpolation; no
//!   scene, no rays.
//! - [`render`]: light transport — incident radiance and irradiance at
//!   points, the camera's pixel loop ([`render::render_tile_with`] with a
//!   [`render::CameraRayShader`]), and the point estimators
//!   ([`estimators`]) with their prior means
//!   ([`render::environment_prior`]), fitted lengthscales
//!   ([`estimators::lengthscale`]), calibrated error bars
//!   ([`estimators::calibration`]) and error targets ([`estimators::error_target`]);
//!   [`render::seed`] holds the random streams every result is reproducible by.
//! - [`scene`]: JSON and Mitsuba 3 XML scenes, the camera, rays and the BVH;
//!   the BSDF, light and texture plugins, each in a file of its own.
//! - [`cancel`]: the flag a long library call (a tile, a query, a scene
//!   load) is stopped by, below every layer.
//! - [`bmc`] and [`sphere`]: the math — kernels, densities, kernel means,
//!   factorisations, BMC weights and variances, hyperparameter fits;
//!   hemisphere frames and sample sets; [`optics`]: Fresnel terms,
//!   microfacet distributions and direction warps the BSDFs are made of.
//! - [`image`]: RGB images with per-pixel variance; EXR/PNG/JSON encodings,
//!   relative RMSE.
//! - [`study`]: the convergence study on synthetic environments and the
//!   real-scene study against converged references.
//!
//! Inside each module, its files are private and its types re-exported at
//! its root; `stats` (running means and variances) is private to the crate.
//! A few items are public only for the tests, benches and examples and are
//! hidden from these docs (`testing`, `scene::generate`, `render::polygon`,
//! `optics::warp`, the service's `AppState` and `CpuPool`); nothing outside
//! this repository should rely on them.

pub mod bmc;
pub mod cache;
pub mod cancel;
pub mod cli;
pub mod color;
pub mod estimators;
pub mod image;
pub mod integrator;
pub(crate) mod isolated;
pub mod loadtest;
pub mod optics;
pub mod render;
pub mod scene;
pub mod service;
pub mod sphere;
pub(crate) mod stats;
pub mod study;
#[doc(hidden)]
pub mod testing;

pub use estimators::{EstimatorError, EstimatorMethod, EstimatorSpec, PointEstimator};
pub use image::{Image, ImageEncoding};
pub use integrator::cached::{CachedIntegrator, CachedSpec};
pub use integrator::{Integrator, Preset};
pub use render::{
    Cancel, IrradianceEstimate, IrradianceOptions, PathDepth, QueryPoint, RenderError,
    RenderedTile, Rgb, TileRequest, Transport,
};
pub use scene::{MitsubaOptions, Scene, SceneError};

//! # bmc-irradiance
//!
//! Bayesian Monte Carlo (BMC) estimation of irradiance and radiance on the
//! hemisphere, with precomputed quadrature weights `w = Q⁻¹ z` and cached
//! factorisations (see `docs/math.md`).
//!
//! ## Layout
//! The math (`sphere`, `bmc`, `study`) knows nothing of scenes or HTTP; the
//! service is a thin layer over the library.
//! - `stats`: the running mean and variance of a sample (Welford), for every layer.
//! - `sphere`: local shading frames and hemisphere sample sets (local frame, z = normal).
//! - `bmc`: kernels, densities, exact kernel means, Cholesky factorisation, BMC weights and variance;
//!   `bmc::cache` (byte-bounded single-flight cache of factorisations and weights),
//!   `bmc::estimator` (MC, QMC, BMC behind one interface), `bmc::hyperparameters`
//!   (marginal-likelihood fit of ℓ, σ², σ_n²), `bmc::report` (a quadrature's
//!   spec, stable id and the report the CLI and the service return).
//! - `scene`: JSON and Mitsuba 3 XML (`scene::mitsuba`) scene loading, shapes,
//!   materials, emitters, environment maps, camera, BVH ray tracing
//!   (`intersect`, `occluded`).
//! - `render`: light transport — BSDFs, light sampling, incident radiance
//!   `L_i(x, ω)` and irradiance `E(x, n)` at points; tiles of the camera image;
//!   `render::hemisphere_estimate` (irradiance at points with any MC/QMC/BMC
//!   estimator), `render::estimators` (the point estimator a request or the CLI
//!   names, resolved once), `render::lengthscale` (the scene-fitted `"auto"`
//!   lengthscale), `render::environment_prior` (the unoccluded environment as
//!   a prior mean), `render::calibration` (error bars calibrated on the
//!   scene), `render::error_target` (estimates to a relative error).
//! - `study`: synthetic environments with known irradiance and the estimator
//!   convergence study (MC vs QMC vs BMC); the real-scene study against
//!   converged references (`study::scenes`).
//! - `cache`: the Bayesian irradiance cache's record store — BMC records with
//!   variance and gradients, concurrent spatial index, interpolation; no scene,
//!   no rays.
//! - `integrator::cached`: the irradiance-cache integrator — records computed at
//!   points and reproducible placement, outgoing radiance through the cache
//!   (BMC Phong glossy), camera tiles and radiance queries.
//! - `image`: RGB images with per-pixel variance; EXR/PNG/JSON encodings, relative RMSE.
//! - `cli`: the binary's subcommands (`irradiance`, `quadrature`, `study`, `study-scene`,
//!   `render`, `compare`) as library functions.
//! - `service`: the HTTP service (config, routes, errors, CPU pool, metrics).
//! - `loadtest`: closed-loop load generator for the service (the `bmc-loadtest` binary).
//!
//! How the layers depend on each other, one request traced end to end and the
//! conventions are in `docs/ARCHITECTURE.md`.

pub mod bmc;
pub mod cache;
pub mod cli;
pub mod image;
pub mod integrator;
pub mod loadtest;
pub mod render;
pub mod scene;
pub mod service;
pub mod sphere;
pub mod stats;
pub mod study;
#[doc(hidden)]
pub mod testing;

//! # bmc-irradiance
//!
//! Bayesian Monte Carlo (BMC) estimation of irradiance and radiance on the
//! hemisphere, with precomputed quadrature weights `w = Q⁻¹ z` and cached
//! factorisations (see `shared/docs/bmc-math.md`).
//!
//! ## Layout
//! Modules are listed here as they land; the math never knows about HTTP.
//! - `sphere`: local shading frames and hemisphere sample sets (local frame, z = normal).
//! - `bmc`: kernels, densities, exact kernel means, Cholesky factorisation, BMC weights and variance.
//! - `scene`: JSON scene loading, shapes, materials, emitters, environment
//!   maps, camera, BVH ray tracing (`intersect`, `occluded`).
//! - `render`: light transport — BSDFs, light sampling, incident radiance
//!   `L_i(x, ω)` and irradiance `E(x, n)` at points.
//! - `service`: the HTTP service (config, routes, errors, CPU pool, metrics).
//! - `loadtest`: closed-loop load generator for the service (`loadtest` subcommand).

pub mod bmc;
pub mod loadtest;
pub mod render;
pub mod scene;
pub mod service;
pub mod sphere;

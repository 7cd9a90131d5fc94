//! # bmc-irradiance
//!
//! Bayesian Monte Carlo (BMC) estimation of irradiance and radiance on the
//! hemisphere, with precomputed quadrature weights `w = Q⁻¹ z` and cached
//! factorisations (see `shared/docs/bmc-math.md`).
//!
//! ## Layout
//! Modules are listed here as they land; the math never knows about HTTP.
//! - `loadtest`: closed-loop load generator for the service (`loadtest` subcommand).
//! - `service`: the HTTP service (config, routes, errors, CPU pool, metrics).

pub mod loadtest;
pub mod service;
pub mod sphere;

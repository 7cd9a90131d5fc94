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
//! - `study`: synthetic environments with known irradiance and the estimator
//!   convergence study (MC vs QMC vs BMC).

pub mod bmc;
pub mod sphere;
pub mod study;

//! # bmc-irradiance
//!
//! Bayesian Monte Carlo (BMC) estimation of irradiance and radiance on the
//! hemisphere, with precomputed quadrature weights `w = Q⁻¹ z` and cached
//! factorisations (see `shared/docs/bmc-math.md`).
//!
//! ## Layout
//! Modules are listed here as they land; the math never knows about HTTP.
//! - `render`: light transport — BSDFs, light sampling, incident radiance
//!   `L_i(x, ω)` and irradiance `E(x, n)` at points.
//! - `scene`: JSON scene loading, shapes, materials, emitters, environment
//!   maps, camera, BVH ray tracing (`intersect`, `occluded`).

pub mod render;
pub mod scene;
pub mod sphere;

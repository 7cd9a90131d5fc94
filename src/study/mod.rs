//! Numerical studies of the estimators on environments with known integrals.

pub mod convergence;
pub mod synthetic;

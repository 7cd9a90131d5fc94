//! Numerical studies of the estimators: on synthetic environments with known
//! integrals (`convergence`), and on real scenes against converged references
//! (`scenes`).

pub mod convergence;
pub mod scenes;
pub mod synthetic;

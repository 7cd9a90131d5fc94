//! Bayesian Monte Carlo quadrature on the hemisphere (docs/math.md §2–4, §8):
//! kernels, densities, exact kernel means, the factorisation of `Q` and the
//! resulting weights and posterior variance.

pub mod cache;
pub mod density;
pub mod error;
pub mod estimator;
pub mod factorisation;
pub mod gls;
pub mod hyperparameters;
pub mod kernel;
pub mod kernel_mean;
pub mod quadrature;
pub mod report;

mod bessel;
mod integrate;

pub use density::{Density, DensityKey};
pub use error::BmcError;
pub use factorisation::Factorisation;
pub use kernel::{Kernel, KernelKey, KernelKind, MAX_LENGTHSCALE, MIN_LENGTHSCALE};
pub use kernel_mean::{kernel_means, prior_variance};
pub use quadrature::{KernelMeanMethod, PriorMean, Quadrature};

//! Bayesian Monte Carlo quadrature on the hemisphere (docs/math.md §2–4, §8):
//! kernels, densities, exact kernel means, the factorisation of `Q` and the
//! resulting weights and posterior variance.

pub mod cache;
pub mod control_variate;
pub mod dense;
mod density;
mod error;
pub mod estimator;
mod factorisation;
pub(crate) mod gls;
pub mod hyperparameters;
mod kernel;
mod kernel_mean;
mod quadrature;
pub mod report;

mod bessel;
mod integrate;

pub use density::{Density, DensityKey, MAX_PHONG_EXPONENT};
pub use error::BmcError;
pub use factorisation::Factorisation;
pub use kernel::{Kernel, KernelKey, KernelKind, MAX_LENGTHSCALE, MIN_LENGTHSCALE};
pub use kernel_mean::KernelMeanMethod;
pub use kernel_mean::{kernel_means, prior_variance};
pub use quadrature::{PriorMean, Quadrature};

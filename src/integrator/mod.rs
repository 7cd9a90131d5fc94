//! Integrators: how a camera ray or a query becomes a radiance estimate. Path
//! tracing lives with the light-transport kernels in [`crate::render`]; the
//! irradiance-cache integrator, which reads and extends the record store of
//! [`crate::cache`], is [`cached`].

pub mod cached;
mod preset;

pub use preset::{Preset, TileSettings};

/// How the radiance along a camera ray (or towards a query's viewer) is
/// computed: the integrator a request or the command line names.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Deserialize,
    serde::Serialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Unidirectional path tracing with next-event estimation, MIS and
    /// Russian roulette (`Transport::render_tile`), emitters seen directly
    /// included: the unbiased reference.
    Path,
    /// Direct light by light sampling, diffuse indirect light interpolated
    /// from irradiance-cache records computed by BMC, glossy reflection by
    /// BMC with the Phong density ([`cached`]). `"bmc"` is accepted as an
    /// alias (the name this had before `"bmc"` came to mean one quadrature
    /// per point, as it does for point queries).
    #[default]
    #[serde(alias = "bmc")]
    Cache,
}

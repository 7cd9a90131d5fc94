//! The integrators by name, as requests (`"method"`) and the command line
//! (`--method`) spell them.

use utoipa::ToSchema;

/// The integrators by name.
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
    ToSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Unidirectional path tracing with next-event estimation, MIS and
    /// Russian roulette (`path`), emitters seen directly
    /// included: the unbiased reference.
    Path,
    /// Direct light by light sampling, diffuse indirect light interpolated
    /// from irradiance-cache records computed by BMC, glossy reflection by
    /// BMC with the Phong density (`cache`). `"bmc"` names one thing
    /// across the API, a point estimator (a quadrature per point), so it
    /// is not a name of this integrator, which it once was.
    #[default]
    Cache,
}

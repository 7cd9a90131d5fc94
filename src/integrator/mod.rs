//! Integrators: how a camera ray or a query becomes a radiance estimate.
//!
//! - `method`: the integrators by name;
//! - `spec`: the integrator a request or the command line names, as data
//!   ([`IntegratorSpec`]: the method and its knobs);
//! - `resolved`: that spec checked ([`Integrator`]) and bound to a scene and
//!   its cache ([`BoundIntegrator`]), the one place that matches on the method;
//! - [`path`]: the path tracer, the unbiased reference;
//! - [`cached`]: the irradiance-cache integrator, which reads and extends the
//!   record store of [`crate::cache`];
//! - `radiance`: outgoing radiance at surface points by either integrator;
//! - `preset`: named quality levels of camera tiles.
//!
//! Adding an integrator: its module here, a variant of [`IntegratorSpec`]
//! and of [`Integrator`] / [`BoundIntegrator`] (the compiler then lists every
//! match to extend, all in `spec.rs` and `resolved.rs`).

pub mod cached;
mod method;
pub mod path;
pub mod point_query;
mod preset;
pub mod progressive;
mod radiance;
mod resolved;
mod spec;

pub use method::Method;
pub use path::PathIntegrator;
pub use preset::{Preset, TileSettings};
pub use radiance::{
    PROBE_RELATIVE, RadianceEstimate, RadianceOptions, RadianceQuery, radiance_at_points,
    surface_at,
};
pub use resolved::{BoundIntegrator, Integrator};
pub use spec::{IntegratorSpec, PathSpec};

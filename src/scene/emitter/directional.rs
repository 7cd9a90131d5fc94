//! `directional`: light from infinitely far away along one direction (the
//! sun, seen as a point).
//!
//! Parameters (Mitsuba 3's): `direction` (the direction the light travels,
//! default +z), `irradiance` (W/m² on a surface facing the light, default 1).

use super::{Emitter, power};
use crate::scene::error::SceneError;
use crate::scene::params::Params;

pub(super) fn parse(params: &mut Params) -> Result<Emitter, SceneError> {
    Ok(Emitter::Directional {
        direction: params.direction("direction")?.unwrap_or([0.0, 0.0, 1.0]),
        irradiance: power(params, "irradiance", 1.0)?,
    })
}

//! `point`: an isotropic point light.
//!
//! Parameters (Mitsuba 3's): `position` (`[x, y, z]`, default the origin),
//! `intensity` (radiant intensity, W/sr, default 1).

use super::{Emitter, power};
use crate::scene::error::SceneError;
use crate::scene::params::Params;

pub(super) fn parse(params: &mut Params) -> Result<Emitter, SceneError> {
    Ok(Emitter::Point {
        position: params.vector("position")?.unwrap_or([0.0; 3]),
        intensity: power(params, "intensity", 1.0)?,
    })
}

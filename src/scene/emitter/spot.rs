//! `spot`: a point light shining into a cone, with Mitsuba 3's linear
//! falloff: full intensity within `beam_width` of the axis, falling
//! linearly in angle to zero at `cutoff_angle`.
//!
//! Parameters: `position` (default the origin), `direction` (the axis,
//! default +z; Mitsuba's `to_world` translates to both), `intensity` (W/sr
//! on the axis, default 1), `cutoff_angle` (degrees, in (0, 180), default
//! 20), `beam_width` (degrees, in (0, cutoff_angle], default 3/4 of it).

use super::{Emitter, power};
use crate::scene::error::SceneError;
use crate::scene::params::Params;

pub(super) fn parse(params: &mut Params) -> Result<Emitter, SceneError> {
    let cutoff = params.number("cutoff_angle")?.unwrap_or(20.0);
    if !(cutoff > 0.0 && cutoff < 180.0) {
        return Err(SceneError::invalid(
            params.field("cutoff_angle"),
            format!("{cutoff} is not an angle in (0, 180) degrees"),
        ));
    }
    let beam = params.number("beam_width")?.unwrap_or(0.75 * cutoff);
    if !(beam > 0.0 && beam <= cutoff) {
        return Err(SceneError::invalid(
            params.field("beam_width"),
            format!("{beam} is not an angle in (0, cutoff_angle = {cutoff}] degrees"),
        ));
    }
    Ok(Emitter::Spot {
        position: params.vector("position")?.unwrap_or([0.0; 3]),
        direction: params.direction("direction")?.unwrap_or([0.0, 0.0, 1.0]),
        intensity: power(params, "intensity", 1.0)?,
        cutoff_angle: cutoff.to_radians(),
        beam_width: beam.to_radians(),
    })
}

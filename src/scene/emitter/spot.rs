//! `spot`: a point light shining into a cone, with Mitsuba 3's linear
//! falloff: full intensity within `beam_width` of the axis, falling
//! linearly in angle to zero at `cutoff_angle` ([`spot_falloff`]).
//!
//! Parameters: `position` (default the origin), `direction` (the axis,
//! default +z; Mitsuba's `to_world` translates to both), `intensity` (W/sr
//! on the axis, default 1), `cutoff_angle` (degrees, in (0, 180), default
//! 20), `beam_width` (degrees, in (0, cutoff_angle], default 3/4 of it).

use glam::DVec3;

use super::{Light, LightSample, Reach, power, toward_point};
use crate::color::Rgb;
use crate::scene::Scene;
use crate::scene::error::SceneError;
use crate::scene::params::Params;

/// A spot light; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct SpotLight {
    /// World position.
    pub position: [f64; 3],
    /// The unit axis, world frame.
    pub direction: [f64; 3],
    /// Radiant intensity on the axis, W/sr per channel.
    pub intensity: [f64; 3],
    /// Radians, `0 < beam_width ≤ cutoff_angle < π`.
    pub cutoff_angle: f64,
    pub beam_width: f64,
}

impl SpotLight {
    /// The parameters of a light document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
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
        Ok(Self {
            position: params.vector("position")?.unwrap_or([0.0; 3]),
            direction: params.direction("direction")?.unwrap_or([0.0, 0.0, 1.0]),
            intensity: power(params, "intensity", 1.0)?,
            cutoff_angle: cutoff.to_radians(),
            beam_width: beam.to_radians(),
        })
    }
}

impl Light for SpotLight {
    /// `lum(I)` on the axis, with the cone that limits it.
    fn reach(&self, _: &Scene) -> Reach {
        Reach::Point {
            position: DVec3::from_array(self.position),
            intensity: Rgb::from_array(self.intensity).luminance(),
            cone: Some(Cone {
                axis: DVec3::from_array(self.direction).normalize_or_zero(),
                cutoff_angle: self.cutoff_angle,
                beam_width: self.beam_width,
            }),
        }
    }

    fn sample(&self, _: &Scene, x: DVec3, p_select: f64, _: [f64; 2]) -> Option<LightSample> {
        let axis = DVec3::from_array(self.direction);
        let towards_x = (x - DVec3::from_array(self.position)).normalize_or_zero();
        let theta = axis.dot(towards_x).clamp(-1.0, 1.0).acos();
        let falloff = spot_falloff(theta, self.cutoff_angle, self.beam_width);
        if falloff <= 0.0 {
            return None;
        }
        toward_point(
            x,
            &self.position,
            Rgb::from_array(self.intensity) * falloff,
            p_select,
        )
    }
}

/// A spot light's cone: unit axis and angles, radians.
#[derive(Clone, Copy, Debug)]
pub struct Cone {
    axis: DVec3,
    cutoff_angle: f64,
    beam_width: f64,
}

impl Cone {
    /// The falloff towards the unit direction `d` from the light.
    pub fn falloff(&self, d: DVec3) -> f64 {
        let theta = self.axis.dot(d).clamp(-1.0, 1.0).acos();
        spot_falloff(theta, self.cutoff_angle, self.beam_width)
    }
}

/// Mitsuba 3's spot falloff at angle `theta` from the axis: 1 within
/// `beam_width`, 0 beyond `cutoff_angle`, linear in angle between (radians).
pub fn spot_falloff(theta: f64, cutoff_angle: f64, beam_width: f64) -> f64 {
    if theta >= cutoff_angle {
        0.0
    } else if theta <= beam_width {
        1.0
    } else {
        (cutoff_angle - theta) / (cutoff_angle - beam_width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_falloff_is_zero_at_the_cutoff() {
        assert_eq!(spot_falloff(0.3, 0.3, 0.2), 0.0);
        assert_eq!(spot_falloff(0.2, 0.3, 0.2), 1.0);
        assert!((spot_falloff(0.25, 0.3, 0.2) - 0.5).abs() < 1e-12);
    }
}

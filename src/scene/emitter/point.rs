//! `point`: an isotropic point light, irradiance `I cos θ / d²` at
//! distance `d`.
//!
//! Parameters (Mitsuba 3's): `position` (`[x, y, z]`, default the origin),
//! `intensity` (radiant intensity, W/sr per channel, default 1).

use glam::DVec3;

use super::{Light, LightSample, Reach, power, toward_point};
use crate::color::Rgb;
use crate::scene::Scene;
use crate::scene::error::SceneError;
use crate::scene::params::Params;

/// A point light; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    /// World position.
    pub position: [f64; 3],
    /// Radiant intensity, W/sr per channel.
    pub intensity: [f64; 3],
}

impl PointLight {
    /// The parameters of a light document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Ok(Self {
            position: params.vector("position")?.unwrap_or([0.0; 3]),
            intensity: power(params, "intensity", 1.0)?,
        })
    }
}

impl Light for PointLight {
    /// `lum(I)` at the light's position.
    fn reach(&self, _: &Scene) -> Reach {
        Reach::Point {
            position: DVec3::from_array(self.position),
            intensity: Rgb::from_array(self.intensity).luminance(),
            cone: None,
        }
    }

    fn sample(&self, _: &Scene, x: DVec3, p_select: f64, _: [f64; 2]) -> Option<LightSample> {
        toward_point(x, &self.position, Rgb::from_array(self.intensity), p_select)
    }
}

//! `directional`: light from infinitely far away along one direction (the
//! sun, seen as a point), the same irradiance `E` on every surface facing
//! it.
//!
//! Parameters (Mitsuba 3's): `direction` (the direction the light travels,
//! default +z), `irradiance` (W/m² on a surface facing the light, default 1).

use glam::DVec3;

use super::{Light, LightSample, Reach, power};
use crate::color::Rgb;
use crate::scene::Scene;
use crate::scene::error::SceneError;
use crate::scene::params::Params;

/// A directional light; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct DirectionalLight {
    /// The unit direction the light travels, world frame.
    pub direction: [f64; 3],
    /// Irradiance on a surface facing the light, W/m² per channel.
    pub irradiance: [f64; 3],
}

impl DirectionalLight {
    /// The parameters of a light document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Ok(Self {
            direction: params.direction("direction")?.unwrap_or([0.0, 0.0, 1.0]),
            irradiance: power(params, "irradiance", 1.0)?,
        })
    }
}

impl Light for DirectionalLight {
    /// `lum(E)`, the same at every point.
    fn reach(&self, _: &Scene) -> Reach {
        Reach::Distant(Rgb::from_array(self.irradiance).luminance())
    }

    /// Its one direction, carrying `E` (the delta's weight).
    fn sample(&self, _: &Scene, _: DVec3, p_select: f64, _: [f64; 2]) -> Option<LightSample> {
        Some(LightSample {
            wi: -DVec3::from_array(self.direction),
            radiance: Rgb::from_array(self.irradiance),
            pdf: p_select,
            target: None,
            delta: true,
        })
    }
}

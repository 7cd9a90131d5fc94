//! `conductor`: a smooth metal, a perfect mirror weighted by the
//! conductor's complex Fresnel reflectance (`fresnel::conductor`): all light
//! from `ω_o` leaves along its mirror direction `(−ω_{o,x}, −ω_{o,y}, ω_{o,z})`.
//!
//! Parameters (Mitsuba 3's): `eta` and `k` (colours, the complex index
//! per RGB channel relative to the outside) or `material` (a named metal,
//! [`super::metals`]; default `none`, a perfect mirror);
//! `specular_reflectance` (a factor in [0, 1], a colour or a texture,
//! default 1).

use glam::DVec3;

use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, optical_params};
use crate::color::{Rgb, RgbArray};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};
use crate::optics::fresnel;

/// A smooth conductor; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Rgb,
}

impl Conductor {
    /// Fresnel reflectance per channel at `cos_i`, times `specular_reflectance`.
    pub fn reflectance(&self, cos_i: f64) -> Rgb {
        fresnel::conductor_rgb(cos_i, self.eta, self.k) * self.specular_reflectance
    }

    /// The mirror direction with the delta's weight: `value · cos θ_i /
    /// pdf` is the Fresnel reflectance. `None` from below the surface.
    pub fn sample(&self, wo: DVec3) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        Some(LobeSample {
            wi: DVec3::new(-wo.x, -wo.y, wo.z),
            value: self.reflectance(wo.z) * (1.0 / wo.z),
            pdf: 1.0,
            delta: true,
        })
    }
}

/// The parameters of a `conductor` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct ConductorMaterial {
    /// Real part `η` of the relative complex index, per channel.
    pub eta: RgbArray,
    /// Imaginary part `k` (absorption), per channel.
    pub k: RgbArray,
    /// A factor on the reflectance, in [0, 1].
    pub specular_reflectance: Texture,
}

impl Plugin for ConductorMaterial {
    type Model = Conductor;
}

impl ConductorMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let (eta, k) = optical_params::metal(params)?;
        Ok(Self {
            eta,
            k,
            specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
        })
    }
}

impl Parameters for ConductorMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.specular_reflectance]
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        Bsdf::Conductor(Conductor {
            eta: Rgb::from_array(self.eta),
            k: Rgb::from_array(self.k),
            specular_reflectance: lookup.rgb(&self.specular_reflectance),
        })
    }
}

impl Model for Conductor {
    fn sample(&self, wo: DVec3, _: f64, _: [f64; 2]) -> Option<LobeSample> {
        Conductor::sample(self, wo)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            delta: true,
            ..BsdfFlags::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mirror_returns_the_fresnel_reflectance() {
        let gold = Conductor {
            eta: Rgb::new(0.18, 0.42, 1.37),
            k: Rgb::new(3.42, 2.35, 1.77),
            specular_reflectance: Rgb::WHITE,
        };
        let wo = DVec3::new(0.6, 0.0, 0.8);
        let s = gold.sample(wo).unwrap();
        assert_eq!(s.wi, DVec3::new(-0.6, 0.0, 0.8));
        let throughput = s.value * (s.wi.z / s.pdf);
        let expected = gold.reflectance(0.8);
        assert!((throughput - expected).max_component().abs() < 1e-12);
        assert!(s.delta && expected.r > expected.b && expected.r < 1.0);
        assert!(gold.sample(DVec3::new(0.6, 0.0, -0.8)).is_none());
    }

    #[test]
    fn named_gold_reflects_as_in_mitsuba() {
        // Mitsuba 3.9.1's `conductor` with material Au reflects
        // (0.966069, 0.801277, 0.329045) at cos θ = 0.8.
        let (eta, k) = crate::scene::material::metals::named_metal("Au").unwrap();
        let at_08 = [0, 1, 2].map(|c| fresnel::conductor(0.8, eta[c], k[c]));
        for (ours, theirs) in at_08.iter().zip([0.966_069, 0.801_277, 0.329_045]) {
            assert!((ours - theirs).abs() < 2e-5, "{at_08:?}");
        }
    }
}

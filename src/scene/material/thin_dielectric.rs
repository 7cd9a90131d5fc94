//! `thindielectric`: a thin slab of dielectric (a window pane, a soap
//! film): light reflects off both faces any number of times, and what
//! crosses leaves along its original direction. With `F` the Fresnel
//! reflectance of one face at the arrival angle, the slab reflects
//! `R = F + (1 − F)² F / (1 − F²) = 2F / (1 + F)` (the geometric series of
//! inner bounces) and transmits `T = 1 − R`, both into delta directions:
//! the mirror direction and `−ω_o`.
//!
//! Parameters: as `dielectric`'s (`int_ior`, `ext_ior`,
//! `specular_reflectance`, `specular_transmittance`), Mitsuba 3's.

use glam::DVec3;

use super::Interface;
use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin};
use crate::color::Rgb;
use crate::scene::error::SceneError;
use crate::scene::texture::Texture;
use crate::optics::fresnel;

/// A thin dielectric slab; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinDielectric {
    /// Slab over surrounding index of refraction, > 0 and ≠ 1.
    pub eta: f64,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl ThinDielectric {
    /// The slab's reflectance `R` for light arriving with `|cos θ|`.
    pub fn reflectance(&self, cos: f64) -> f64 {
        let f = fresnel::dielectric(cos.abs(), self.eta).reflectance;
        2.0 * f / (1.0 + f)
    }

    /// Reflection (when `u_event < R`) or straight transmission, with the
    /// delta's weight: `value · |cos θ_i| / pdf` is the event's factor.
    /// `None` at grazing `ω_o`.
    pub fn sample(&self, wo: DVec3, u_event: f64) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let r = self.reflectance(wo.z);
        let (wi, factor, pdf) = if u_event < r {
            (DVec3::new(-wo.x, -wo.y, wo.z), self.specular_reflectance, r)
        } else {
            (-wo, self.specular_transmittance, 1.0 - r)
        };
        Some(LobeSample {
            wi,
            value: factor * (pdf / wi.z.abs()),
            pdf,
            delta: true,
        })
    }
}

/// The parameters of a `thindielectric` material: a dielectric's.
#[derive(Clone, Debug, PartialEq)]
pub struct ThinDielectricMaterial(pub Interface);

impl Plugin for ThinDielectricMaterial {
    type Model = ThinDielectric;
}

impl ThinDielectricMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Interface::parse(params).map(Self)
    }
}

impl Parameters for ThinDielectricMaterial {
    fn textures(&self) -> Vec<&Texture> {
        self.0.textures()
    }

    /// A slab is the same from both sides.
    fn may_be_a_side(&self) -> bool {
        false
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let (eta, specular_reflectance, specular_transmittance) = self.0.at(lookup);
        Bsdf::ThinDielectric(ThinDielectric {
            eta,
            specular_reflectance,
            specular_transmittance,
        })
    }
}

impl Model for ThinDielectric {
    fn sample(&self, wo: DVec3, u_lobe: f64, _: [f64; 2]) -> Option<LobeSample> {
        ThinDielectric::sample(self, wo, u_lobe)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            delta: true,
            transmission: true,
            ..BsdfFlags::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slab_sums_its_inner_bounces() {
        let slab = ThinDielectric {
            eta: 1.5,
            specular_reflectance: Rgb::WHITE,
            specular_transmittance: Rgb::WHITE,
        };
        for cos in [1.0, 0.7, 0.2] {
            let f = fresnel::dielectric(cos, 1.5).reflectance;
            // F + (1−F)² F Σ F^(2n), summed term by term.
            let series: f64 = f
                + (0..200)
                    .map(|n| (1.0 - f).powi(2) * f.powi(2 * n + 1))
                    .sum::<f64>();
            assert!((slab.reflectance(cos) - series).abs() < 1e-12, "{cos}");
        }
        // Normal incidence on glass: F = 0.04, R = 0.0769…
        assert!((slab.reflectance(1.0) - 0.08 / 1.04).abs() < 1e-12);
        let wo = DVec3::new(0.6, 0.0, 0.8);
        let through = slab.sample(wo, 0.99).unwrap();
        assert_eq!(through.wi, -wo);
        assert!((through.value.g * through.wi.z.abs() / through.pdf - 1.0).abs() < 1e-12);
        let back = slab.sample(wo, 0.0).unwrap();
        assert_eq!(back.wi, DVec3::new(-0.6, 0.0, 0.8));
        // Mitsuba 3.9.1's `thindielectric` (int_ior 1.5) reflects with
        // probability 0.0840980 from (0.6, 0, 0.8) and 0.0775437 from (0.3, −0.2, −0.932738).
        assert!((slab.reflectance(0.8) - 0.084_098).abs() < 1e-6);
        assert!((slab.reflectance(-(0.87f64.sqrt())) - 0.077_543_7).abs() < 1e-6);
        // Seen from either side alike.
        assert_eq!(slab.reflectance(-0.8), slab.reflectance(0.8));
    }
}

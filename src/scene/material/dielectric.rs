//! `dielectric`: a smooth interface between two dielectrics. Light from
//! `ω_o` is reflected about the normal with the Fresnel reflectance `F`
//! (`fresnel::dielectric`) and refracted by Snell's law with `1 − F`, its
//! radiance scaled by `1/η'²` (`η'` the index of `ω_i`'s side over
//! `ω_o`'s), as `rough_dielectric` does in the limit of zero roughness.
//! Sampling picks reflection with probability `F`, so the throughput of
//! either event is the event's factor alone.
//!
//! Parameters (Mitsuba 3's names): `int_ior` (default BK7, 1.5046) and
//! `ext_ior` (default air), numbers or named media ([`super::ior`]), whose
//! ratio is `eta`; `specular_reflectance` and `specular_transmittance`
//! (factors in [0, 1], colours or textures, default 1).

use glam::DVec3;

use super::Interface;
use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin};
use crate::color::Rgb;
use crate::scene::error::SceneError;
use crate::scene::texture::Texture;
use crate::optics::fresnel;

/// A smooth dielectric interface; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    /// Interior over exterior index of refraction, > 0 and ≠ 1.
    pub eta: f64,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl Dielectric {
    /// Reflection (when `u_event < F`) or refraction of `ω_o`, with the
    /// delta's weight: `value · |cos θ_i| / pdf` is `specular_reflectance`
    /// or `specular_transmittance / η'²`. `None` at grazing `ω_o`.
    pub fn sample(&self, wo: DVec3, u_event: f64) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let fresnel = fresnel::dielectric(wo.z, self.eta);
        let f = fresnel.reflectance;
        if u_event < f {
            let wi = DVec3::new(-wo.x, -wo.y, wo.z);
            return Some(LobeSample {
                wi,
                value: self.specular_reflectance * (f / wi.z.abs()),
                pdf: f,
                delta: true,
            });
        }
        // Snell: the tangential part scales by 1/η', the normal part is cos θ_t.
        let wi = DVec3::new(-wo.x / fresnel.eta, -wo.y / fresnel.eta, fresnel.cos_t).normalize();
        let scale = (1.0 - f) / (fresnel.eta * fresnel.eta);
        Some(LobeSample {
            wi,
            value: self.specular_transmittance * (scale / wi.z.abs()),
            pdf: 1.0 - f,
            delta: true,
        })
    }
}

/// The parameters of a `dielectric` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct DielectricMaterial(pub Interface);

impl Plugin for DielectricMaterial {
    type Model = Dielectric;
}

impl DielectricMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Interface::parse(params).map(Self)
    }
}

impl Parameters for DielectricMaterial {
    fn textures(&self) -> Vec<&Texture> {
        self.0.textures()
    }

    /// A dielectric is the same from both sides.
    fn may_be_a_side(&self) -> bool {
        false
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let (eta, specular_reflectance, specular_transmittance) = self.0.at(lookup);
        Bsdf::Dielectric(Dielectric {
            eta,
            specular_reflectance,
            specular_transmittance,
        })
    }
}

impl Model for Dielectric {
    fn sample(&self, wo: DVec3, u_lobe: f64, _: [f64; 2]) -> Option<LobeSample> {
        Dielectric::sample(self, wo, u_lobe)
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
    use std::f64::consts::PI;

    use super::*;

    fn glass() -> Dielectric {
        Dielectric {
            eta: 1.5,
            specular_reflectance: Rgb::WHITE,
            specular_transmittance: Rgb::WHITE,
        }
    }

    #[test]
    fn events_follow_fresnel_and_snell() {
        let wo = DVec3::new(30f64.to_radians().sin(), 0.0, 30f64.to_radians().cos());
        let f = fresnel::dielectric(wo.z, 1.5).reflectance;
        let reflected = glass().sample(wo, 0.5 * f).unwrap();
        assert_eq!(reflected.wi, DVec3::new(-wo.x, 0.0, wo.z));
        let t = glass().sample(wo, 0.5 + 0.5 * f).unwrap();
        // sin θ_i = η sin θ_t, below the surface, opposite azimuth.
        assert!((wo.x - 1.5 * (-t.wi.x)).abs() < 1e-12 && t.wi.z < 0.0);
        assert!(((t.wi.length()) - 1.0).abs() < 1e-12);
        // Throughputs are the events' factors: 1 for reflection, 1/η'² for
        // refraction with η' = 1.5 (ω_i in the glass, ω_o outside).
        let tr = t.value.g * t.wi.z.abs() / t.pdf;
        assert!((tr - 1.0 / 2.25).abs() < 1e-12, "{tr}");
        let rr = reflected.value.g * reflected.wi.z / reflected.pdf;
        assert!((rr - 1.0).abs() < 1e-12);
    }

    #[test]
    fn events_agree_with_mitsuba() {
        // Mitsuba 3.9.1's `dielectric` (int_ior 1.5) sampled from
        // ω_o = (0.6, 0, 0.8): reflection with probability 0.0438947,
        // refraction along (−0.4, 0, −0.916515) with throughput 1/2.25.
        let wo = DVec3::new(0.6, 0.0, 0.8);
        let r = glass().sample(wo, 0.0).unwrap();
        assert!((r.pdf - 0.043_894_73).abs() < 1e-7, "{}", r.pdf);
        let t = glass().sample(wo, 0.99).unwrap();
        assert!((t.wi - DVec3::new(-0.4, 0.0, -0.916_515_1)).length() < 1e-6);
        // From inside, (0.3, −0.2, −0.932738): refraction out with throughput 2.25.
        let inside = DVec3::new(0.3, -0.2, -(0.87f64.sqrt()));
        let out = glass().sample(inside, 0.99).unwrap();
        assert!((out.wi - DVec3::new(-0.45, 0.3, 0.841_130_1)).length() < 1e-6);
        assert!((out.value.g * out.wi.z.abs() / out.pdf - 2.25).abs() < 1e-9);
        assert!((out.pdf - 0.957_746_1).abs() < 1e-6, "{}", out.pdf);
    }

    #[test]
    fn light_inside_past_the_critical_angle_is_always_reflected() {
        let theta = PI - 1.0; // 57° from the inward normal, past 41.8°
        let wo = DVec3::new(theta.sin(), 0.0, theta.cos());
        for u in [0.0, 0.5, 0.999] {
            let s = glass().sample(wo, u).unwrap();
            assert!(s.wi.z < 0.0 && (s.pdf - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn crossing_and_returning_retraces_the_ray() {
        let wo = DVec3::new(0.3, -0.2, 0.93).normalize();
        let t = glass().sample(wo, 1.0).unwrap();
        // Light arriving along the refracted ray from inside leaves along ω_o.
        let back = glass().sample(t.wi, 1.0).unwrap();
        assert!((back.wi - wo).length() < 1e-12, "{:?}", back.wi);
    }
}

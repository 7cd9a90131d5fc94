//! `mask`: with probability `α` (the opacity) the nested BSDF scatters,
//! otherwise light passes straight through (`ω_i = −ω_o`, a delta
//! transmission of weight `1 − α`), Mitsuba 3's. Shadow rays stop at the
//! surface as at any other (as in Mitsuba); light crossing it is reached
//! by sampling the pass-through.

use glam::DVec3;

use super::{Bsdf, BsdfFlags, LobeSample};
use crate::color::Rgb;

#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    /// `α` in [0, 1].
    pub opacity: f64,
    pub bsdf: Bsdf,
}

impl Mask {
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.bsdf.eval(wo, wi) * self.opacity
    }

    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.bsdf.pdf(wo, wi) * self.opacity
    }

    pub fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        let alpha = self.opacity;
        // Where the nested BSDF scatters nothing (a one-sided one seen
        // from below) passing through is the only event.
        let scatters = self.bsdf.scatters_towards(wo);
        if u_lobe >= alpha || !scatters {
            let wi = -wo;
            if wi.z == 0.0 || alpha >= 1.0 {
                return None;
            }
            let pass = 1.0 - alpha;
            return Some(LobeSample {
                wi,
                value: Rgb::WHITE * (pass / wi.z.abs()),
                pdf: if scatters { pass } else { 1.0 },
                delta: true,
            });
        }
        let s = self.bsdf.sample(wo, u_lobe / alpha, u)?;
        Some(LobeSample {
            value: s.value * alpha,
            pdf: s.pdf * alpha,
            ..s
        })
    }

    pub fn flags(&self) -> BsdfFlags {
        let pass = BsdfFlags {
            delta: self.opacity < 1.0,
            transmission: self.opacity < 1.0,
            ..BsdfFlags::default()
        };
        self.bsdf.flags().union(pass)
    }

    pub fn lambertian(&self, wo: DVec3) -> Rgb {
        self.bsdf.lambertian(wo) * self.opacity
    }

    pub fn scatters_towards(&self, wo: DVec3) -> bool {
        self.opacity < 1.0 || self.bsdf.scatters_towards(wo)
    }
}

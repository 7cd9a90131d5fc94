//! `blendbsdf`: `f = (1 − w) f₀ + w f₁` (Mitsuba 3's). Sampling picks `f₁`
//! with probability `w`; a direction from a spread lobe is then weighed by
//! the whole blend's value and density (so MIS sees the mixture), a delta
//! event by its component's share.

use glam::DVec3;

use super::{Bsdf, BsdfFlags, LobeSample};
use crate::color::Rgb;

#[derive(Clone, Debug, PartialEq)]
pub struct Blend {
    /// `w` in [0, 1].
    pub weight: f64,
    pub bsdfs: [Bsdf; 2],
}

impl Blend {
    fn mix<T: std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T>>(&self, a: T, b: T) -> T {
        a * (1.0 - self.weight) + b * self.weight
    }

    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.mix(self.bsdfs[0].eval(wo, wi), self.bsdfs[1].eval(wo, wi))
    }

    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.mix(self.bsdfs[0].pdf(wo, wi), self.bsdfs[1].pdf(wo, wi))
    }

    pub fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        let w = self.weight;
        // The lobe number reused for the component's own choice.
        let (i, share, u_lobe) = if u_lobe < w {
            (1, w, u_lobe / w)
        } else {
            (0, 1.0 - w, (u_lobe - w) / (1.0 - w))
        };
        let s = self.bsdfs[i].sample(wo, u_lobe.min(1.0 - f64::EPSILON), u)?;
        if s.delta {
            return Some(LobeSample {
                value: s.value * share,
                pdf: s.pdf * share,
                ..s
            });
        }
        LobeSample::spread(s.wi, self.pdf(wo, s.wi), || self.eval(wo, s.wi))
    }

    pub fn flags(&self) -> BsdfFlags {
        self.bsdfs[0].flags().union(self.bsdfs[1].flags())
    }

    pub fn lambertian(&self, wo: DVec3) -> Rgb {
        self.mix(self.bsdfs[0].lambertian(wo), self.bsdfs[1].lambertian(wo))
    }

    pub fn scatters_towards(&self, wo: DVec3) -> bool {
        self.bsdfs.iter().any(|b| b.scatters_towards(wo))
    }
}

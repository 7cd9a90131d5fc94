//! Known densities `p` of the BMC integral `I = ∫_H f(ω) p(ω) dω`
//! (docs/math.md §1): the BRDF·cosine factor, which need not integrate to 1.
//!
//! All directions are in the local frame (z = surface normal); `p` is zero
//! below the horizon (`z < 0`).

use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, PI, TAU};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::error::BmcError;
use super::integrate::{Tolerance, adaptive};

/// Largest accepted Phong exponent; far beyond any glossy material, and
/// keeps `cos^m α` representable for the quadrature (lobe width `~1/sqrt(m)`).
pub const MAX_PHONG_EXPONENT: f64 = 1.0e6;

/// Density of the integral, in the local frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Density {
    /// `1/(2π)` on the hemisphere (∫ = 1).
    Uniform,
    /// `cos θ / π` (∫ = 1); with it `I = E/π` for irradiance `E`.
    Lambert,
    /// Normalised modified Phong lobe times the cosine, clamped to the
    /// hemisphere: `(m+2)/(2π) max(0, ω·r)^m · max(0, cos θ)`.
    ///
    /// The mirror direction is `r = (sin θ_r, 0, cos θ_r)`: azimuth 0 in the
    /// local frame (callers rotate their frame about the normal to put it
    /// there) and **polar angle** `θ_r = mirror_elevation` measured from the
    /// normal, in radians, `0 ≤ θ_r ≤ π/2` (0: r along the normal; π/2: grazing).
    /// For `θ_r > 0` the lobe is cut by the horizon, so `∫p < 1`.
    Phong {
        /// `m ≥ 0`, at most [`MAX_PHONG_EXPONENT`].
        exponent: f64,
        /// `θ_r` in radians, `[0, π/2]` (see above).
        mirror_elevation: f64,
    },
}

/// Bitwise identity of a density, for cache keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DensityKey {
    /// [`Density::Uniform`].
    Uniform,
    /// [`Density::Lambert`].
    Lambert,
    /// [`Density::Phong`], with the bits of `exponent` and `mirror_elevation`.
    Phong(u64, u64),
}

impl Density {
    /// Check the parameters: a typed error naming the field, never a panic.
    pub fn validate(&self) -> Result<(), BmcError> {
        if let Density::Phong {
            exponent,
            mirror_elevation,
        } = *self
        {
            if !(exponent.is_finite() && (0.0..=MAX_PHONG_EXPONENT).contains(&exponent)) {
                return Err(BmcError::invalid(
                    "exponent",
                    format!("must be finite and in [0, {MAX_PHONG_EXPONENT}], got {exponent}"),
                ));
            }
            if !(mirror_elevation.is_finite() && (0.0..=FRAC_PI_2).contains(&mirror_elevation)) {
                return Err(BmcError::invalid(
                    "mirror_elevation",
                    format!("must be in [0, π/2] radians, got {mirror_elevation}"),
                ));
            }
        }
        Ok(())
    }

    /// `p(ω)` for a unit direction in the local frame.
    pub fn eval(&self, w: DVec3) -> f64 {
        if w.z < 0.0 {
            return 0.0;
        }
        match *self {
            Density::Uniform => 0.5 / PI,
            Density::Lambert => w.z * FRAC_1_PI,
            Density::Phong { exponent, .. } => {
                let cos_alpha = w.dot(self.mirror_direction());
                if cos_alpha <= 0.0 {
                    return 0.0;
                }
                phong_normalisation(exponent) * cos_alpha.powf(exponent) * w.z
            }
        }
    }

    /// `∫_H p(ω) dω`, accurate to ~1e-14 relative.
    ///
    /// Phong: in a frame about `r` with `u = cos α` and azimuth `ψ`, the cosine
    /// `cos θ = A + B cos ψ` (`A = u cos θ_r`, `B = sqrt(1−u²) sin θ_r`); its
    /// clipped azimuthal integral is closed-form (`clipped_cosine_arc`), and
    /// for `u ≥ sin θ_r` the whole circle is above the horizon, which gives
    /// `cos θ_r (1 − sin^{m+2} θ_r)` in closed form; only `u < sin θ_r` is
    /// integrated numerically (over `α = acos u`).
    pub fn integral(&self) -> f64 {
        match *self {
            Density::Uniform | Density::Lambert => 1.0,
            Density::Phong {
                exponent: m,
                mirror_elevation,
            } => {
                let (sin_r, cos_r) = mirror_elevation.sin_cos();
                let unclipped = cos_r * (1.0 - sin_r.powf(m + 2.0));
                // Over α (not u): sin α stays analytic up to α = 0, which the
                // clipped range reaches for grazing r.
                let clipped = adaptive(
                    &|alpha: f64| {
                        let (v, u) = alpha.sin_cos();
                        u.powf(m) * v * clipped_cosine_arc(u * cos_r, v * sin_r)
                    },
                    FRAC_PI_2 - mirror_elevation,
                    FRAC_PI_2,
                    Tolerance {
                        rel: 1e-13,
                        abs: 0.0,
                    },
                );
                unclipped + phong_normalisation(m) * clipped
            }
        }
    }

    /// Mirror direction `r` of a Phong density in the local frame (the normal
    /// for the other densities, whose symmetry axis it is).
    pub fn mirror_direction(&self) -> DVec3 {
        match *self {
            Density::Phong {
                mirror_elevation, ..
            } => {
                let (s, c) = mirror_elevation.sin_cos();
                DVec3::new(s, 0.0, c)
            }
            _ => DVec3::Z,
        }
    }

    /// Bitwise key for caches.
    pub fn cache_key(&self) -> DensityKey {
        match *self {
            Density::Uniform => DensityKey::Uniform,
            Density::Lambert => DensityKey::Lambert,
            Density::Phong {
                exponent,
                mirror_elevation,
            } => DensityKey::Phong(exponent.to_bits(), mirror_elevation.to_bits()),
        }
    }
}

/// `(m+2)/(2π)`, the normalisation of the modified Phong lobe.
pub(crate) fn phong_normalisation(m: f64) -> f64 {
    (m + 2.0) / TAU
}

/// Half-width `γ₀ ∈ [0, π]` of the arc where `a + b cos γ ≥ 0` (`b ≥ 0`):
/// the part of a circle of directions that lies above the horizon.
pub(crate) fn positive_half_arc(a: f64, b: f64) -> f64 {
    if a >= b {
        PI
    } else if a <= -b {
        0.0
    } else {
        (-a / b).clamp(-1.0, 1.0).acos()
    }
}

/// `∫_{−π}^{π} max(0, a + b cos γ) dγ = 2(a γ₀ + b sin γ₀)` (`b ≥ 0`): the
/// horizon-clipped cosine integrated around a circle of directions.
pub(crate) fn clipped_cosine_arc(a: f64, b: f64) -> f64 {
    let g = positive_half_arc(a, b);
    2.0 * (a * g + b * g.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent brute force: Gauss–Legendre in cos θ × Gauss–Legendre in
    /// φ on a fine product grid in the *local* frame.
    fn brute_force_integral(d: &Density, n_mu: usize, n_phi: usize) -> f64 {
        use crate::bmc::integrate::GaussLegendre;
        let gm = GaussLegendre::new(n_mu);
        let gp = GaussLegendre::new(n_phi);
        let mut sum = 0.0;
        for (x, wx) in gm.nodes.iter().zip(&gm.weights) {
            let mu = 0.5 * (x + 1.0);
            let s = (1.0 - mu * mu).sqrt();
            for (y, wy) in gp.nodes.iter().zip(&gp.weights) {
                let phi = PI * (y + 1.0);
                let w = DVec3::new(s * phi.cos(), s * phi.sin(), mu);
                sum += wx * wy * d.eval(w);
            }
        }
        sum * 0.5 * PI
    }

    #[test]
    fn phong_integral_is_one_at_normal_incidence_and_below_one_when_clipped() {
        for m in [0.0, 1.0, 10.0, 100.0, 5000.0] {
            let d = Density::Phong {
                exponent: m,
                mirror_elevation: 0.0,
            };
            assert!((d.integral() - 1.0).abs() < 1e-13, "m={m}");
        }
        let mut last = 1.0;
        for theta in [0.2, 0.6, 1.0, 1.4, FRAC_PI_2] {
            let d = Density::Phong {
                exponent: 20.0,
                mirror_elevation: theta,
            };
            let v = d.integral();
            assert!(v < last && v > 0.0, "θ={theta}: {v}");
            last = v;
        }
    }

    #[test]
    fn phong_integral_matches_brute_force() {
        for (m, theta) in [(3.0, 1.2), (10.0, FRAC_PI_2), (1.0, 0.3)] {
            let d = Density::Phong {
                exponent: m,
                mirror_elevation: theta,
            };
            // The clipped integrand has kinks, so the brute force converges
            // slowly; 1e-6 is what this grid resolves.
            let bf = brute_force_integral(&d, 400, 400);
            assert!((d.integral() / bf - 1.0).abs() < 1e-6, "m={m} θ={theta}");
        }
        for d in [Density::Uniform, Density::Lambert] {
            assert!((brute_force_integral(&d, 50, 50) - 1.0).abs() < 1e-12);
        }
    }

    /// m = 0: p = cos θ/π on the lune between the hemispheres about n and r,
    /// and `∫_lune ω dω = (π/2)(n + r)`, so `∫p = (1 + cos θ_r)/2`.
    #[test]
    fn phong_integral_of_the_flat_lobe_is_closed_form() {
        for theta in [0.0, 0.3, 0.7, 1.2, FRAC_PI_2] {
            let d = Density::Phong {
                exponent: 0.0,
                mirror_elevation: theta,
            };
            assert!(
                (d.integral() - 0.5 * (1.0 + theta.cos())).abs() < 1e-13,
                "θ={theta}"
            );
        }
    }

    #[test]
    fn eval_is_zero_below_the_horizon_and_behind_the_lobe() {
        let d = Density::Phong {
            exponent: 0.0,
            mirror_elevation: 1.0,
        };
        let behind = -d.mirror_direction();
        let w = DVec3::new(behind.x, behind.y, behind.z.abs()).normalize();
        assert!(w.dot(d.mirror_direction()) < 0.0);
        assert_eq!(d.eval(w), 0.0);
        assert_eq!(Density::Lambert.eval(DVec3::new(0.0, 0.6, -0.8)), 0.0);
        assert_eq!(Density::Uniform.eval(DVec3::new(0.0, 0.6, -0.8)), 0.0);
        assert!((Density::Lambert.eval(DVec3::Z) - FRAC_1_PI).abs() < 1e-16);
    }

    #[test]
    fn bad_parameters_are_typed_errors() {
        for (m, t, field) in [
            (-1.0, 0.1, "exponent"),
            (f64::NAN, 0.1, "exponent"),
            (1e9, 0.1, "exponent"),
            (2.0, -0.1, "mirror_elevation"),
            (2.0, 1.6, "mirror_elevation"),
            (2.0, f64::NAN, "mirror_elevation"),
        ] {
            let d = Density::Phong {
                exponent: m,
                mirror_elevation: t,
            };
            assert_eq!(d.validate().unwrap_err().field(), Some(field));
        }
        assert!(Density::Lambert.validate().is_ok());
    }

    #[test]
    fn serde_uses_tagged_snake_case() {
        let d = Density::Phong {
            exponent: 8.0,
            mirror_elevation: 0.5,
        };
        let s = serde_json::to_string(&d).unwrap();
        assert_eq!(
            s,
            r#"{"kind":"phong","exponent":8.0,"mirror_elevation":0.5}"#
        );
        assert_eq!(serde_json::from_str::<Density>(&s).unwrap(), d);
        assert_eq!(
            serde_json::from_str::<Density>(r#"{"kind":"lambert"}"#).unwrap(),
            Density::Lambert
        );
    }
}

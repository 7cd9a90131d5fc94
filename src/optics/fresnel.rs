//! Fresnel reflectance of unpolarised light at a smooth interface: between
//! two dielectrics (real relative index `η = n_t / n_i`) and at a conductor
//! (complex index `η + i k`, relative to the outside medium). Both are the
//! mean of the s- and p-polarised reflectances (Born & Wolf, "Principles of
//! Optics", §1.5; pbrt-v4 §9.3).

use num_complex::Complex64;

use crate::color::Rgb;

/// Reflectance at a dielectric interface, with what refraction needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricFresnel {
    /// Fraction of the light reflected, in `[0, 1]` (1 under total internal
    /// reflection).
    pub reflectance: f64,
    /// `cos θ_t` of the transmitted direction, signed opposite to
    /// `cos θ_i` (0 under total internal reflection).
    pub cos_t: f64,
    /// The relative index the light meets, `η` when it arrives from the
    /// outside (`cos θ_i > 0`), `1/η` from the inside.
    pub eta: f64,
}

/// Fresnel reflectance of light arriving with `cos_i = ω_i · n` (positive
/// from the side the normal points to, the outside) at an interface of
/// relative index `eta = n_inside / n_outside > 0`.
pub fn dielectric(cos_i: f64, eta: f64) -> DielectricFresnel {
    let (cos_i_abs, eta_seen) = if cos_i >= 0.0 {
        (cos_i, eta)
    } else {
        (-cos_i, 1.0 / eta)
    };
    let cos_i_abs = cos_i_abs.min(1.0);
    // Snell: sin²θ_t = sin²θ_i / η².
    let sin2_t = (1.0 - cos_i_abs * cos_i_abs) / (eta_seen * eta_seen);
    if sin2_t >= 1.0 {
        return DielectricFresnel {
            reflectance: 1.0,
            cos_t: 0.0,
            eta: eta_seen,
        };
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_s = (cos_i_abs - eta_seen * cos_t) / (cos_i_abs + eta_seen * cos_t);
    let r_p = (eta_seen * cos_i_abs - cos_t) / (eta_seen * cos_i_abs + cos_t);
    DielectricFresnel {
        reflectance: 0.5 * (r_s * r_s + r_p * r_p),
        cos_t: if cos_i >= 0.0 { -cos_t } else { cos_t },
        eta: eta_seen,
    }
}

/// [`conductor`] per RGB channel.
pub fn conductor_rgb(cos_i: f64, eta: Rgb, k: Rgb) -> Rgb {
    Rgb::new(
        conductor(cos_i, eta.r, k.r),
        conductor(cos_i, eta.g, k.g),
        conductor(cos_i, eta.b, k.b),
    )
}

/// Fresnel reflectance of a conductor with complex relative index
/// `eta + i k` for light arriving with `cos_i ∈ [0, 1]` from outside.
pub fn conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let n = Complex64::new(eta, k);
    let sin2_i = Complex64::from(1.0 - cos_i * cos_i);
    // Snell with a complex index: cos θ_t = √(1 − sin²θ_i / n²).
    let cos_t = (Complex64::from(1.0) - sin2_i / (n * n)).sqrt();
    let ci = Complex64::from(cos_i);
    let r_s = (ci - n * cos_t) / (ci + n * cos_t);
    let r_p = (n * ci - cos_t) / (n * ci + cos_t);
    0.5 * (r_s.norm_sqr() + r_p.norm_sqr())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_matches_the_closed_form() {
        // ((η − 1) / (η + 1))² for a dielectric, ((η−1)² + k²)/((η+1)² + k²) for a conductor.
        for eta in [1.0, 1.333, 1.5046, 2.419] {
            let r = dielectric(1.0, eta).reflectance;
            let expected = ((eta - 1.0) / (eta + 1.0)).powi(2);
            assert!((r - expected).abs() < 1e-12, "{eta}: {r} vs {expected}");
            assert!((conductor(1.0, eta, 0.0) - expected).abs() < 1e-12);
        }
        let (eta, k) = (0.2, 3.9);
        let expected = ((eta - 1.0f64).powi(2) + k * k) / ((eta + 1.0f64).powi(2) + k * k);
        assert!((conductor(1.0, eta, k) - expected).abs() < 1e-12);
    }

    #[test]
    fn a_conductor_without_absorption_is_a_dielectric() {
        for i in 0..=20 {
            let cos_i = f64::from(i) / 20.0;
            let d = dielectric(cos_i, 1.5).reflectance;
            let c = conductor(cos_i, 1.5, 0.0);
            assert!((d - c).abs() < 1e-12, "cos {cos_i}: {d} vs {c}");
        }
    }

    #[test]
    fn grazing_light_is_reflected_and_inside_light_can_be_trapped() {
        assert!((dielectric(0.0, 1.5).reflectance - 1.0).abs() < 1e-12);
        assert!((conductor(0.0, 0.2, 3.9) - 1.0).abs() < 1e-12);
        // From inside glass beyond the critical angle asin(1/1.5) ≈ 41.8°.
        let inside = dielectric(-(50f64.to_radians().cos()), 1.5);
        assert_eq!((inside.reflectance, inside.cos_t), (1.0, 0.0));
        // Below it, light crosses, and Snell's law holds.
        let cos_i = 30f64.to_radians().cos();
        let out = dielectric(cos_i, 1.5);
        let sin_t = (1.0 - out.cos_t * out.cos_t).sqrt();
        assert!((30f64.to_radians().sin() - 1.5 * sin_t).abs() < 1e-12);
        assert!(out.cos_t < 0.0 && out.reflectance < 0.1);
    }

    #[test]
    fn reflectance_is_the_same_from_both_sides_of_a_refraction() {
        // Stokes relations: the reflectance at θ_i outside equals that at θ_t inside.
        let cos_i = 0.7;
        let out = dielectric(cos_i, 1.33);
        let back = dielectric(out.cos_t, 1.33);
        assert!((out.reflectance - back.reflectance).abs() < 1e-12);
        assert!((back.cos_t - cos_i).abs() < 1e-12);
    }
}

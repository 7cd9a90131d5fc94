use std::f64::consts::{FRAC_PI_2, TAU};

use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::*;
use crate::optics::chi_square::ChiSquare;

/// `θ = (π/2) t²`: resolution where sharp lobes peak, at the normal.
fn theta_of(t: f64) -> f64 {
    FRAC_PI_2 * t * t
}

fn direction(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// `∫ f(m) dm` over the upper hemisphere by the midpoint rule on
/// `(t, φ) ∈ [t0, t1] × [φ0, φ1]`, `n × n` cells.
fn integrate(
    f: &dyn Fn(DVec3) -> f64,
    (t0, t1): (f64, f64),
    (p0, p1): (f64, f64),
    n: usize,
) -> f64 {
    let (dt, dp) = ((t1 - t0) / n as f64, (p1 - p0) / n as f64);
    let mut sum = 0.0;
    for i in 0..n {
        let t = t0 + (i as f64 + 0.5) * dt;
        let theta = theta_of(t);
        // dθ = π t dt; dm = sin θ dθ dφ.
        let jacobian = theta.sin() * std::f64::consts::PI * t * dt * dp;
        for j in 0..n {
            let phi = p0 + (j as f64 + 0.5) * dp;
            sum += f(direction(theta, phi)) * jacobian;
        }
    }
    sum
}

fn distributions() -> Vec<Microfacet> {
    let mut all = Vec::new();
    for kind in [MicrofacetKind::Ggx, MicrofacetKind::Beckmann] {
        for (au, av) in [(0.1, 0.1), (0.5, 0.5), (1.0, 1.0), (0.2, 0.6)] {
            all.push(Microfacet::new(kind, au, av).unwrap());
        }
    }
    all
}

fn viewers() -> [DVec3; 4] {
    [
        DVec3::Z,
        direction(0.6, 0.3),
        direction(1.2, 2.0),
        direction(1.5, -1.0),
    ]
}

#[test]
fn projected_area_is_one() {
    for d in distributions() {
        let area = integrate(&|m| d.d(m) * m.z, (0.0, 1.0), (0.0, TAU), 1200);
        assert!((area - 1.0).abs() < 2e-3, "{d:?}: {area}");
    }
}

#[test]
fn visible_normals_are_normalised_so_smith_masking_is_consistent() {
    // ∫ G1(ω, m) max(0, ω·m) D(m) dm = ω_z is Smith's Λ's defining property.
    for d in distributions() {
        for w in viewers() {
            let visible = integrate(
                &|m| d.g1(w, m) * w.dot(m).max(0.0) * d.d(m) / w.z,
                (0.0, 1.0),
                (0.0, TAU),
                1200,
            );
            assert!((visible - 1.0).abs() < 3e-3, "{d:?} from {w}: {visible}");
        }
    }
}

#[test]
fn masking_is_symmetric_and_bounded() {
    for d in distributions() {
        for (wi, wo) in [(viewers()[1], viewers()[2]), (viewers()[3], viewers()[0])] {
            let m = (wi + wo).normalize();
            let g = d.g(wi, wo, m);
            assert!((g - d.g(wo, wi, m)).abs() < 1e-15);
            // Height correlation shadows no more than independent masking.
            assert!(
                g >= d.g1(wi, m) * d.g1(wo, m) - 1e-15 && g <= 1.0,
                "{d:?}: {g}"
            );
        }
        assert_eq!(d.g1(DVec3::Z, DVec3::Z), 1.0);
        assert_eq!(d.g1(DVec3::new(0.0, 0.6, -0.8), DVec3::Z), 0.0);
    }
    assert!(Microfacet::new(MicrofacetKind::Ggx, 0.0, 0.1).is_none());
    assert!(Microfacet::new(MicrofacetKind::Ggx, 0.1, f64::NAN).is_none());
}

#[test]
fn sampled_normals_follow_the_reported_density() {
    const T_BINS: usize = 16;
    const P_BINS: usize = 24;
    const SAMPLES: usize = 100_000;
    let mut rng = Pcg64::seed_from_u64(0x5EED);
    for d in distributions() {
        for w in viewers() {
            let mut counts = vec![0.0f64; T_BINS * P_BINS];
            for _ in 0..SAMPLES {
                let s = d.sample(w, [rng.random(), rng.random()]);
                assert!((s.m.length() - 1.0).abs() < 1e-9 && s.m.z > 0.0);
                let pdf = d.pdf(w, s.m);
                assert!(
                    (s.pdf - pdf).abs() <= 1e-9 * pdf.max(1.0),
                    "{d:?}: {} vs {pdf}",
                    s.pdf
                );
                let theta = s.m.z.clamp(-1.0, 1.0).acos();
                let t = (theta / FRAC_PI_2).sqrt();
                let phi = s.m.y.atan2(s.m.x).rem_euclid(TAU);
                let i = ((t * T_BINS as f64) as usize).min(T_BINS - 1);
                let j = ((phi / TAU * P_BINS as f64) as usize).min(P_BINS - 1);
                counts[i * P_BINS + j] += 1.0;
            }
            let mut expected = vec![0.0f64; T_BINS * P_BINS];
            for i in 0..T_BINS {
                for j in 0..P_BINS {
                    let t = (i as f64 / T_BINS as f64, (i + 1) as f64 / T_BINS as f64);
                    let p = (
                        j as f64 / P_BINS as f64 * TAU,
                        (j + 1) as f64 / P_BINS as f64 * TAU,
                    );
                    expected[i * P_BINS + j] =
                        SAMPLES as f64 * integrate(&|m| d.pdf(w, m), t, p, 24);
                }
            }
            let test = ChiSquare::of(&counts, &expected);
            let (observed, expected) = test.left_out;
            assert!(observed <= 5.0 + 5.0 * expected, "{d:?}");
            assert!(test.passes(), "{d:?} from {w}: {test}");
        }
    }
}

#[test]
fn beckmann_visible_slopes_invert_their_cdf() {
    // A(x) = mu (√π/2) erfc(−x) + e^(−x²)/2 is the integral of the density
    // (mu − x) e^(−x²) from −∞, so A(x(u)) = u A(mu) at every u and view.
    for mu in [0.0, 0.05, 0.7, 3.0, 40.0] {
        let a = |x: f64| mu * 0.5 * PI.sqrt() * libm::erfc(-x) + 0.5 * (-x * x).exp();
        for u in [1e-6, 0.1, 0.5, 0.9, 0.999_999] {
            let x = beckmann_visible_slope(mu, u);
            assert!(x <= mu, "{mu} {u}: {x}");
            assert!((a(x) - u * a(mu)).abs() < 1e-10 * a(mu), "{mu} {u}: {x}");
        }
    }
}

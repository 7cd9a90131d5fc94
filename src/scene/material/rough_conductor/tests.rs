use std::f64::consts::{FRAC_PI_2, PI, TAU};

use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::*;
use crate::optics::chi_square::ChiSquare;
use crate::optics::microfacet::MicrofacetKind;

fn direction(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// Gold-like: η ≈ (0.18, 0.42, 1.37), k ≈ (3.42, 2.35, 1.77).
fn metal(kind: MicrofacetKind, au: f64, av: f64) -> RoughConductor {
    RoughConductor {
        distribution: Microfacet::new(kind, au, av).unwrap(),
        eta: Rgb::new(0.18, 0.42, 1.37),
        k: Rgb::new(3.42, 2.35, 1.77),
        specular_reflectance: Rgb::WHITE,
    }
}

/// A perfect reflector (F = 1): η = 0, no absorption term needed.
fn white(kind: MicrofacetKind, alpha: f64) -> RoughConductor {
    RoughConductor {
        distribution: Microfacet::new(kind, alpha, alpha).unwrap(),
        eta: Rgb::BLACK,
        k: Rgb::splat(1e6),
        specular_reflectance: Rgb::WHITE,
    }
}

fn lobes() -> Vec<RoughConductor> {
    let mut all = Vec::new();
    for kind in [MicrofacetKind::Ggx, MicrofacetKind::Beckmann] {
        all.push(metal(kind, 0.1, 0.1));
        all.push(metal(kind, 0.5, 0.5));
        all.push(metal(kind, 0.15, 0.6));
    }
    all
}

fn viewers() -> [DVec3; 3] {
    [DVec3::Z, direction(0.7, 0.4), direction(1.3, 2.5)]
}

/// `∫ f(ω_o, ω_i) cos θ_i dω_i` by the midpoint rule on `θ = (π/2) t²`.
fn albedo(lobe: &RoughConductor, wo: DVec3) -> Rgb {
    let n = 800;
    let mut sum = Rgb::BLACK;
    for i in 0..n {
        let t = (i as f64 + 0.5) / n as f64;
        let theta = FRAC_PI_2 * t * t;
        let weight = theta.sin() * PI * t / n as f64 * TAU / n as f64;
        for j in 0..n {
            let wi = direction(theta, (j as f64 + 0.5) / n as f64 * TAU);
            sum += lobe.eval(wo, wi) * (wi.z * weight);
        }
    }
    sum
}

#[test]
fn reciprocal() {
    for lobe in lobes() {
        for (a, b) in [(viewers()[1], viewers()[2]), (viewers()[0], viewers()[2])] {
            let (ab, ba) = (lobe.eval(a, b), lobe.eval(b, a));
            assert!((ab - ba).max_component().abs() <= 1e-12 * ab.max_component().max(1.0));
        }
    }
}

#[test]
fn white_furnace_albedo_is_at_most_one_and_near_one_when_smooth() {
    for kind in [MicrofacetKind::Ggx, MicrofacetKind::Beckmann] {
        for wo in viewers() {
            let smooth = albedo(&white(kind, 0.05), wo).g;
            let rough = albedo(&white(kind, 0.8), wo).g;
            assert!(
                smooth <= 1.0 + 2e-3 && rough <= 1.0 + 2e-3,
                "{kind:?}: {smooth} {rough}"
            );
            // Nearly smooth: single scattering keeps almost all the light
            // (less at grazing views, where masking grows).
            let floor = if wo.z > 0.5 { 0.98 } else { 0.9 };
            assert!(smooth > floor, "{kind:?} from {wo}: {smooth}");
            // Rough: multiple scattering between facets is not modelled.
            assert!(rough < smooth, "{kind:?}: {rough} vs {smooth}");
        }
    }
    // Gold absorbs blue more than red.
    let gold = albedo(&metal(MicrofacetKind::Ggx, 0.2, 0.2), DVec3::Z);
    assert!(
        gold.r > gold.g && gold.g > gold.b && gold.r < 1.0,
        "{gold:?}"
    );
}

#[test]
fn sampled_directions_follow_the_reported_density() {
    const T_BINS: usize = 16;
    const P_BINS: usize = 24;
    const SAMPLES: usize = 100_000;
    let mut rng = Pcg64::seed_from_u64(7);
    for lobe in lobes() {
        for wo in viewers() {
            let mut counts = vec![0.0f64; T_BINS * P_BINS];
            let mut kept = 0usize;
            for _ in 0..SAMPLES {
                let Some(s) = lobe.sample(wo, [rng.random(), rng.random()]) else {
                    continue;
                };
                kept += 1;
                assert!((s.pdf - lobe.pdf(wo, s.wi)).abs() <= 1e-9 * s.pdf.max(1.0));
                let t = (s.wi.z.clamp(-1.0, 1.0).acos() / FRAC_PI_2).sqrt();
                let phi = s.wi.y.atan2(s.wi.x).rem_euclid(TAU);
                let i = ((t * T_BINS as f64) as usize).min(T_BINS - 1);
                let j = ((phi / TAU * P_BINS as f64) as usize).min(P_BINS - 1);
                counts[i * P_BINS + j] += 1.0;
            }
            assert!(kept > SAMPLES / 2, "{lobe:?}: {kept}");
            let mut expected = vec![0.0f64; T_BINS * P_BINS];
            let sub = 16;
            for i in 0..T_BINS {
                for j in 0..P_BINS {
                    let mut e = 0.0;
                    for a in 0..sub {
                        let t = (i as f64 + (a as f64 + 0.5) / sub as f64) / T_BINS as f64;
                        let theta = FRAC_PI_2 * t * t;
                        let dt = 1.0 / (T_BINS * sub) as f64;
                        let dp = TAU / (P_BINS * sub) as f64;
                        for b in 0..sub {
                            let phi =
                                (j as f64 + (b as f64 + 0.5) / sub as f64) * TAU / P_BINS as f64;
                            let wi = direction(theta, phi);
                            e += lobe.pdf(wo, wi) * theta.sin() * PI * t * dt * dp;
                        }
                    }
                    expected[i * P_BINS + j] = e * SAMPLES as f64;
                }
            }
            let test = ChiSquare::of(&counts, &expected);
            assert!(test.passes(), "{lobe:?} from {wo}: {test}");
        }
    }
}

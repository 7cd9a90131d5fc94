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

fn glass(kind: MicrofacetKind, au: f64, av: f64, eta: f64) -> RoughDielectric {
    RoughDielectric {
        distribution: Microfacet::new(kind, au, av).unwrap(),
        eta,
        specular_reflectance: Rgb::WHITE,
        specular_transmittance: Rgb::WHITE,
    }
}

fn lobes() -> Vec<RoughDielectric> {
    let mut all = Vec::new();
    for kind in [MicrofacetKind::Ggx, MicrofacetKind::Beckmann] {
        all.push(glass(kind, 0.1, 0.1, 1.5));
        all.push(glass(kind, 0.4, 0.4, 1.33));
        all.push(glass(kind, 0.15, 0.5, 1.5));
    }
    all
}

/// Views from outside and from inside the interface.
fn viewers() -> [DVec3; 4] {
    [
        DVec3::Z,
        direction(0.9, 0.4),
        direction(PI - 0.3, 1.0),
        direction(PI - 1.1, -2.0),
    ]
}

/// Index of the medium a direction lies in (outside 1, inside `eta`).
fn index(lobe: &RoughDielectric, w: DVec3) -> f64 {
    if w.z > 0.0 { 1.0 } else { lobe.eta }
}

/// `∫ g(ω_i) dω_i` over the sphere, midpoint rule on each hemisphere with
/// `θ = (π/2) t²` from its pole.
fn over_sphere(g: &dyn Fn(DVec3) -> f64, n: usize) -> f64 {
    let mut sum = 0.0;
    for i in 0..n {
        let t = (i as f64 + 0.5) / n as f64;
        let theta = FRAC_PI_2 * t * t;
        let weight = theta.sin() * PI * t / n as f64 * TAU / n as f64;
        for j in 0..n {
            let w = direction(theta, (j as f64 + 0.5) / n as f64 * TAU);
            sum += (g(w) + g(DVec3::new(w.x, w.y, -w.z))) * weight;
        }
    }
    sum
}

#[test]
fn generalised_reciprocity_holds() {
    for lobe in lobes() {
        let v = viewers();
        for (a, b) in [(v[1], v[2]), (v[0], v[3]), (v[1], v[0]), (v[2], v[3])] {
            let left = lobe.eval(a, b).g / index(&lobe, a).powi(2);
            let right = lobe.eval(b, a).g / index(&lobe, b).powi(2);
            assert!(
                (left - right).abs() <= 1e-10 * left.abs().max(1e-6),
                "{lobe:?}: {a} {b}: {left} vs {right}"
            );
        }
    }
}

#[test]
fn energy_is_conserved_up_to_multiple_scattering() {
    // Importance is what a lossless interface conserves: weighting the
    // transmitted part by (n_i/n_o)² undoes the radiance convention's 1/η'².
    // Single scattering drops light that would bounce between facets, most
    // from inside a rough interface (steep facets reflect totally, then
    // downwards), so only the nearly smooth interface must keep it all.
    for kind in [MicrofacetKind::Ggx, MicrofacetKind::Beckmann] {
        for wo in viewers() {
            let albedo = |alpha: f64| {
                let lobe = glass(kind, alpha, alpha, 1.5);
                over_sphere(
                    &|wi| {
                        let scale = (index(&lobe, wi) / index(&lobe, wo)).powi(2);
                        lobe.eval(wo, wi).g * wi.z.abs() * scale
                    },
                    600,
                )
            };
            let (smooth, rough) = (albedo(0.05), albedo(0.5));
            assert!(
                smooth <= 1.0 + 3e-3 && smooth > 0.985,
                "{kind:?} α 0.05 from {wo}: {smooth}"
            );
            assert!(
                rough <= smooth + 1e-3 && rough > 0.5,
                "{kind:?} α 0.5 from {wo}: {rough}"
            );
        }
    }
}

#[test]
fn light_inside_beyond_the_critical_angle_is_reflected() {
    let lobe = glass(MicrofacetKind::Ggx, 0.01, 0.01, 1.5);
    let wo = direction(PI - 1.2, 0.0); // 69° from the inward normal, past 41.8°
    let mut rng = Pcg64::seed_from_u64(3);
    for _ in 0..1000 {
        if let Some(s) = lobe.sample(wo, rng.random(), [rng.random(), rng.random()]) {
            assert!(s.wi.z < 0.0, "{:?}", s.wi);
        }
    }
}

#[test]
fn sampled_directions_follow_the_reported_density() {
    // Bins: each hemisphere in t = √(θ'/(π/2)) from its pole, and φ.
    const T_BINS: usize = 12;
    const P_BINS: usize = 16;
    const SAMPLES: usize = 100_000;
    let bin = |w: DVec3| {
        let lower = usize::from(w.z < 0.0);
        let theta = w.z.abs().min(1.0).acos();
        let t = (theta / FRAC_PI_2).sqrt();
        let phi = w.y.atan2(w.x).rem_euclid(TAU);
        let i = ((t * T_BINS as f64) as usize).min(T_BINS - 1);
        let j = ((phi / TAU * P_BINS as f64) as usize).min(P_BINS - 1);
        (lower * T_BINS + i) * P_BINS + j
    };
    let mut rng = Pcg64::seed_from_u64(11);
    for lobe in lobes() {
        for wo in viewers() {
            let mut counts = vec![0.0f64; 2 * T_BINS * P_BINS];
            for _ in 0..SAMPLES {
                let Some(s) = lobe.sample(wo, rng.random(), [rng.random(), rng.random()]) else {
                    continue;
                };
                assert!((s.pdf - lobe.pdf(wo, s.wi)).abs() <= 1e-9 * s.pdf.max(1.0));
                counts[bin(s.wi)] += 1.0;
            }
            let mut expected = vec![0.0f64; 2 * T_BINS * P_BINS];
            let sub = 12;
            for lower in 0..2 {
                for i in 0..T_BINS {
                    for j in 0..P_BINS {
                        let mut e = 0.0;
                        for a in 0..sub {
                            let t = (i as f64 + (a as f64 + 0.5) / sub as f64) / T_BINS as f64;
                            let theta = FRAC_PI_2 * t * t;
                            let dt = 1.0 / (T_BINS * sub) as f64;
                            let dp = TAU / (P_BINS * sub) as f64;
                            for b in 0..sub {
                                let phi = (j as f64 + (b as f64 + 0.5) / sub as f64) * TAU
                                    / P_BINS as f64;
                                let mut w = direction(theta, phi);
                                if lower == 1 {
                                    w.z = -w.z;
                                }
                                e += lobe.pdf(wo, w) * theta.sin() * PI * t * dt * dp;
                            }
                        }
                        expected[(lower * T_BINS + i) * P_BINS + j] = e * SAMPLES as f64;
                    }
                }
            }
            let test = ChiSquare::of(&counts, &expected);
            assert!(test.passes(), "{lobe:?} from {wo}: {test}");
        }
    }
}

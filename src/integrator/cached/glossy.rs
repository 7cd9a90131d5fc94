//! BMC with the Phong density for glossy reflection (docs/math.md §13).
//!
//! θ_r is tabulated and the weights interpolated.
//! The Phong density depends on the mirror direction's polar angle `θ_r`
//! once the sample set is turned about the normal to put the mirror
//! direction at azimuth 0 (docs/math.md §4; `Q` is unchanged by the turn).
//! Kernel means for one `θ_r` cost milliseconds each and `V₀` up to seconds
//! (docs/BENCHMARKS.md), so they cannot be computed per point. We compute
//! exact quadratures at `bins` equally spaced nodes `θ_k = k (π/2)/(bins−1)`
//! (kept in a [`QuadratureCache`]) and interpolate **linearly in `θ_r`
//! between the two neighbouring nodes**. Weights are linear in the kernel
//! means (`w = Q⁻¹z` plus the GLS term, also linear in `z`), so this equals
//! exact BMC with linearly interpolated kernel means: the error is
//! `O(h² ∂²z/∂θ_r²)` for node spacing `h`, and `Σ w = ∫p` is interpolated
//! the same way. The test `interpolated_glossy_weights_match_the_exact_rule`
//! measures it (module tests; figure in docs/BENCHMARKS.md). Exponents above
//! [`super::MAX_BMC_EXPONENT`] (near-mirror lobes a hemisphere sample set cannot
//! resolve) fall back to one Phong-lobe-sampled path per shading.
//!
//! The Phong rules have negative weights (with the default rule, for
//! `m = 80` and `400`, their magnitudes add up to 0.2 to 1.7 times `∫p` for
//! `θ_r ≤ 1.4`, more towards grazing), so a value far above the others on a
//! negatively weighted direction can make `Σ w_i L_i` negative.
//! [`GlossyWeights::estimate`] applies the negative-weight guard of
//! docs/math.md §3.6 to the traced values; the shading replaces a rejected
//! estimate by [`lobe_sampled`] paths (docs/math.md §13.3), unbiased and
//! non-negative, with their variance. The fixed directions cannot serve
//! that rule themselves: a lobe of `m = 400` is about 0.05 rad wide, the
//! directions about 0.3 rad apart.

use std::f64::consts::FRAC_PI_2;
use std::sync::Arc;

use glam::DVec3;
use rand::{Rng, RngExt};

use crate::bmc::cache::QuadratureCache;
use crate::bmc::{Density, KernelMeanMethod};
use crate::cache::{CacheError, RecordRuleSpec};
use crate::optics::warp;
use crate::render::strata::GridStrata;
use crate::render::{Evaluation, RadianceSample, Rgb};
use crate::sphere::Frame;
use crate::stats::RunningMean;

/// Largest accepted number of `θ_r` nodes of the glossy rule.
pub const MAX_GLOSSY_BINS: usize = 1024;

/// BMC with the Phong density, tabulated over `θ_r` (module docs).
pub struct GlossyRule {
    spec: RecordRuleSpec,
    bins: usize,
    quadratures: Arc<QuadratureCache>,
}

/// Interpolated glossy weights for one `(m, θ_r)`.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyWeights {
    /// Local-frame directions (mirror direction at azimuth 0).
    pub directions: Arc<[DVec3]>,
    /// `Î = Σ w_i L_i ≈ ∫ L p`.
    pub weights: Vec<f64>,
    /// Interpolated posterior variance of `Î` for the kernel's `σ²`.
    pub posterior_variance: f64,
}

impl GlossyWeights {
    /// `Î = Σ w_i L_i` for the radiance `samples` traced along `directions`
    /// (in order), units of `L`; `None` where a channel of it is negative,
    /// which no non-negative radiance allows: the negative-weight guard of
    /// docs/math.md §3.6.
    pub fn estimate(&self, samples: &[RadianceSample]) -> Option<Rgb> {
        let sum: Rgb = samples
            .iter()
            .zip(&self.weights)
            .map(|(s, w)| s.radiance * *w)
            .sum();
        let negative = sum.r < 0.0 || sum.g < 0.0 || sum.b < 0.0;
        (!negative).then_some(sum)
    }
}

impl GlossyRule {
    /// `bins ≥ 2` nodes over `θ_r ∈ [0, π/2]`; quadratures live in `quadratures`.
    pub fn new(
        spec: RecordRuleSpec,
        bins: usize,
        quadratures: Arc<QuadratureCache>,
    ) -> Result<Self, CacheError> {
        if !(2..=MAX_GLOSSY_BINS).contains(&bins) {
            return Err(CacheError::invalid(
                "glossy_bins",
                format!("must be in 2..={MAX_GLOSSY_BINS}, got {bins}"),
            ));
        }
        spec.kernel.validate()?;
        Ok(Self {
            spec,
            bins,
            quadratures,
        })
    }

    /// Weights for exponent `m` and mirror polar angle `θ_r` (clamped to
    /// `[0, π/2]`), linear in `θ_r` between the two neighbouring nodes.
    pub fn weights(&self, exponent: f64, theta_r: f64) -> Result<GlossyWeights, CacheError> {
        let step = FRAC_PI_2 / (self.bins - 1) as f64;
        let t = (theta_r.clamp(0.0, FRAC_PI_2) / step).max(0.0);
        let k = (t.floor() as usize).min(self.bins - 2);
        let f = (t - k as f64).clamp(0.0, 1.0);
        let node = |k: usize| {
            let density = Density::Phong {
                exponent,
                mirror_elevation: (k as f64 * step).min(FRAC_PI_2),
            };
            self.quadratures
                .quadrature(
                    self.spec.samples,
                    &self.spec.kernel,
                    &density,
                    self.spec.prior_mean,
                    KernelMeanMethod::Exact,
                )
                .map(|(q, _)| q)
        };
        let (a, b) = (node(k)?, node(k + 1)?);
        let weights = a
            .quadrature
            .weights
            .iter()
            .zip(&b.quadrature.weights)
            .map(|(wa, wb)| (1.0 - f) * wa + f * wb)
            .collect();
        let posterior_variance =
            (1.0 - f) * a.quadrature.posterior_variance + f * b.quadrature.posterior_variance;
        Ok(GlossyWeights {
            directions: a.directions().into(),
            weights,
            posterior_variance,
        })
    }
}

/// `∫ L p dω` for the Phong density of exponent `m` about the unit mirror
/// direction `mirror` (local frame, z = normal) by `n ≥ 1` directions drawn
/// from the lobe `(m+1)/(2π) cos^m α` about it, the unit square stratified
/// on a near-square grid of `n` cells, each term `L (m+2)/(m+1) cos θ`
/// (`p/q`, 0 below the horizon; docs/math.md §13.2, §13.3); `radiance`
/// gives `L` (units of `L`) along a local direction. Returns the mean of the
/// terms, unbiased and non-negative for non-negative `L`, and for `n ≥ 2`
/// the sample variance of the terms over `n` (an upper bound in expectation
/// for stratified directions); zero for `n = 1`, whose spread is unknown.
pub fn lobe_sampled<R: Rng + ?Sized>(
    m: f64,
    mirror: DVec3,
    n: u32,
    rng: &mut R,
    mut radiance: impl FnMut(DVec3, &mut R) -> Rgb,
) -> Evaluation {
    let lobe = Frame::from_normal(mirror);
    let grid = GridStrata::new(n);
    let mut terms = RunningMean::new();
    for j in 0..n.max(1) {
        let u = grid.sample(j, [rng.random(), rng.random()]);
        let wi = lobe.to_world(warp::power_cosine(u, m));
        if wi.z <= 0.0 {
            terms.push(Rgb::BLACK);
            continue;
        }
        // p / q = (m+2)/(2π) cos^m α cos θ / ((m+1)/(2π) cos^m α).
        terms.push(radiance(wi, rng) * ((m + 2.0) / (m + 1.0) * wi.z));
    }
    Evaluation {
        value: terms.mean(),
        variance: terms.variance_of_mean().unwrap_or(Rgb::BLACK),
        shared: Rgb::BLACK,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::cached::default_rule_spec;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;
    use std::f64::consts::TAU;

    /// `Î` of the smooth field `1 + 0.5 x + 0.3 z` (local frame).
    fn integral(directions: &[DVec3], weights: &[f64]) -> f64 {
        directions
            .iter()
            .zip(weights)
            .map(|(d, w)| w * (1.0 + 0.5 * d.x + 0.3 * d.z))
            .sum()
    }

    /// Interpolated weights are the node rules at the nodes and converge to
    /// the exact rule at second order in the node spacing between them.
    #[test]
    fn interpolated_glossy_weights_match_the_exact_rule() {
        let quadratures = Arc::new(QuadratureCache::new(1 << 24));
        let mut spec = default_rule_spec();
        spec.samples.count = 16;
        let (m, theta) = (20.0, 0.6);
        let exact = |theta_r: f64| {
            let density = Density::Phong {
                exponent: m,
                mirror_elevation: theta_r,
            };
            let (q, _) = quadratures
                .quadrature(
                    spec.samples,
                    &spec.kernel,
                    &density,
                    spec.prior_mean,
                    KernelMeanMethod::Exact,
                )
                .unwrap();
            integral(q.directions(), &q.quadrature.weights)
        };
        let coarse = GlossyRule::new(spec, 5, quadratures.clone()).unwrap();
        let fine = GlossyRule::new(spec, 9, quadratures.clone()).unwrap();
        let node = 2.0 * FRAC_PI_2 / 8.0;
        let at_node = fine.weights(m, node).unwrap();
        assert!((integral(&at_node.directions, &at_node.weights) - exact(node)).abs() < 1e-12);
        let truth = exact(theta);
        let err = |rule: &GlossyRule| {
            let w = rule.weights(m, theta).unwrap();
            (integral(&w.directions, &w.weights) - truth).abs() / truth
        };
        let (e_coarse, e_fine) = (err(&coarse), err(&fine));
        assert!(e_fine < 0.4 * e_coarse, "{e_fine} vs {e_coarse}");
        assert!(e_fine < 0.05, "{e_fine}");
        assert_eq!(
            GlossyRule::new(spec, 1, quadratures).err().unwrap().field(),
            Some("glossy_bins")
        );
    }

    fn default_rule() -> GlossyRule {
        let quadratures = Arc::new(QuadratureCache::new(1 << 26));
        GlossyRule::new(default_rule_spec(), 16, quadratures).unwrap()
    }

    /// The smooth field of [`integral`] and a grey level, as radiance.
    fn smooth(d: DVec3) -> Rgb {
        Rgb::WHITE * (1.0 + 0.5 * d.x + 0.3 * d.z)
    }

    fn samples_of(directions: &[DVec3], field: impl Fn(DVec3) -> Rgb) -> Vec<RadianceSample> {
        directions
            .iter()
            .map(|&d| RadianceSample {
                radiance: field(d),
                ..RadianceSample::NONE
            })
            .collect()
    }

    /// `∫ f p dω` for the Phong density about `mirror` by a fine midpoint
    /// rule in the lobe's polar coordinates `(α, φ)`, `α ≤ 0.6` (beyond it
    /// `cos^m α < 10⁻³⁰` for `m = 400`).
    fn lobe_integral(m: f64, mirror: DVec3, f: impl Fn(DVec3) -> f64) -> f64 {
        let lobe = Frame::from_normal(mirror);
        let (na, nf, alpha_max) = (1500, 720, 0.6);
        let (da, df) = (alpha_max / na as f64, TAU / nf as f64);
        let mut sum = 0.0;
        for i in 0..na {
            let a = (i as f64 + 0.5) * da;
            let weight = (m + 2.0) / TAU * a.cos().powf(m) * a.sin() * da * df;
            for j in 0..nf {
                let phi = (j as f64 + 0.5) * df;
                let local = DVec3::new(a.sin() * phi.cos(), a.sin() * phi.sin(), a.cos());
                let w = lobe.to_world(local);
                sum += weight * w.z.max(0.0) * f(w);
            }
        }
        sum
    }

    /// A spike (a sunlit highlight seen through one direction) under the
    /// most negative weight of the gold box's rule (`m = 400`, `θ_r = 1.02`,
    /// where its tile showed the hole) drives the BMC sum negative; the
    /// guard rejects it, and lobe sampling, which the spike far outside the
    /// lobe cannot reach, gives the true integral within its reported error.
    /// Without the spike the BMC sum is kept as it was, bit for bit.
    #[test]
    fn a_spike_under_a_negative_weight_falls_back_to_lobe_sampling() {
        let (m, theta_r) = (400.0, 1.02);
        let w = default_rule().weights(m, theta_r).unwrap();
        let negative: f64 = w.weights.iter().filter(|w| **w < 0.0).sum();
        assert!(negative < -0.2, "{negative}");
        let mirror = DVec3::new(theta_r.sin(), 0.0, theta_r.cos());
        let (k, &most_negative) = w
            .weights
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .unwrap();
        let spike_dir = w.directions[k];
        assert!(most_negative < 0.0);
        assert!(spike_dir.angle_between(mirror) > 0.5, "{spike_dir}");
        // Radiance 60 in a cone of 0.05 rad about that direction.
        let field = |d: DVec3| {
            let spike = if d.angle_between(spike_dir) < 0.05 {
                60.0
            } else {
                0.0
            };
            smooth(d) + Rgb::WHITE * spike
        };
        let sum = |samples: &[RadianceSample]| -> Rgb {
            samples
                .iter()
                .zip(&w.weights)
                .map(|(s, w)| s.radiance * *w)
                .sum()
        };
        let spiked = samples_of(&w.directions, field);
        assert!(sum(&spiked).r < 0.0, "{:?}", sum(&spiked));
        assert_eq!(w.estimate(&spiked), None);
        let truth = lobe_integral(m, mirror, |d| smooth(d).r);
        // Without the spike BMC is kept, unchanged, and right.
        let plain = samples_of(&w.directions, smooth);
        let kept = w.estimate(&plain).unwrap();
        assert_eq!(kept, sum(&plain));
        assert!((kept.r - truth).abs() < 0.05 * truth, "{kept:?} vs {truth}");
        // The fallback: as many lobe directions as the rule has.
        let mut rng = Pcg64::seed_from_u64(3);
        let n = w.directions.len() as u32;
        let fallback = lobe_sampled(m, mirror, n, &mut rng, |d, _| field(d));
        let (value, se) = (fallback.value.r, fallback.variance.r.sqrt());
        assert!(value >= 0.0 && se > 0.0, "{fallback:?}");
        assert!(
            (value - truth).abs() < 4.0 * se,
            "{value} ± {se} vs {truth}"
        );
        // One direction reports no spread.
        let one = lobe_sampled(m, mirror, 1, &mut rng, |d, _| field(d));
        assert_eq!(one.variance, Rgb::BLACK);
    }
}

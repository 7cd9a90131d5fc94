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

use std::f64::consts::FRAC_PI_2;
use std::sync::Arc;

use glam::DVec3;

use crate::bmc::cache::QuadratureCache;
use crate::bmc::{Density, KernelMeanMethod};
use crate::cache::{CacheError, RecordRuleSpec};

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::cached::default_rule_spec;

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
}

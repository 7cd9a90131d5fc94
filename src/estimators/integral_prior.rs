//! A Gaussian prior on a part of a point's estimate, the indirect part
//! (docs/math.md §10.7) or the direct part (§10.8), and its combination
//! with a rule's estimate.
//!
//! The rule's estimate `Ĥ` with variance `s²` is read as the likelihood of
//! the integral `H`; a prior `N(m, v)` on `H` from what the service already
//! knows (the irradiance cache's records or their direct-light twins,
//! `cache::RecordsPrior`) gives the
//! posterior `N((Ĥ/s² + m/v)/(1/s² + 1/v), 1/(1/s² + 1/v))` per channel.
//! As samples grow, `s² → 0` and the posterior mean tends to `Ĥ`: the prior
//! moves a finite-sample estimate, never the limit.

use crate::render::QueryPoint;
use crate::render::Rgb;
use crate::render::{IndirectPart, IrradianceEstimate};

/// A prior at one point: its mean and variance per channel, W/m² and
/// (W/m²)², the variance in two parts: what was measured at the point
/// (`variance`) and what a scene-wide model states (`modelled`), which the
/// scale fitted on the scene multiplies (docs/math.md §10.9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorAt {
    pub mean: Rgb,
    pub variance: Rgb,
    pub modelled: Rgb,
    /// Rays traced at the point to state the prior (its shadow probe,
    /// §10.8), which the estimate it moves counts.
    pub rays: u64,
}

impl PriorAt {
    /// Mean and variance with the modelled part scaled by `scale`.
    pub fn scaled(self, scale: f64) -> (Rgb, Rgb) {
        (self.mean, self.variance + self.modelled * scale)
    }

    /// The variance with the modelled part as stated.
    pub fn stated_variance(self) -> Rgb {
        self.variance + self.modelled
    }
}

/// A prior on a part of the irradiance at a point (indirect or direct),
/// W/m², when one is known.
pub trait IntegralPrior: Sync {
    /// The prior at `point`, or `None`.
    fn at(&self, point: &QueryPoint) -> Option<PriorAt>;

    /// A coarse summary of what the prior knows, which changes when it
    /// learns much more (e.g. `⌊log₂⌋` of the records it holds): error bars
    /// calibrated with the prior (docs/math.md §10.5) are fitted again when
    /// it changes.
    fn state(&self) -> u64;
}

/// Multipliers of the priors' variances `v`, fitted with the error bars on
/// the scene's training points (docs/math.md §10.9): the held-out error that
/// `v` holds is measured where records stood, farther from the others than a
/// query point usually is from the nearest, so `v` can be several times too
/// wide, and the weights of the combination with it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PriorScales {
    /// Of the indirect part's prior (the records, §10.7).
    pub records: f64,
    /// Of the direct part's prior (the direct-light records, §10.8).
    pub direct: f64,
}

impl PriorScales {
    /// The priors' variances as they state them.
    pub const ONE: Self = Self {
        records: 1.0,
        direct: 1.0,
    };

    /// The candidates tried by the fit: variance multipliers `4ᵏ`,
    /// `k = −2 … 1`, the stated variance first. Smaller ones (down to
    /// 4⁻⁴) were tried: the fit on camera-seen training points chose 4⁻³
    /// for the overcast scene's twins, which made error bars too narrow at
    /// points unlike those (rms z 1.50 on the environment light of issue
    /// 39's points, 1.37 with 4⁻² the least; docs/math.md §10.9).
    pub const CANDIDATES: [f64; 4] = [1.0, 1.0 / 16.0, 0.25, 4.0];
}

/// How many standard deviations of their difference a direct part and its
/// prior may be apart before the prior is taken to be wrong at the point
/// (docs/math.md §10.8, prior-data conflict): if both were right, a larger
/// gap would happen once in 370.
pub const CONFLICT_SIGMAS: f64 = 3.0;

/// The posterior of `estimate` (value, variance per channel) under the
/// prior `(mean, variance)` (module docs). A channel whose estimate or
/// prior has no positive variance keeps the estimate: a zero variance states
/// no uncertainty to weigh (all sample values equal), not certainty.
pub fn combine(estimate: (Rgb, Rgb), prior: (Rgb, Rgb)) -> (Rgb, Rgb) {
    let (value, variance) = (estimate.0.to_array(), estimate.1.to_array());
    let (mean, prior_variance) = (prior.0.to_array(), prior.1.to_array());
    let mut out = (value, variance);
    for c in 0..3 {
        let (s2, v) = (variance[c], prior_variance[c]);
        if s2 > 0.0 && v > 0.0 && s2.is_finite() && v.is_finite() && mean[c].is_finite() {
            let precision = 1.0 / s2 + 1.0 / v;
            out.0[c] = (value[c] / s2 + mean[c] / v) / precision;
            out.1[c] = 1.0 / precision;
        }
    }
    (Rgb::from_array(out.0), Rgb::from_array(out.1))
}

/// `estimate` under `prior`, a prior on its indirect part (an estimate that
/// reports none is left as it is, and `false` returned): the part is
/// combined by [`combine`] with its share of the estimate's variance
/// ([`IndirectPart::variance_share`]), the total moves by what the part
/// moved, and the rest of the variance stays beside the part's posterior
/// variance. The share is of the estimate's variance as
/// stated (calibrated, §10.5, by default), since calibration is fitted on
/// the total, not on its parts.
pub fn combine_part(estimate: &mut IrradianceEstimate, prior: (Rgb, Rgb)) -> bool {
    let Some(part) = estimate.indirect else {
        return false;
    };
    let moved = move_part(estimate, part.irradiance, part.variance_share, prior, false);
    estimate.indirect = Some(IndirectPart {
        irradiance: moved.posterior,
        variance_share: share(moved.posterior_variance, moved.total),
    });
    true
}

/// `estimate` under `prior`, a prior on its direct part: the estimate less
/// its indirect part, or all of it where it reports none, as direct-light
/// records hold it (docs/math.md §10.8); a prior in conflict with the part
/// is left out ([`in_conflict`]). So an estimate with reflections
/// must report its indirect part (estimators do with the records prior);
/// one that reports none is taken to be of direct light only. The part is
/// combined as in [`combine_part`], with the share of the variance that is
/// not the indirect part's, and the indirect part keeps its own variance,
/// now a share of the smaller total. Light the rule's samples may all have
/// missed ([`IrradianceEstimate::unseen_light`]) is missing from the
/// combination only with the rule's weight in the part, its posterior
/// variance over the part's (docs/math.md §10.5, §10.8). Returns whether the
/// prior was combined (`false`: in conflict, the estimate left as it was).
pub fn combine_direct(estimate: &mut IrradianceEstimate, prior: (Rgb, Rgb)) -> bool {
    let (indirect, indirect_share) = match estimate.indirect {
        Some(part) => (part.irradiance, part.variance_share),
        None => (Rgb::BLACK, Rgb::BLACK),
    };
    let direct_share = indirect_share.map(|s| 1.0 - s);
    let moved = move_part(
        estimate,
        estimate.irradiance - indirect,
        direct_share,
        prior,
        true,
    );
    if let Some(part) = estimate.indirect.as_mut() {
        part.variance_share = share(moved.rest, moved.total);
    }
    if moved.combined {
        let weight = share(moved.posterior_variance, moved.part_variance).to_array();
        estimate.unseen_light = std::array::from_fn(|c| estimate.unseen_light[c] * weight[c]);
    }
    moved.combined
}

/// What [`move_part`] did: whether it combined the prior at all, the
/// part's variance before, its posterior mean and variance, the rest of the
/// estimate's variance and the new total variance, per channel.
struct Moved {
    combined: bool,
    part_variance: Rgb,
    posterior: Rgb,
    posterior_variance: Rgb,
    rest: Rgb,
    total: Rgb,
}

/// Whether `part` of an estimate whose variance is `variance` and `prior`
/// are more than [`CONFLICT_SIGMAS`] standard deviations apart in any
/// channel, the deviation the estimate's whole variance and the prior's
/// (docs/math.md §10.8): the whole, not the part's share, because the share
/// comes from the rule's own model variances, which calibration does not
/// correct, and a share too small would call agreeing values a conflict.
fn in_conflict(part: Rgb, variance: Rgb, prior: (Rgb, Rgb)) -> bool {
    let (part, variance) = (part.to_array(), variance.to_array());
    let (mean, prior_variance) = (prior.0.to_array(), prior.1.to_array());
    (0..3).any(|c| {
        let spread = variance[c] + prior_variance[c];
        spread > 0.0 && (part[c] - mean[c]).powi(2) > CONFLICT_SIGMAS.powi(2) * spread
    })
}

/// Combines `part` of `estimate`, which has `part_share` of its variance,
/// with `prior`, and moves the total by what the part moved; the rest of the
/// variance stays beside the part's posterior variance. With
/// `check_conflict`, a prior in conflict with the part ([`in_conflict`])
/// leaves the estimate as it is.
fn move_part(
    estimate: &mut IrradianceEstimate,
    part: Rgb,
    part_share: Rgb,
    prior: (Rgb, Rgb),
    check_conflict: bool,
) -> Moved {
    let variance = estimate.std_error * estimate.std_error;
    let part_variance = variance * part_share;
    let rest = (variance - part_variance).map(|v| v.max(0.0));
    if check_conflict && in_conflict(part, variance, prior) {
        return Moved {
            combined: false,
            part_variance,
            posterior: part,
            posterior_variance: part_variance,
            rest,
            total: variance,
        };
    }
    let (posterior, posterior_variance) = combine((part, part_variance), prior);
    estimate.irradiance += posterior - part;
    let total = posterior_variance + rest;
    estimate.std_error = total.map(f64::sqrt);
    Moved {
        combined: true,
        part_variance,
        posterior,
        posterior_variance,
        rest,
        total,
    }
}

/// `of / total` per channel, 1 where the total is zero.
pub(crate) fn share(of: Rgb, total: Rgb) -> Rgb {
    Rgb::from_array(std::array::from_fn(|c| {
        let (p, t) = (of.to_array()[c], total.to_array()[c]);
        if t > 0.0 { p / t } else { 1.0 }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precision_weighting_per_channel() {
        let estimate = (Rgb::new(1.0, 2.0, 3.0), Rgb::new(1.0, 4.0, 0.0));
        let prior = (Rgb::new(3.0, 2.0, 9.0), Rgb::new(1.0, 1.0, 1.0));
        let (value, variance) = combine(estimate, prior);
        // Equal variances: the midpoint, half the variance.
        assert_eq!(value.r, 2.0);
        assert_eq!(variance.r, 0.5);
        // Same mean: unchanged value, variance 1/(1/4 + 1) = 0.8.
        assert_eq!(value.g, 2.0);
        assert!((variance.g - 0.8).abs() < 1e-15);
        // No variance on the estimate's side: the estimate is kept.
        assert_eq!((value.b, variance.b), (3.0, 0.0));
        // A prior without variance is not taken as certainty.
        let (kept, _) = combine(estimate, (Rgb::new(5.0, 5.0, 5.0), Rgb::BLACK));
        assert_eq!(kept, estimate.0);
    }

    #[test]
    fn a_prior_on_the_part_moves_the_total_by_what_the_part_moved() {
        let mut estimate = IrradianceEstimate {
            irradiance: Rgb::splat(5.0),
            std_error: Rgb::splat(1.0),
            rays: 7,
            indirect: Some(IndirectPart::whole(Rgb::splat(2.0))),
            unseen_light: [0.0; 3],
            direct_strata: None,
        };
        assert!(combine_part(
            &mut estimate,
            (Rgb::splat(4.0), Rgb::splat(1.0))
        ));
        // Part: (2 + 4)/2 = 3 with variance ½; the direct 3 is kept.
        assert_eq!(estimate.irradiance, Rgb::splat(6.0));
        assert_eq!(
            estimate.indirect,
            Some(IndirectPart::whole(Rgb::splat(3.0)))
        );
        assert!((estimate.std_error.r - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(estimate.rays, 7);
        // Without an indirect part there is nothing to combine.
        let mut direct_only = IrradianceEstimate {
            indirect: None,
            ..estimate
        };
        assert!(!combine_part(
            &mut direct_only,
            (Rgb::splat(100.0), Rgb::splat(1.0))
        ));
        assert_eq!(direct_only.irradiance, Rgb::splat(6.0));
    }

    #[test]
    fn the_part_weighs_its_share_of_the_variance_and_keeps_the_rest() {
        let mut estimate = IrradianceEstimate {
            irradiance: Rgb::splat(5.0),
            std_error: Rgb::splat(2.0),
            rays: 7,
            indirect: Some(IndirectPart {
                irradiance: Rgb::splat(2.0),
                variance_share: Rgb::splat(0.25),
            }),
            unseen_light: [0.0; 3],
            direct_strata: None,
        };
        combine_part(&mut estimate, (Rgb::splat(4.0), Rgb::splat(1.0)));
        // The part's variance is ¼ · 4 = 1: the midpoint 3 with variance ½,
        // beside the other 3 of the whole's 4.
        assert_eq!(estimate.irradiance, Rgb::splat(6.0));
        assert!((estimate.std_error.g - 3.5f64.sqrt()).abs() < 1e-15);
        let part = estimate.indirect.unwrap();
        assert_eq!(part.irradiance, Rgb::splat(3.0));
        assert!((part.variance_share.b - 0.5 / 3.5).abs() < 1e-15);
    }

    #[test]
    fn a_prior_on_the_direct_part_leaves_the_indirect_part_as_it_was() {
        let mut estimate = IrradianceEstimate {
            irradiance: Rgb::splat(5.0),
            std_error: Rgb::splat(2.0),
            rays: 7,
            indirect: Some(IndirectPart {
                irradiance: Rgb::splat(2.0),
                variance_share: Rgb::splat(0.25),
            }),
            unseen_light: [0.0; 3],
            direct_strata: None,
        };
        combine_direct(&mut estimate, (Rgb::splat(5.0), Rgb::splat(3.0)));
        // Direct part 3 with variance ¾ · 4 = 3 against the prior 5 with 3:
        // the midpoint 4 with variance 1.5, beside the indirect part's 1.
        assert!((estimate.irradiance.r - 6.0).abs() < 1e-12);
        assert!((estimate.std_error.r - 2.5f64.sqrt()).abs() < 1e-15);
        let part = estimate.indirect.unwrap();
        assert_eq!(part.irradiance, Rgb::splat(2.0));
        assert!((part.variance_share.g - 1.0 / 2.5).abs() < 1e-15);
        // Direct light only: the whole estimate is the part.
        let mut direct_only = IrradianceEstimate {
            irradiance: Rgb::splat(1.0),
            std_error: Rgb::splat(1.0),
            rays: 7,
            indirect: None,
            unseen_light: [0.0; 3],
            direct_strata: None,
        };
        combine_direct(&mut direct_only, (Rgb::splat(3.0), Rgb::splat(1.0)));
        assert!((direct_only.irradiance.g - 2.0).abs() < 1e-12);
        assert!((direct_only.std_error.b - 0.5f64.sqrt()).abs() < 1e-15);
    }

    /// Light every direction of the rule missed is missing from a
    /// combination only as far as the rule still weighs in its direct part
    /// (docs/math.md §10.5); the records' prior on the indirect part leaves
    /// the direct part, and the weight, to the rule.
    #[test]
    fn a_direct_prior_takes_over_the_light_the_rule_may_have_missed() {
        let rule = IrradianceEstimate {
            irradiance: Rgb::splat(5.0),
            std_error: Rgb::splat(2.0),
            rays: 64,
            indirect: Some(IndirectPart {
                irradiance: Rgb::splat(2.0),
                variance_share: Rgb::splat(0.25),
            }),
            unseen_light: [1.0, 1.0, 0.0],
            direct_strata: None,
        };
        // The direct part's variance is ¾ · 4 = 3; a prior with 1 weighs
        // three times the rule there, which keeps a quarter.
        let mut estimate = rule;
        assert!(combine_direct(
            &mut estimate,
            (Rgb::splat(3.0), Rgb::splat(1.0))
        ));
        assert!((estimate.unseen_light[0] - 0.25).abs() < 1e-15);
        assert_eq!(estimate.unseen_light[2], 0.0);
        let mut estimate = rule;
        assert!(combine_part(
            &mut estimate,
            (Rgb::splat(2.0), Rgb::splat(1.0))
        ));
        assert_eq!(estimate.unseen_light, rule.unseen_light);
        // A prior without variance is not taken: the rule keeps it all.
        let mut estimate = rule;
        combine_direct(&mut estimate, (Rgb::splat(3.0), Rgb::BLACK));
        assert_eq!(estimate.unseen_light, rule.unseen_light);
    }

    #[test]
    fn the_estimate_dominates_as_its_variance_vanishes() {
        let prior = (Rgb::new(10.0, 10.0, 10.0), Rgb::new(0.01, 0.01, 0.01));
        let (far, _) = combine((Rgb::new(1.0, 1.0, 1.0), Rgb::new(1.0, 1.0, 1.0)), prior);
        let (near, _) = combine((Rgb::new(1.0, 1.0, 1.0), Rgb::new(1e-8, 1e-8, 1e-8)), prior);
        assert!(far.r > 9.0);
        assert!((near.r - 1.0).abs() < 1e-5);
    }

    /// A prior the point's own estimate contradicts beyond three standard
    /// deviations (the estimate's whole variance and the prior's), in any
    /// channel, is not combined; within them it weighs as before.
    #[test]
    fn a_prior_in_conflict_with_the_estimate_is_left_out() {
        // Direct light only: the whole estimate is the part, 5.5 ± 0.5.
        let estimate = IrradianceEstimate {
            irradiance: Rgb::new(5.5, 5.0, 4.0),
            std_error: Rgb::splat(0.5),
            rays: 64,
            indirect: None,
            unseen_light: [0.0; 3],
            direct_strata: None,
        };
        // The twin of a record in a shadow, confident: 1.0 ± 0.1.
        let mut moved = estimate;
        assert!(!combine_direct(
            &mut moved,
            (Rgb::new(1.0, 4.9, 4.1), Rgb::splat(0.01))
        ));
        assert_eq!(moved, estimate);
        // Within the bound (1.4 apart against 3 × 0.51).
        let mut moved = estimate;
        assert!(combine_direct(
            &mut moved,
            (Rgb::new(4.1, 4.9, 4.1), Rgb::splat(0.01))
        ));
        let expected = (5.5 / 0.25 + 4.1 / 0.01) / (1.0 / 0.25 + 1.0 / 0.01);
        assert!((moved.irradiance.r - expected).abs() < 1e-12, "{moved:?}");
        assert!(moved.std_error.r < 0.1);
    }
}

//! The irradiance cache's records as a prior on a point query's indirect
//! irradiance (docs/math.md §10.7), or their direct-light twins as one on
//! its direct irradiance (§10.8): where records cover the point, their
//! interpolated irradiance and its variance (`IrradianceCache::lookup`) are
//! the prior's mean and variance.

use super::irradiance_cache::{Accuracy, IrradianceCache};
use super::twin_caches::TwinCaches;
use crate::estimators::{IntegralPrior, PriorAt};
use crate::render::{QueryPoint, Rgb};

/// Records of one or more caches, each looked up with its own accuracy and
/// its own measured relative prediction error.
pub struct RecordsPrior<'a> {
    caches: Vec<Source<'a>>,
}

/// One cache as a source of the prior.
struct Source<'a> {
    cache: &'a IrradianceCache,
    /// The shadow probes at the records' places, for twins (§10.8).
    probes: Option<&'a IrradianceCache>,
    accuracy: Accuracy,
    /// What the records are, as responses name them.
    origin: &'static str,
    /// The cache's held-out prediction error (module docs).
    error: HeldOutError,
}

/// The finest accuracy of a prior's lookups (docs/math.md §10.7): records
/// placed finer (the final preset's 0.25) each stand where the others did
/// not reach, so at their own accuracy almost none is predicted by the
/// others (10 of 243 on the overcast scene's final tiles) and the prior's
/// error cannot be measured. Looked up at 0.5, the records predict each
/// other (239 of 243) and `τ²` measures the error of reaching that far;
/// at 1.0 the prior reached too far and made environment-only BMC worse
/// than without it there (1.34× QMC, against 0.82× at 0.5).
pub const PRIOR_ACCURACY: f64 = 0.5;

/// Records left out in turn to measure a cache's prediction error.
pub const HELD_OUT_RECORDS: usize = 256;
/// Fewest held-out predictions that make the measured error a measurement:
/// a cache with fewer serves no prior.
pub const MIN_HELD_OUT: usize = 16;

impl<'a> RecordsPrior<'a> {
    /// A prior from `caches` (each with its accuracy and what its records
    /// are), whose records must hold the part the prior is for: the indirect
    /// irradiance of paths at least as long as the query's, or the direct
    /// light alone (direct-light twins).
    pub fn new(
        caches: impl IntoIterator<Item = (&'a IrradianceCache, Accuracy, &'static str)>,
    ) -> Self {
        Self::of_sources(
            caches
                .into_iter()
                .map(|(cache, accuracy, origin)| (cache, None, accuracy, origin)),
        )
    }

    /// A prior on the direct part from direct-light twins, each beside its
    /// shadow probes ([`Self::at_with_probes`]).
    pub fn of_twins(
        caches: impl IntoIterator<Item = (&'a TwinCaches, Accuracy, &'static str)>,
    ) -> Self {
        Self::of_sources(
            caches.into_iter().map(|(twins, accuracy, origin)| {
                (&twins.twins, Some(&twins.probes), accuracy, origin)
            }),
        )
    }

    fn of_sources(
        caches: impl IntoIterator<
            Item = (
                &'a IrradianceCache,
                Option<&'a IrradianceCache>,
                Accuracy,
                &'static str,
            ),
        >,
    ) -> Self {
        let caches = caches
            .into_iter()
            .filter_map(|(cache, probes, accuracy, origin)| {
                let accuracy = reach(accuracy);
                held_out_error(cache, accuracy).map(|error| Source {
                    cache,
                    probes,
                    accuracy,
                    origin,
                    error,
                })
            })
            .collect();
        Self { caches }
    }

    /// The prior at `point` (as [`IntegralPrior::at`]) and, where its
    /// records are twins, their shadow probes interpolated at the point
    /// with the same weights (docs/math.md §10.8).
    pub fn at_with_probes(&self, point: &QueryPoint) -> Option<(PriorAt, Option<Rgb>)> {
        let (source, prior) = self.best(point)?;
        let probes = source
            .probes
            .and_then(|probes| probes.lookup(point, source.accuracy))
            .map(|found| found.irradiance);
        Some((prior, probes))
    }

    /// Whether no cache serves the prior (none given, or none with enough
    /// records to measure its error).
    pub fn is_empty(&self) -> bool {
        self.caches.is_empty()
    }

    /// What the records serving the prior at `point` are, if any serve.
    pub fn origin_at(&self, point: &QueryPoint) -> Option<&'static str> {
        self.best(point).map(|(source, _)| source.origin)
    }

    /// Among the caches covering `point`, the one with the smallest prior
    /// variance of luminance, with the prior there: the interpolation's
    /// variance and the records' disagreement measured at the point, and
    /// `(τ E)²` per channel modelled, `τ²` the cache's held-out error.
    fn best(&self, point: &QueryPoint) -> Option<(&Source<'a>, PriorAt)> {
        self.caches
            .iter()
            .filter_map(|source| {
                let found = source.cache.lookup(point, source.accuracy)?;
                let e = found.irradiance;
                let prior = PriorAt {
                    mean: e,
                    variance: found.error_variance(),
                    modelled: e * e * source.error.at(found.reach),
                    rays: 0,
                };
                Some((source, prior))
            })
            .min_by(|a, b| {
                let v = |p: &PriorAt| p.stated_variance().luminance();
                v(&a.1).total_cmp(&v(&b.1))
            })
    }
}

/// The accuracy of a prior's lookups: the cache's, or the coarser
/// [`PRIOR_ACCURACY`].
fn reach(accuracy: Accuracy) -> Accuracy {
    if accuracy.value() >= PRIOR_ACCURACY {
        accuracy
    } else {
        Accuracy::new(PRIOR_ACCURACY).expect("PRIOR_ACCURACY is an accuracy")
    }
}

/// A cache's squared relative prediction error as a function of how far
/// its records reach a point (docs/math.md §10.7): `τ²(δ) = c δ`, with `δ`
/// the lookup's [`Interpolated::reach`](super::Interpolated::reach). Linear
/// because an occluder's edge lies between the point and its records with a
/// chance that grows with the distance, and then costs a step; a smooth field
/// extrapolated with gradients errs less (second order), so the line is the
/// wider of the two near the records.
#[derive(Clone, Copy, Debug, PartialEq)]
struct HeldOutError {
    /// `c`: the squared relative error per validity radius of reach.
    per_reach: f64,
}

impl HeldOutError {
    /// `τ²` at a point the records reach by `reach`.
    fn at(self, reach: f64) -> f64 {
        self.per_reach * reach
    }

    /// `c = Σ e_i² / Σ δ_i` over pairs `(δ_i, e_i²)`, so that `τ²(δ_i)`
    /// averages to the measured error over them.
    fn fit(pairs: &[(f64, f64)]) -> Option<Self> {
        let (reach, error) = pairs
            .iter()
            .fold((0.0, 0.0), |(d, e), p| (d + p.0, e + p.1));
        (reach > 0.0).then(|| Self {
            per_reach: error / reach,
        })
    }
}

/// `τ²(δ)` of a cache (module docs): for up to [`HELD_OUT_RECORDS`]
/// records spread over its insertion order, the squared relative difference
/// of luminance `e²` between the record and the interpolation of the others
/// at its point and normal, and how far the others reach it, `δ`, fitted by
/// [`HeldOutError::fit`]. `None` below [`MIN_HELD_OUT`] predictions. It
/// holds the interpolation error and the noise of the records on both sides
/// (docs/math.md §10.9: the estimators scale it on the scene).
fn held_out_error(cache: &IrradianceCache, accuracy: Accuracy) -> Option<HeldOutError> {
    let records = cache.records();
    let step = records.len().div_ceil(HELD_OUT_RECORDS).max(1);
    let mut pairs = Vec::new();
    for record in records.iter().step_by(step) {
        let own = record.irradiance.luminance();
        let Ok(point) = QueryPoint::new(record.position, record.normal) else {
            continue;
        };
        if own <= 0.0 {
            continue;
        }
        let others = cache.lookup_filtered(&point, accuracy, |r| r.position != record.position);
        if let Some(others) = others {
            let d = (others.irradiance.luminance() - own) / own;
            pairs.push((others.reach, d * d));
        }
    }
    if pairs.len() < MIN_HELD_OUT {
        return None;
    }
    HeldOutError::fit(&pairs)
}

impl IntegralPrior for RecordsPrior<'_> {
    /// The best covering cache's prior (`Self::best`).
    fn at(&self, point: &QueryPoint) -> Option<PriorAt> {
        self.best(point).map(|(_, prior)| prior)
    }

    /// The bit length of the number of records held: it changes each time
    /// the records double.
    fn state(&self) -> u64 {
        let records: u64 = self.caches.iter().map(|s| s.cache.stats().records).sum();
        u64::from(u64::BITS - records.leading_zeros())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cache::{CacheConfig, Record};
    use crate::render::Rgb;
    use glam::DVec3;

    /// Records on a 10 × 10 grid in the plane z = 0, 0.1 apart with radius
    /// 0.25, irradiance `1 + x` times a factor `1 ± noise` alternating.
    fn grid(noise: f64, variance: f64) -> IrradianceCache {
        let cache = IrradianceCache::new(CacheConfig::default()).unwrap();
        for i in 0..10 {
            for j in 0..10 {
                let x = 0.1 * f64::from(i);
                let sign = if (i + j) % 2 == 0 { 1.0 } else { -1.0 };
                cache
                    .insert(Record {
                        position: DVec3::new(x, 0.1 * f64::from(j), 0.0),
                        normal: DVec3::Z,
                        irradiance: Rgb::splat((1.0 + x) * (1.0 + sign * noise)),
                        variance: Rgb::splat(variance),
                        radius: 0.25,
                        rotation_gradient: [DVec3::ZERO; 3],
                        translation_gradient: [DVec3::ZERO; 3],
                    })
                    .unwrap();
            }
        }
        cache
    }

    /// On errors that grow with the reach the line averages to them; at a
    /// record's own place it is near zero.
    #[test]
    fn the_held_out_error_grows_with_the_reach() {
        let pairs: Vec<_> = (1..=20)
            .map(|i| {
                let d = 0.02 * f64::from(i);
                (d, 0.05 * d)
            })
            .collect();
        let fit = HeldOutError::fit(&pairs).unwrap();
        assert!((fit.per_reach - 0.05).abs() < 1e-12);
        assert!(fit.at(1e-12) < 1e-12);
        assert_eq!(HeldOutError::fit(&[(0.0, 0.1)]), None);
    }

    #[test]
    fn the_prior_variance_holds_the_measured_prediction_error() {
        let accuracy = Accuracy::new(0.5).unwrap();
        let (smooth, noisy) = (grid(0.0, 1e-6), grid(0.2, 1e-6));
        let e2 = |c| held_out_error(c, accuracy).expect("enough records");
        // A linear field is predicted well; alternating ±20 % is not, and
        // the records' own (tiny) variances do not hide it.
        let (smooth_e2, noisy_e2) = (e2(&smooth).at(0.3), e2(&noisy).at(0.3));
        assert!(smooth_e2 < 0.01, "{smooth_e2}");
        assert!(noisy_e2 > 0.02, "{noisy_e2}");
        let point = QueryPoint::new(DVec3::new(0.45, 0.45, 0.0), DVec3::Z).unwrap();
        let alone = RecordsPrior::new([(&noisy, accuracy, "noisy")]);
        let prior = alone.at(&point).expect("covered");
        let (mean, variance) = (prior.mean, prior.stated_variance());
        let reach = noisy.lookup(&point, accuracy).unwrap().reach;
        assert!(reach > 0.0 && reach <= 0.5, "{reach}");
        assert!((prior.modelled.r - mean.r * mean.r * e2(&noisy).at(reach)).abs() < 1e-12);
        // With both, the more precise cache is the prior.
        let both = RecordsPrior::new([(&noisy, accuracy, "noisy"), (&smooth, accuracy, "smooth")]);
        let best = both.at(&point).unwrap().stated_variance();
        assert!(best.r < variance.r);
        assert_eq!(both.origin_at(&point), Some("smooth"));
        let far = QueryPoint::new(DVec3::new(50.0, 0.0, 0.0), DVec3::Z).unwrap();
        assert_eq!(both.origin_at(&far), None);
        // 200 records: bit length 8; a cache too small to measure serves nothing.
        assert_eq!(both.state(), 8);
        let tiny = IrradianceCache::new(CacheConfig::default()).unwrap();
        assert!(
            RecordsPrior::new([(&tiny, accuracy, "tiny")])
                .caches
                .is_empty()
        );
    }
}

//! Which records serve a point query's estimate as priors, decided once for
//! every front end (the irradiance route, the real-scene study): the
//! indirect part leans on the records of every cache whose records sum
//! paths at least as long, from their point, as the query's (docs/math.md
//! §10.7); the direct part leans on the direct-light twins of every cache's
//! records, at any depth, since those hold the direct light alone, made as
//! the query's decomposition estimates it (§10.8), widened where the
//! point's shadow probe and the twins' disagree.

use crate::cache::{Accuracy, IrradianceCache, RecordsPrior, TwinCaches};
use crate::estimators::{IntegralPrior, PriorAt};
use crate::render::{
    Cancel, Decomposition, IrradianceMethod, PathDepth, QueryPoint, RenderError, TraceStats,
    Transport,
};

/// A cache of records that may serve point queries as a prior.
pub trait RecordSource {
    /// The records and the accuracy of their lookups.
    fn records(&self) -> (&IrradianceCache, Accuracy);

    /// What the records are, as responses name them (`RecordsPrior::origin_at`).
    fn origin(&self) -> &'static str;

    /// Path segments the records sum, counted from their own point (`None`:
    /// none beyond it, so no indirect light).
    fn depth_from_point(&self) -> Option<PathDepth>;

    /// The records' direct-light twins for queries under `decomposition`
    /// (`None`: none to offer) and the rays traced now to make missing ones.
    fn direct_twins(
        &self,
        transport: &Transport,
        decomposition: Decomposition,
        cancel: &Cancel,
    ) -> Result<Option<(&TwinCaches, u64)>, RenderError>;
}

/// The priors of a point query.
pub struct PointPriors<'a> {
    /// On the indirect part (§10.7).
    pub records: RecordsPrior<'a>,
    /// On the direct part (§10.8).
    pub direct: DirectPrior<'a>,
    /// Rays traced making direct-light twins.
    pub rays: u64,
}

/// The priors `sources` offer a query whose paths have `max_depth`
/// segments (a camera path's depth: the segment to the point counts),
/// estimated by `method` (module docs).
pub fn point_priors<'a, S: RecordSource>(
    sources: &'a [S],
    transport: &'a Transport,
    max_depth: PathDepth,
    method: IrradianceMethod,
    cancel: &Cancel,
) -> Result<PointPriors<'a>, RenderError> {
    let records = sources.iter().filter_map(|source| {
        let deep_enough = source
            .depth_from_point()
            .is_some_and(|d| d.get() >= max_depth.get());
        deep_enough.then(|| {
            let (cache, accuracy) = source.records();
            (cache, accuracy, source.origin())
        })
    });
    let records = RecordsPrior::new(records);
    let mut twins = Vec::new();
    let mut rays = 0;
    let decomposition = transport.decomposition(method);
    for source in sources {
        if let Some((cache, traced)) = source.direct_twins(transport, decomposition, cancel)? {
            rays += traced;
            twins.push((cache, source.records().1, source.origin()));
        }
    }
    Ok(PointPriors {
        records,
        direct: DirectPrior {
            twins: RecordsPrior::of_twins(twins),
            transport,
        },
        rays,
    })
}

/// The prior on a point's direct part (docs/math.md §10.8): the
/// interpolated direct-light twins, their variance widened by the squared
/// difference between the point's shadow probe and the twins' probes
/// interpolated there. Twins do not see the edges of occluders between
/// their places and the point, nor what their extrapolation to its normal
/// misses; the probes, drawn from the same numbers at both and
/// extrapolated alike, see what those change.
pub struct DirectPrior<'a> {
    twins: RecordsPrior<'a>,
    transport: &'a Transport,
}

impl DirectPrior<'_> {
    /// Whether no twins serve the prior.
    pub fn is_empty(&self) -> bool {
        self.twins.is_empty()
    }

    /// What the records whose twins serve at `point` are, if any serve.
    pub fn origin_at(&self, point: &QueryPoint) -> Option<&'static str> {
        self.twins.origin_at(point)
    }
}

impl IntegralPrior for DirectPrior<'_> {
    /// The twins' prior, widened by the probes' squared difference per
    /// channel (measured at the point: no scale of §10.9 applies to it),
    /// and the probe's rays.
    fn at(&self, point: &QueryPoint) -> Option<PriorAt> {
        let (mut prior, probes) = self.twins.at_with_probes(point)?;
        if let Some(probes) = probes {
            let mut stats = TraceStats::default();
            let difference = self.transport.shadow_probe(point, &mut stats).0 - probes;
            prior.variance += difference * difference;
            prior.rays += stats.rays;
        }
        Some(prior)
    }

    fn state(&self) -> u64 {
        self.twins.state()
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::cache::{CacheConfig, Record};
    use crate::integrator::cached::{TwinRule, direct_records};
    use crate::render::{Rgb, SHADOW_PROBES};

    /// Twins on a grid inside the point light's shadow of
    /// [`crate::testing::occluded_ground`] (`|x|, |y| ≤ 0.4`, radius 0.6),
    /// and two query points: one among them in the shadow, one lit just
    /// past its edge but still within their reach.
    #[test]
    fn probes_widen_the_twins_prior_past_a_shadow_edge() {
        let sky = 0.05;
        let transport = crate::testing::occluded_ground(sky);
        let places: Vec<Record> = (0..25)
            .map(|i| {
                let (x, y) = (0.2 * (i % 5) as f64 - 0.4, 0.2 * (i / 5) as f64 - 0.4);
                crate::testing::flat_record(DVec3::new(x, y, 0.0), DVec3::Z, Rgb::BLACK, 0.6)
            })
            .collect();
        let caches = TwinCaches::new(CacheConfig::default()).unwrap();
        direct_records(
            &transport,
            &places,
            TwinRule::LightSamples(1024),
            &caches,
            3,
            &Cancel::never(),
        )
        .unwrap();
        let accuracy = Accuracy::new(0.5).unwrap();
        let prior = DirectPrior {
            twins: RecordsPrior::of_twins([(&caches, accuracy, "test")]),
            transport: &transport,
        };
        let at = |x: f64| QueryPoint::new(DVec3::new(x, 0.0, 0.0), DVec3::Z).unwrap();
        // Lit: the point light's I cos θ / r² above what the twins hold.
        let lit = at(0.6);
        let (plain, _) = prior.twins.at_with_probes(&lit).expect("covered");
        let widened = prior.at(&lit).unwrap();
        let light = 4.0 * 2.0 / (0.36f64 + 4.0).powf(1.5);
        let z = |p: PriorAt| (light + plain.mean.g - p.mean.g) / p.stated_variance().g.sqrt();
        assert!(
            z(plain) > 5.0,
            "the twins alone claim the shadow: {plain:?}"
        );
        assert!(z(widened) < 2.0, "{widened:?}");
        assert_eq!(widened.mean, plain.mean);
        assert!(widened.rays > 0 && widened.rays <= 2 * u64::from(SHADOW_PROBES));
        // In the shadow among the twins the probes agree: the prior stays
        // narrow against the light it would have missed.
        let shaded = prior.at(&at(-0.1)).unwrap();
        assert!(
            shaded.stated_variance().g.sqrt() < 0.1 * light,
            "{shaded:?}"
        );
    }
}

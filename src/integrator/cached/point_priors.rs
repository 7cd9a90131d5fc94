//! Which records serve a point query's estimate as priors, decided once for
//! every front end (the irradiance route, the real-scene study): the
//! indirect part leans on the records of every cache whose records sum
//! paths at least as long, from their point, as the query's (docs/math.md
//! §10.7); the direct part leans on the direct-light twins of every cache's
//! records, at any depth, since those hold the direct light alone, made as
//! the query's decomposition estimates it (§10.8).

use crate::cache::{Accuracy, IrradianceCache, RecordsPrior};
use crate::render::{Cancel, Decomposition, IrradianceMethod, PathDepth, RenderError, Transport};

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
    ) -> Result<Option<(&IrradianceCache, u64)>, RenderError>;
}

/// The priors of a point query.
pub struct PointPriors<'a> {
    /// On the indirect part (§10.7).
    pub records: RecordsPrior<'a>,
    /// On the direct part (§10.8).
    pub direct: RecordsPrior<'a>,
    /// Rays traced making direct-light twins.
    pub rays: u64,
}

/// The priors `sources` offer a query whose paths have `max_depth`
/// segments (a camera path's depth: the segment to the point counts),
/// estimated by `method` (module docs).
pub fn point_priors<'a, S: RecordSource>(
    sources: &'a [S],
    transport: &Transport,
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
        direct: RecordsPrior::new(twins),
        rays,
    })
}

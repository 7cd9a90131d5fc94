//! Records placed among a point query's own points (docs/math.md §10.11):
//! the placement pass of the cache (§9.5) over the query's points in their
//! order, as a tile's over its pixels, so points no record covers get one and
//! the others are covered by their neighbours'. The records hold the indirect
//! irradiance of paths as long as the query's, and later serve it and other
//! queries as a prior (§10.7), their places the direct-light twins (§10.8).
//! A function of the points, the depth, the rules and the seed only: the
//! same points give the same records on every replica.

use super::config::{CachedShading, indirect_paths};
use super::placement::{PlacementCache, PlacementReport, place_records};
use super::record_estimate::PlacementPoint;
use super::shade::Gather;
use crate::cache::{IrradianceCache, Record};
use crate::render::{Cancel, PathDepth, QueryPoint, RenderError, Transport};

/// The records placed among `points` by `shading`'s rules at its accuracy,
/// summing paths of up to `from_point` segments from their own point, in
/// insertion order, with what placing them took.
pub fn point_records(
    transport: &Transport,
    shading: &CachedShading,
    points: &[QueryPoint],
    from_point: PathDepth,
    seed: u64,
    cancel: &Cancel,
) -> Result<(Vec<Record>, PlacementReport), RenderError> {
    let cache = IrradianceCache::new(crate::cache::CacheConfig::default())?;
    let targets: Vec<PlacementPoint> = points
        .iter()
        .map(|&point| PlacementPoint {
            point,
            footprint: None,
        })
        .collect();
    let report = place_records(
        PlacementCache::Private(&cache),
        transport,
        &shading.rule,
        &targets,
        &shading.placement(indirect_paths(from_point), seed),
        Gather::Paths,
        cancel,
    )?;
    Ok((cache.records(), report))
}

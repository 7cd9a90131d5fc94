//! Computing records by BMC at surface points, and the two-pass reproducible
//! scheme: a placement pass over the points in a fixed order that decides
//! where records go, then a shading pass that only reads the cache.
//!
//! # Reproducibility
//! Point `i` of a request draws every random number (its rotation about the
//! normal, then its paths) from [`point_rng`]`(seed, i)`. The placement pass
//! takes the points in batches of `batch_size` in the given order: every
//! decision in a batch is made against the cache state at the batch start,
//! only the records are computed in parallel, and they are inserted in point
//! order. So which records exist, their values and their radii (including
//! the neighbour clamp and FIFO eviction, both functions of the insertion
//! order) do not depend on the thread count. Lookups visit records in an
//! order fixed by the insertion order too, so interpolated values are
//! bit-identical. [`place_and_shade`] runs both passes on a private cache,
//! which makes the result independent of anything other requests did; a
//! caller may afterwards copy its records into the shared cache. The
//! batch size trades parallelism against duplicate records for nearby points
//! of one batch.
//!
//! # Estimates in batches
//! A record's BMC estimate reads the rule's `N × N` tables (24 MB at
//! N = 1024), so estimating records together, one solve for all of their
//! columns, costs far less per record than one at a time. A pass over a
//! cache no one else reads ([`PlacementCache::Private`]), gathering by paths
//! and with no variance target, inserts each record as soon as its first
//! segments are traced (their distances fix its radius), with its values
//! still unknown, and later traces the paths of up to [`HELD_BACK`] of them
//! at once, in parallel, and estimates them together: where records go,
//! their radii and evictions depend only on positions, normals and radii,
//! and the pass only asks whether a point is covered, so the cache ends
//! exactly as with finished inserts. The first segments draw no random
//! numbers, so each record's paths draw the same ones as when traced right
//! after them (`TracedRecord`): the records are the same bits. Tracing a
//! record's paths per batch of points instead left a thread idle whenever a
//! batch wanted fewer records than there are threads (most batches, once
//! most points are covered). Otherwise each batch of points gathers and
//! estimates its own records.
//!
//! # Light leaks
//! With `occlusion_check`, a record is only used if a shadow ray between the
//! point and the record, both lifted off their surfaces by `10⁻³ R_k` along
//! their normals, is unobstructed; this stops records from being used
//! through thin walls (a point and a record on opposite sides) at the cost of
//! one ray per candidate record.

use rayon::prelude::*;

use super::config::PlacementOptions;
use super::record_estimate::{
    GatheredRecord, PlacementPoint, awaiting_record, finish_records, lookup,
};
use super::shade::{Gather, RecordGather, TracedRecord, gather_record, trace_record};
use super::stats::ShadingStats;
use crate::cache::{
    CacheConfig, CacheError, Interpolated, IrradianceCache, RadiusLimits, Record, RecordRule,
    RecordSlot,
};
use crate::render::seed::point_rng;
use crate::render::{Cancel, QueryPoint, Transport};

/// What a placement pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct PlacementReport {
    /// Records inserted, those created at other records' bounces included.
    pub records_created: u64,
    /// Of those, created at the bounces of other records' rays ([`Gather`]).
    pub ambient_records: u64,
    /// Of those, created because of the variance target.
    pub records_for_variance: u64,
    /// Rays traced for records.
    pub rays: u64,
    /// Records' rays whose hit no record of the cache they gather through
    /// covered, so one path estimated its indirect light ([`Gather::Cache`],
    /// [`Gather::Secondary`]).
    pub fallbacks: u64,
}

impl PlacementReport {
    /// Counts one record placed at a point with `stats` from its gathering.
    fn count(&mut self, stats: &ShadingStats, for_variance: bool) {
        self.records_created += 1 + stats.records_created;
        self.ambient_records += stats.ambient_records;
        self.records_for_variance += u64::from(for_variance);
        self.rays += stats.rays;
        self.fallbacks += stats.fallbacks;
    }
}

/// Whether the variance target asks for another record here.
fn too_uncertain(found: &Interpolated, target: f64) -> bool {
    const Y: [f64; 3] = crate::color::LUMINANCE_WEIGHTS;
    let e = found.irradiance.to_array();
    let v = found.variance.to_array();
    let lum: f64 = (0..3).map(|c| Y[c] * e[c]).sum();
    let var: f64 = (0..3).map(|c| Y[c] * Y[c] * v[c]).sum();
    lum > 0.0 && var.sqrt() > target * lum
}

/// The cache a placement pass fills, by who reads it meanwhile.
#[derive(Clone, Copy)]
pub enum PlacementCache<'a> {
    /// Read by the pass only (a private cache, dropped if the pass fails).
    Private(&'a IrradianceCache),
    /// Read by other requests too: every record goes in finished.
    Shared(&'a IrradianceCache),
}

/// Records whose paths and estimates a pass may hold back (module docs,
/// "Estimates in batches"), estimated in batches of [`HELD_BATCH`], in
/// parallel. Each keeps its first segments meanwhile (224 bytes per
/// direction: 29 MB at 1024 directions).
const HELD_BACK: usize = 128;
/// Records estimated together once held back: from about 32 on, a record's
/// estimate costs a third of one made alone (docs/BENCHMARKS.md). A fixed
/// number, not a share per thread, so which records share a batch (and with
/// it the last bits of faer's blocked solves) does not depend on the thread
/// count.
const HELD_BATCH: usize = 32;

/// Placement pass (module docs): records where the cache has no value (or,
/// with a target, too uncertain a value) at each point, in point order,
/// their rays gathered as `gather` says. Only a read-only `gather` (paths, or
/// the cache without nested insertion) keeps the pass deterministic.
pub fn place_records(
    into: PlacementCache,
    transport: &Transport,
    rule: &RecordRule,
    points: &[PlacementPoint],
    options: &PlacementOptions,
    gather: Gather,
    cancel: &Cancel,
) -> Result<PlacementReport, CacheError> {
    // The options come checked (`CacheShadingOptions::validate`, through
    // `CachedSpec::resolve`); a hand-built value must keep the same invariants.
    debug_assert!(options.batch_size >= 1 && options.paths_per_direction >= 1);
    let (cache, private) = match into {
        PlacementCache::Private(cache) => (cache, true),
        PlacementCache::Shared(cache) => (cache, false),
    };
    let limits = cache.radius_limits();
    // Held-back estimates are invisible only to a pass that asks whether a
    // point is covered, never for a value (module docs).
    let hold_back = private
        && matches!(gather, Gather::Paths | Gather::Secondary { .. })
        && options.relative_error_target.is_none();
    let how = RecordGather {
        paths: options.paths,
        per_direction: options.paths_per_direction,
        gather,
    };
    let mut report = PlacementReport::default();
    let mut awaiting = Vec::new();
    let held = HeldBack {
        cache,
        transport,
        rule,
        how: &how,
        limits,
        cancel,
    };
    let fill = |awaiting: &mut Vec<_>, report: &mut PlacementReport| held.fill(awaiting, report);
    for (b, batch) in points.chunks(options.batch_size).enumerate() {
        cancel.check()?;
        let first = b * options.batch_size;
        // (point index, created for variance)
        let wanted: Vec<(usize, bool)> = batch
            .par_iter()
            .enumerate()
            .filter_map(|(i, p)| match lookup(cache, transport, &p.point, options) {
                None => Some((first + i, false)),
                Some(found) => options
                    .relative_error_target
                    .filter(|t| too_uncertain(&found, *t))
                    .map(|_| (first + i, true)),
            })
            .collect();
        if hold_back {
            // Only the first segments now: they fix the radius, and the
            // paths from them are traced for many records at once below,
            // where both threads have work (one record per thread here
            // left a thread idle whenever a batch wanted an odd number).
            let traced = wanted
                .par_iter()
                .map(|&(i, _)| {
                    let mut stats = ShadingStats::default();
                    let rng = point_rng(options.seed, i as u64);
                    let target = &points[i];
                    let traced = trace_record(transport, rule, target, &how, rng, &mut stats);
                    (target, traced, stats)
                })
                .collect::<Vec<_>>();
            cancel.check()?;
            for ((target, traced, stats), &(_, for_variance)) in traced.into_iter().zip(&wanted) {
                report.count(&stats, for_variance);
                let record = awaiting_record(target, &traced.distances(), limits);
                let slot = cache.insert_awaiting_values(record)?;
                awaiting.push((slot, target, traced));
            }
            if awaiting.len() >= HELD_BACK {
                fill(&mut awaiting, &mut report)?;
            }
            continue;
        }
        let (gathered, stats): (Vec<(&PlacementPoint, GatheredRecord)>, Vec<ShadingStats>) = wanted
            .par_iter()
            .map(|&(i, _)| {
                cancel.check()?;
                let mut rng = point_rng(options.seed, i as u64);
                let mut stats = ShadingStats::default();
                let target = &points[i];
                let rays = gather_record(transport, rule, target, &how, &mut rng, &mut stats)?;
                Ok(((target, rays), stats))
            })
            .collect::<Result<Vec<_>, CacheError>>()?
            .into_iter()
            .unzip();
        cancel.check()?;
        for (stats, &(_, for_variance)) in stats.iter().zip(&wanted) {
            report.count(stats, for_variance);
        }
        let per_thread = gathered.len().div_ceil(rayon::current_num_threads());
        for record in estimate_records(rule, &gathered, limits, per_thread) {
            cache.insert(record?)?;
        }
    }
    fill(&mut awaiting, &mut report)?;
    Ok(report)
}

/// Records estimated from gathered rays, in order, in batches of `batch`
/// in parallel: each batch reads the rule's tables from memory once
/// (`RecordRule::estimate_batch`).
fn estimate_records(
    rule: &RecordRule,
    gathered: &[(&PlacementPoint, GatheredRecord)],
    limits: RadiusLimits,
    batch: usize,
) -> Vec<Result<Record, CacheError>> {
    gathered
        .par_chunks(batch.max(1))
        .flat_map_iter(|chunk| finish_records(rule, chunk, limits))
        .collect()
}

/// What filling held-back records needs (module docs, "Estimates in
/// batches"): the pass's cache, scene, rule, gathering, radius limits and
/// cancellation.
struct HeldBack<'a> {
    cache: &'a IrradianceCache,
    transport: &'a Transport,
    rule: &'a RecordRule,
    how: &'a RecordGather<'a>,
    limits: RadiusLimits,
    cancel: &'a Cancel,
}

impl HeldBack<'_> {
    /// Gathers the rest of the rays of the records inserted awaiting their
    /// values, all in parallel, then estimates them and fills them in.
    /// Their rays and fallbacks are added to `report`.
    fn fill(
        &self,
        awaiting: &mut Vec<(RecordSlot, &PlacementPoint, TracedRecord)>,
        report: &mut PlacementReport,
    ) -> Result<(), CacheError> {
        let (slots, gathered): (Vec<RecordSlot>, Vec<_>) = std::mem::take(awaiting)
            .into_par_iter()
            .map(|(slot, target, traced)| {
                self.cancel.check()?;
                let mut stats = ShadingStats::default();
                let gathered = traced.continue_paths(self.transport, self.how, &mut stats)?;
                Ok((slot, ((target, gathered), stats)))
            })
            .collect::<Result<Vec<_>, CacheError>>()?
            .into_iter()
            .map(|(slot, (gathered, stats))| {
                report.rays += stats.rays;
                report.fallbacks += stats.fallbacks;
                (slot, gathered)
            })
            .unzip();
        let records = estimate_records(self.rule, &gathered, self.limits, HELD_BATCH);
        for (slot, record) in slots.into_iter().zip(records) {
            self.cache.fill_values(slot, &record?)?;
        }
        Ok(())
    }
}

/// Shading pass: read-only lookups, in parallel, results in point order.
pub fn shade(
    cache: &IrradianceCache,
    transport: &Transport,
    points: &[QueryPoint],
    options: &PlacementOptions,
) -> Vec<Option<Interpolated>> {
    points
        .par_iter()
        .map(|p| lookup(cache, transport, p, options))
        .collect()
}

/// Both passes on a private cache built from `config`, records gathering by
/// paths: bit-identical for the
/// same inputs whatever the thread count or earlier requests. Returns the
/// interpolated values and the private cache (to publish its records).
pub fn place_and_shade(
    transport: &Transport,
    rule: &RecordRule,
    config: CacheConfig,
    points: &[PlacementPoint],
    options: &PlacementOptions,
) -> Result<(Vec<Option<Interpolated>>, IrradianceCache, PlacementReport), CacheError> {
    let cache = IrradianceCache::new(config)?;
    let report = place_records(
        PlacementCache::Private(&cache),
        transport,
        rule,
        points,
        options,
        Gather::Paths,
        &Cancel::never(),
    )?;
    let query: Vec<QueryPoint> = points.iter().map(|p| p.point).collect();
    Ok((shade(&cache, transport, &query, options), cache, report))
}

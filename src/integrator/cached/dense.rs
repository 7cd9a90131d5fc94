//! Tiles where records do not pay (docs/math.md §9.7): where the cache's
//! rules would place nearly a record per pixel (thousands of small, curved,
//! mutually occluding parts, such as the bricks of the tutorials' lego), a
//! record costs its `N` directions' paths and serves a pixel or two, which
//! is more than the camera samples' own indirect paths cost, and its
//! interpolation still leaves a bias. Such a tile places no records: each
//! camera sample's diffuse indirect light is one cosine-distributed path
//! (the shading pass's miss fallback, unbiased), and its direct light takes
//! [`DENSE_LIGHT_FACTOR`] times the light samples, as the records' budget
//! goes to the direct light that then dominates the noise.
//!
//! Whether a tile is dense is decided before any record is computed, by a
//! probe: the placement pass over the tile's placement points, in the same
//! order and with the same coverage rule, but each record's radius taken
//! from [`PROBE_DIRECTIONS`] first segments only and no value estimated, on
//! a cache of its own. It is a function of the scene, the configuration and
//! the tile (its own random stream), so a reproducible tile stays so.

use rayon::prelude::*;

use super::config::PlacementOptions;
use super::record_estimate::{PlacementPoint, awaiting_record, lookup};
use crate::cache::{CacheConfig, CacheError, IrradianceCache};
use crate::render::seed::point_rng;
use crate::render::{Cancel, RenderError, TraceStats, Transport};
use crate::sphere::{SampleSet, SampleSetSpec};

/// Directions whose first segments give a probe record its radius (Ward's
/// harmonic mean distance); enough for the count of records, which is all
/// the probe is for.
pub const PROBE_DIRECTIONS: usize = 64;
/// A tile is dense only if its probe places more records than this, so a
/// tile that sees a few pixels of geometry keeps its records.
pub const MIN_DENSE_RECORDS: u64 = 32;
/// Light samples of a dense tile's shading points, in multiples of the
/// configuration's: on the lego at the `final` preset, 4.85 % error over
/// 8×8 blocks in 9.6 s with 1×, 4.34 % in 21.8 s with 4× (docs/BENCHMARKS.md).
pub const DENSE_LIGHT_FACTOR: u32 = 4;
/// Seed of the probe's record rotations (its own stream: the probe draws
/// nothing from the placement's).
const PROBE_SEED: u64 = 0xde05_e7a1_e5ba_5e00;

/// What a probe found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Probe {
    /// Records the placement would create (as the probe counts them).
    pub records: u64,
    /// Rays the probe traced.
    pub rays: u64,
}

impl Probe {
    /// Whether a tile of `points` placement points with this probe is dense
    /// under a limit of `max_per_point` records per placement point.
    pub fn is_dense(&self, points: usize, max_per_point: f64) -> bool {
        self.records > MIN_DENSE_RECORDS && self.records as f64 > max_per_point * points as f64
    }
}

/// The probe of the placement of records at `points` with `options`
/// (module docs), on a cache configured as `config`.
pub fn probe(
    transport: &Transport,
    config: CacheConfig,
    directions: SampleSetSpec,
    points: &[PlacementPoint],
    options: &PlacementOptions,
    cancel: &Cancel,
) -> Result<Probe, RenderError> {
    let set = SampleSet::generate(SampleSetSpec {
        count: PROBE_DIRECTIONS,
        ..directions
    })
    .map_err(CacheError::from)?;
    let cache = IrradianceCache::new(config)?;
    let limits = cache.radius_limits();
    let mut found = Probe {
        records: 0,
        rays: 0,
    };
    for (b, batch) in points.chunks(options.batch_size).enumerate() {
        cancel.check()?;
        let first = b * options.batch_size;
        let wanted: Vec<usize> = batch
            .par_iter()
            .enumerate()
            .filter(|(_, p)| lookup(&cache, transport, &p.point, options).is_none())
            .map(|(i, _)| first + i)
            .collect();
        let records: Vec<_> = wanted
            .par_iter()
            .map(|&i| {
                let target = &points[i];
                let mut rng = point_rng(PROBE_SEED, i as u64);
                let frame = target.point.turned_frame(&mut rng);
                let mut trace = TraceStats::default();
                let distances: Vec<f64> = transport
                    .hemisphere_first_segments(
                        &target.point,
                        &frame,
                        &set.directions,
                        options.paths,
                        &mut trace,
                    )
                    .iter()
                    .map(|s| s.distance())
                    .collect();
                (awaiting_record(target, &distances, limits), trace.rays)
            })
            .collect();
        for (record, rays) in records {
            cache.insert_awaiting_values(record)?;
            found.records += 1;
            found.rays += rays;
        }
    }
    Ok(found)
}

//! The irradiance cache shared by all requests for one (scene, estimator
//! configuration): insertion with the neighbour clamp, Ward-weighted lookup
//! with gradients, a byte budget with FIFO eviction, and statistics.
//!
//! # Eviction policy
//! Oldest first (FIFO by insertion): when an insertion takes the accounted
//! bytes above `byte_budget`, the oldest records are removed until it fits.
//! Old records are the ones placed by earlier requests, often for views no
//! longer rendered; FIFO is deterministic given the insertion order, which
//! the reproducible placement pass fixes (see `placement`). Each record
//! accounts [`RECORD_BYTES`]: the record, its id and its queue entry
//! (hash-map buckets of cells are not counted; there are at most as many
//! cells as records).
//!
//! # Concurrency
//! Lookups take no lock: they read the index's published shard snapshots
//! and bump atomic counters. Insertions, evictions and `clear` serialise on
//! one mutex (the FIFO and the record/byte counters), inside which the index
//! publishes one changed shard at a time; so
//! `records = inserts − evictions − cleared` holds whenever the stats are read.

use std::collections::VecDeque;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use serde::Serialize;

use super::error::{CacheError, positive};
use super::index::{CellKey, SpatialIndex};
use super::record::{RadiusLimits, Record};
use crate::render::{QueryPoint, Rgb};

/// Bytes accounted per record (module docs).
pub const RECORD_BYTES: usize = std::mem::size_of::<Record>()
    + std::mem::size_of::<u64>()
    + std::mem::size_of::<(u64, CellKey)>();

/// Weights are capped here so that a lookup exactly at a record (weight ∞)
/// still forms a finite weighted mean, dominated by that record.
const WEIGHT_CAP: f64 = 1e12;

/// Cache settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct CacheConfig {
    /// Upper bound of the accounted record bytes (≥ [`RECORD_BYTES`]).
    pub byte_budget: usize,
    /// Smallest and largest validity radius, world units.
    pub min_radius: f64,
    pub max_radius: f64,
    /// Records whose normal makes `n·n_k` below this are never used
    /// (default `cos 25°`); Ward's weight alone would allow 90° at `a = 1`.
    pub min_normal_cos: f64,
    /// Ward's "in front" test: a record is rejected when
    /// `d_k = (x − x_k)·(n + n_k)/2 < −front_tolerance · R_k`. Relative to
    /// `R_k` rather than Ward's absolute 0.05 so that it is scale-free.
    pub front_tolerance: f64,
    /// Křivánek et al. 2006 neighbour clamp on insertion:
    /// `R_new ≤ min_j (R_j + |x_new − x_j|)` over the records `j` whose
    /// validity sphere contains `x_new` with a compatible normal, so radii
    /// cannot jump between neighbours. Records already stored are not changed.
    pub neighbour_clamp: bool,
}

impl Default for CacheConfig {
    fn default() -> Self {
        Self {
            byte_budget: 64 << 20,
            min_radius: 1e-3,
            max_radius: 1.0,
            min_normal_cos: 25f64.to_radians().cos(),
            front_tolerance: 0.05,
            neighbour_clamp: true,
        }
    }
}

impl CacheConfig {
    pub fn validate(&self) -> Result<RadiusLimits, CacheError> {
        if self.byte_budget < RECORD_BYTES {
            return Err(CacheError::invalid(
                "byte_budget",
                format!(
                    "must hold at least one record ({RECORD_BYTES} bytes), got {}",
                    self.byte_budget
                ),
            ));
        }
        if !(self.min_normal_cos.is_finite() && (-1.0..=1.0).contains(&self.min_normal_cos)) {
            return Err(CacheError::invalid(
                "min_normal_cos",
                format!("must be in [-1, 1], got {}", self.min_normal_cos),
            ));
        }
        if !(self.front_tolerance.is_finite() && self.front_tolerance >= 0.0) {
            return Err(CacheError::invalid(
                "front_tolerance",
                format!("must be finite and >= 0, got {}", self.front_tolerance),
            ));
        }
        RadiusLimits::new(self.min_radius, self.max_radius)
    }
}

/// Ward's accuracy `a ∈ (0, 1]`: records are used where `w_k > 1/a`, i.e.
/// within `a R_k` (smaller = more records, more accurate).
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Serialize)]
pub struct Accuracy(f64);

impl Accuracy {
    pub fn new(a: f64) -> Result<Self, CacheError> {
        positive("accuracy", a)?;
        if a > 1.0 {
            return Err(CacheError::invalid(
                "accuracy",
                format!("must be in (0, 1], got {a}"),
            ));
        }
        Ok(Self(a))
    }

    pub fn value(self) -> f64 {
        self.0
    }
}

/// Irradiance interpolated from records.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interpolated {
    /// `Σ w_k E_k(x, n) / Σ w_k` with gradient-extrapolated `E_k(x, n)`, W/m².
    pub irradiance: Rgb,
    /// `Σ w_k² V_k / (Σ w_k)²`: the posterior variance of that weighted mean
    /// if the records' errors are independent; interpolation error is not
    /// included.
    pub variance: Rgb,
    /// `Σ w_k (E_k(x, n) − E)² / Σ w_k`: how much the records' own
    /// predictions at the point disagree about it (0 with one record).
    pub spread: Rgb,
    pub records_used: usize,
    /// `1 / Σ w_k`: how far the point is from the records that cover it, in
    /// validity radii (Ward's `ε`, the harmonic mean over the records used
    /// divided by their count), at most the lookup's accuracy; near 0 at a
    /// record's own place.
    pub reach: f64,
}

impl Interpolated {
    /// The variance of the interpolated irradiance as an estimate of the
    /// true one, (W/m²)²: the records' own [`Self::variance`] plus their
    /// disagreement [`Self::spread`], which stands in for the interpolation
    /// error the first leaves out (docs/math.md §16.3).
    pub fn error_variance(&self) -> Rgb {
        self.variance + self.spread
    }
}

/// Counters, serialisable for the service's stats endpoint. `records =
/// inserts − evictions − cleared` always holds; `hits + misses = lookups`
/// holds whenever no lookup is in flight.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CacheStats {
    pub records: u64,
    pub bytes: u64,
    pub byte_budget: u64,
    pub inserts: u64,
    pub evictions: u64,
    /// Records dropped by `clear`.
    pub cleared: u64,
    pub lookups: u64,
    pub hits: u64,
    pub misses: u64,
}

/// Where [`IrradianceCache::insert_awaiting_values`] put a record.
#[derive(Clone, Copy, Debug)]
pub struct RecordSlot {
    id: u64,
    key: CellKey,
}

#[derive(Debug, Default)]
struct Ledger {
    order: VecDeque<(u64, CellKey)>,
    next_id: u64,
    inserts: u64,
    evictions: u64,
    cleared: u64,
}

/// The cache (module docs).
#[derive(Debug)]
pub struct IrradianceCache {
    config: CacheConfig,
    limits: RadiusLimits,
    index: SpatialIndex,
    ledger: Mutex<Ledger>,
    lookups: AtomicU64,
    hits: AtomicU64,
    misses: AtomicU64,
}

impl IrradianceCache {
    pub fn new(config: CacheConfig) -> Result<Self, CacheError> {
        let limits = config.validate()?;
        Ok(Self {
            config,
            limits,
            index: SpatialIndex::new(limits.min, limits.max),
            ledger: Mutex::new(Ledger::default()),
            lookups: AtomicU64::new(0),
            hits: AtomicU64::new(0),
            misses: AtomicU64::new(0),
        })
    }

    pub fn config(&self) -> &CacheConfig {
        &self.config
    }

    /// The cache's radius limits (records are clamped to them on insertion).
    pub fn radius_limits(&self) -> RadiusLimits {
        self.limits
    }

    fn ledger(&self) -> std::sync::MutexGuard<'_, Ledger> {
        // Ledger updates are plain field writes; a panic cannot tear them.
        self.ledger.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn compatible(&self, r: &Record, x: DVec3, n: DVec3) -> bool {
        n.dot(r.normal) >= self.config.min_normal_cos
            && r.front_distance(x, n) >= -self.config.front_tolerance * r.radius
    }

    /// Insert a record (radius clamped to the limits and, if configured, by
    /// the neighbour clamp), evicting the oldest records beyond the byte
    /// budget. Returns the record as stored.
    pub fn insert(&self, record: Record) -> Result<Record, CacheError> {
        self.insert_slot(record).map(|(_, stored)| stored)
    }

    /// [`Self::insert`] of a record whose values (irradiance, variance,
    /// gradients) are not known yet; [`Self::fill_values`] sets them later.
    /// Everything insertion decides (radius, neighbour clamp, eviction)
    /// depends on position, normal and radius only, so inserting first and
    /// filling later leaves the cache as inserting the finished record
    /// would. Until then lookups see the record with the values it was
    /// given: only for a cache no one else reads, whose caller asks only
    /// whether a point is covered (the placement pass).
    pub fn insert_awaiting_values(&self, record: Record) -> Result<RecordSlot, CacheError> {
        self.insert_slot(record).map(|(slot, _)| slot)
    }

    /// Sets the values of the record inserted at `slot` from `values` (its
    /// position, normal and radius are kept); `Ok(false)` if it was evicted
    /// meanwhile.
    pub fn fill_values(&self, slot: RecordSlot, values: &Record) -> Result<bool, CacheError> {
        values.validate()?;
        let Some(stored) = self.index.get(slot.key, slot.id) else {
            return Ok(false);
        };
        let filled = Record {
            irradiance: values.irradiance,
            variance: values.variance,
            rotation_gradient: values.rotation_gradient,
            translation_gradient: values.translation_gradient,
            ..stored
        };
        Ok(self.index.replace(slot.key, slot.id, filled))
    }

    fn insert_slot(&self, mut record: Record) -> Result<(RecordSlot, Record), CacheError> {
        record.validate()?;
        record.radius = self.limits.clamp(record.radius);
        if self.config.neighbour_clamp {
            let (x, n) = (record.position, record.normal);
            let mut radius = record.radius;
            self.index.for_each_near(x, 1.0, |r| {
                if self.compatible(r, x, n) {
                    radius = radius.min(r.radius + (x - r.position).length());
                }
            });
            record.radius = self.limits.clamp(radius);
        }
        let mut ledger = self.ledger();
        let id = ledger.next_id;
        ledger.next_id += 1;
        let key = self.index.insert(id, record);
        ledger.order.push_back((id, key));
        ledger.inserts += 1;
        while ledger.order.len() * RECORD_BYTES > self.config.byte_budget {
            let Some((old, key)) = ledger.order.pop_front() else {
                break;
            };
            self.index.remove(key, old);
            ledger.evictions += 1;
        }
        Ok((RecordSlot { id, key }, record))
    }

    /// Interpolated irradiance at `point`, or `None` (a miss) when no record
    /// passes Ward's criterion `w_k > 1/a`, the normal threshold and the
    /// in-front test.
    pub fn lookup(&self, point: &QueryPoint, accuracy: Accuracy) -> Option<Interpolated> {
        self.lookup_filtered(point, accuracy, |_| true)
    }

    /// [`Self::lookup`] with an extra test per candidate record, applied last
    /// (e.g. a shadow ray between the point and the record against light
    /// leaks, see `placement`).
    pub fn lookup_filtered(
        &self,
        point: &QueryPoint,
        accuracy: Accuracy,
        accept: impl Fn(&Record) -> bool,
    ) -> Option<Interpolated> {
        let (x, n, a) = (point.position(), point.normal(), accuracy.value());
        let (mut sum_w, mut sum_e, mut sum_e2, mut sum_v, mut used) =
            (0.0, Rgb::BLACK, Rgb::BLACK, Rgb::BLACK, 0);
        self.index.for_each_near(x, a, |r| {
            if !self.compatible(r, x, n) {
                return;
            }
            let w = r.weight(x, n);
            if w > 1.0 / a && accept(r) {
                let w = w.min(WEIGHT_CAP);
                sum_w += w;
                let e = r.extrapolate(x, n);
                sum_e += e * w;
                sum_e2 += e * e * w;
                sum_v += r.variance * (w * w);
                used += 1;
            }
        });
        self.lookups.fetch_add(1, Ordering::Relaxed);
        if used == 0 {
            self.misses.fetch_add(1, Ordering::Relaxed);
            return None;
        }
        self.hits.fetch_add(1, Ordering::Relaxed);
        let mean = sum_e / sum_w;
        let spread = (sum_e2 / sum_w - mean * mean)
            .to_array()
            .map(|v| v.max(0.0));
        Some(Interpolated {
            irradiance: mean,
            variance: sum_v / (sum_w * sum_w),
            spread: Rgb::new(spread[0], spread[1], spread[2]),
            records_used: used,
            reach: 1.0 / sum_w,
        })
    }

    /// Every stored record, oldest first.
    pub fn records(&self) -> Vec<Record> {
        let ledger = self.ledger();
        ledger
            .order
            .iter()
            .filter_map(|(id, key)| self.index.get(*key, *id))
            .collect()
    }

    /// Drop every record (counters other than `records`/`bytes` are kept).
    pub fn clear(&self) {
        let mut ledger = self.ledger();
        ledger.cleared += ledger.order.len() as u64;
        ledger.order.clear();
        self.index.clear();
    }

    pub fn stats(&self) -> CacheStats {
        let ledger = self.ledger();
        let records = ledger.order.len() as u64;
        CacheStats {
            records,
            bytes: records * RECORD_BYTES as u64,
            byte_budget: self.config.byte_budget as u64,
            inserts: ledger.inserts,
            evictions: ledger.evictions,
            cleared: ledger.cleared,
            lookups: self.lookups.load(Ordering::Relaxed),
            hits: self.hits.load(Ordering::Relaxed),
            misses: self.misses.load(Ordering::Relaxed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(position: DVec3, normal: DVec3, e: f64, radius: f64) -> Record {
        Record {
            position,
            normal,
            irradiance: Rgb::new(e, 2.0 * e, 3.0 * e),
            variance: Rgb::splat(0.01 * e),
            radius,
            rotation_gradient: [DVec3::new(0.3, -0.2, 0.0); 3],
            translation_gradient: [DVec3::new(0.5, 0.0, 0.1); 3],
        }
    }

    fn point(x: DVec3, n: DVec3) -> QueryPoint {
        QueryPoint::new(x, n).unwrap()
    }

    fn cache(byte_budget: usize) -> IrradianceCache {
        IrradianceCache::new(CacheConfig {
            byte_budget,
            min_radius: 0.01,
            max_radius: 1.0,
            neighbour_clamp: false,
            ..CacheConfig::default()
        })
        .unwrap()
    }

    #[test]
    fn a_record_is_returned_at_its_own_position() {
        let c = cache(1 << 20);
        let a = Accuracy::new(0.5).unwrap();
        let r = record(DVec3::new(0.1, -1.0, 0.2), DVec3::Y, 1.5, 0.2);
        c.insert(r).unwrap();
        // A neighbour that also covers the point barely moves the result.
        c.insert(record(DVec3::new(0.15, -1.0, 0.2), DVec3::Y, 9.0, 0.2))
            .unwrap();
        let got = c.lookup(&point(r.position, r.normal), a).unwrap();
        assert_eq!(got.records_used, 2);
        for (g, e) in got
            .irradiance
            .to_array()
            .iter()
            .zip(r.irradiance.to_array())
        {
            assert!((g - e).abs() < 1e-9 * e, "{g} vs {e}");
        }
        assert!((got.variance.r - r.variance.r).abs() < 1e-9);
    }

    #[test]
    fn weighted_mean_of_two_records() {
        let c = cache(1 << 20);
        let mut r1 = record(DVec3::ZERO, DVec3::Z, 1.0, 1.0);
        let mut r2 = record(DVec3::X * 0.2, DVec3::Z, 2.0, 1.0);
        for r in [&mut r1, &mut r2] {
            r.rotation_gradient = [DVec3::ZERO; 3];
            r.translation_gradient = [DVec3::ZERO; 3];
            c.insert(*r).unwrap();
        }
        // At x = 0.05: w1 = 1/0.05 = 20, w2 = 1/0.15.
        let got = c
            .lookup(
                &point(DVec3::X * 0.05, DVec3::Z),
                Accuracy::new(1.0).unwrap(),
            )
            .unwrap();
        let (w1, w2) = (20.0, 1.0 / 0.15);
        assert!((got.irradiance.r - (w1 + 2.0 * w2) / (w1 + w2)).abs() < 1e-12);
        let v = (w1 * w1 * 0.01 + w2 * w2 * 0.02) / ((w1 + w2) * (w1 + w2));
        assert!((got.variance.r - v).abs() < 1e-12);
        // With a = 0.1 only records within 0.1 R_k count and w > 10.
        let got = c
            .lookup(
                &point(DVec3::X * 0.05, DVec3::Z),
                Accuracy::new(0.1).unwrap(),
            )
            .unwrap();
        assert_eq!(got.records_used, 1);
    }

    #[test]
    fn records_are_rejected_across_a_normal_discontinuity() {
        let c = cache(1 << 20);
        // A floor record at a corner; the wall at x = 0 faces +x.
        let floor = record(DVec3::new(0.02, 0.0, 0.0), DVec3::Y, 1.0, 0.5);
        c.insert(floor).unwrap();
        let a = Accuracy::new(1.0).unwrap();
        assert!(
            c.lookup(&point(DVec3::new(0.0, 0.02, 0.0), DVec3::X), a)
                .is_none()
        );
        // Slightly tilted normals are still fine.
        let tilted = DVec3::new(0.1, 1.0, 0.0).normalize();
        assert!(
            c.lookup(&point(DVec3::new(0.03, 0.0, 0.0), tilted), a)
                .is_some()
        );
        // Facing away.
        assert!(c.lookup(&point(floor.position, -DVec3::Y), a).is_none());
    }

    #[test]
    fn records_in_front_of_the_point_are_rejected() {
        let c = cache(1 << 20);
        // A record on a raised step; the point lies on the floor below it.
        let step = record(DVec3::new(0.0, 0.1, 0.0), DVec3::Y, 1.0, 0.5);
        c.insert(step).unwrap();
        let a = Accuracy::new(1.0).unwrap();
        assert!(
            c.lookup(&point(DVec3::new(0.05, 0.0, 0.0), DVec3::Y), a)
                .is_none()
        );
        // A point slightly above the record's plane may use it.
        assert!(
            c.lookup(&point(DVec3::new(0.05, 0.12, 0.0), DVec3::Y), a)
                .is_some()
        );
        let stats = c.stats();
        assert_eq!((stats.lookups, stats.hits, stats.misses), (2, 1, 1));
    }

    #[test]
    fn byte_budget_is_respected_by_evicting_the_oldest() {
        let budget = 10 * RECORD_BYTES + RECORD_BYTES / 2;
        let c = cache(budget);
        for i in 0..25 {
            c.insert(record(DVec3::X * i as f64, DVec3::Z, 1.0 + i as f64, 0.1))
                .unwrap();
            assert!(c.stats().bytes <= budget as u64);
        }
        let s = c.stats();
        assert_eq!(s.records, 10);
        assert_eq!(s.inserts, 25);
        assert_eq!(s.evictions, 15);
        let kept: Vec<f64> = c.records().iter().map(|r| r.position.x).collect();
        assert_eq!(kept, (15..25).map(f64::from).collect::<Vec<_>>());
        let a = Accuracy::new(1.0).unwrap();
        assert!(c.lookup(&point(DVec3::ZERO, DVec3::Z), a).is_none());
        assert!(c.lookup(&point(DVec3::X * 24.0, DVec3::Z), a).is_some());
        c.clear();
        let s = c.stats();
        assert_eq!((s.records, s.bytes, s.cleared), (0, 0, 10));
        assert!(c.lookup(&point(DVec3::X * 24.0, DVec3::Z), a).is_none());
    }

    #[test]
    fn neighbour_clamp_limits_radius_jumps() {
        let c = IrradianceCache::new(CacheConfig {
            min_radius: 0.01,
            max_radius: 1.0,
            ..CacheConfig::default()
        })
        .unwrap();
        c.insert(record(DVec3::ZERO, DVec3::Z, 1.0, 0.05)).unwrap();
        let stored = c
            .insert(record(DVec3::X * 0.02, DVec3::Z, 1.0, 0.8))
            .unwrap();
        assert!((stored.radius - 0.07).abs() < 1e-12);
        // Far away: unclamped.
        let stored = c
            .insert(record(DVec3::X * 5.0, DVec3::Z, 1.0, 0.8))
            .unwrap();
        assert_eq!(stored.radius, 0.8);
    }

    #[test]
    fn concurrent_inserts_and_lookups_keep_counts_consistent() {
        let budget = 3000 * RECORD_BYTES;
        let c = cache(budget);
        let per_thread = 500;
        std::thread::scope(|s| {
            for t in 0..8 {
                let c = &c;
                s.spawn(move || {
                    let a = Accuracy::new(0.8).unwrap();
                    for i in 0..per_thread {
                        let x = DVec3::new(t as f64, i as f64 * 0.01, 0.0);
                        c.insert(record(x, DVec3::Z, 1.0, 0.02)).unwrap();
                        let _ = c.lookup(&point(x + DVec3::X * 0.5, DVec3::Z), a);
                        let _ = c.lookup(&point(x, DVec3::Z), a);
                    }
                });
            }
        });
        let s = c.stats();
        assert_eq!(s.inserts, 8 * per_thread);
        assert_eq!(s.records, s.inserts - s.evictions);
        assert_eq!(s.records, 3000);
        assert_eq!(s.lookups, 2 * 8 * per_thread);
        assert_eq!(s.hits + s.misses, s.lookups);
        // Every lookup at a just-inserted record's position that was not yet
        // evicted hits; the ones half a unit away never do.
        assert!(s.hits >= 8 * per_thread - s.evictions);
        assert!(s.misses >= 8 * per_thread);
        let stored = c.records();
        assert_eq!(stored.len() as u64, s.records);
        assert!(s.bytes <= budget as u64);
    }

    /// Without evictions no concurrent insertion is lost: every record is
    /// stored once and found at its own position.
    #[test]
    fn concurrent_inserts_lose_nothing() {
        let c = cache(1 << 24);
        std::thread::scope(|s| {
            for t in 0..8 {
                let c = &c;
                s.spawn(move || {
                    for i in 0..400 {
                        let x = DVec3::new(i as f64 * 0.05, t as f64 * 0.05, 0.0);
                        c.insert(record(x, DVec3::Z, 1.0 + t as f64, 0.01)).unwrap();
                    }
                });
            }
        });
        let s = c.stats();
        assert_eq!((s.records, s.inserts, s.evictions), (3200, 3200, 0));
        let mut keys: Vec<(i64, i64)> = c
            .records()
            .iter()
            .map(|r| {
                (
                    (r.position.x * 20.0).round() as i64,
                    (r.position.y * 20.0).round() as i64,
                )
            })
            .collect();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), 3200);
        let a = Accuracy::new(0.5).unwrap();
        for t in 0..8 {
            for i in (0..400).step_by(37) {
                let x = DVec3::new(i as f64 * 0.05, t as f64 * 0.05, 0.0);
                let got = c.lookup(&point(x, DVec3::Z), a).unwrap();
                assert_eq!(got.records_used, 1);
                assert!((got.irradiance.r - (1.0 + t as f64)).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn bad_configuration_and_records_are_typed_errors() {
        let bad = |cfg: CacheConfig| IrradianceCache::new(cfg).unwrap_err();
        let d = CacheConfig::default();
        assert_eq!(
            bad(CacheConfig {
                byte_budget: 1,
                ..d
            })
            .field(),
            Some("byte_budget")
        );
        assert_eq!(
            bad(CacheConfig {
                min_radius: -1.0,
                ..d
            })
            .field(),
            Some("min_radius")
        );
        assert_eq!(
            bad(CacheConfig {
                max_radius: f64::NAN,
                ..d
            })
            .field(),
            Some("max_radius")
        );
        assert_eq!(
            bad(CacheConfig {
                min_normal_cos: 2.0,
                ..d
            })
            .field(),
            Some("min_normal_cos")
        );
        assert_eq!(Accuracy::new(0.0).unwrap_err().field(), Some("accuracy"));
        assert_eq!(Accuracy::new(1.5).unwrap_err().field(), Some("accuracy"));
        let c = cache(1 << 20);
        let mut r = record(DVec3::ZERO, DVec3::Z, 1.0, 0.1);
        r.normal = DVec3::new(0.0, 0.0, 2.0);
        assert_eq!(c.insert(r).unwrap_err().field(), Some("normal"));
        assert_eq!(c.stats().inserts, 0);
    }
}

//! Concurrent spatial index over records: which records' validity spheres
//! contain a point.
//!
//! # Design
//! A multi-level hash grid (a flattened octree): level `L` has cubic cells of
//! side `h_L = min_radius · 2^L`, up to the first level with `h_L ≥ max_radius`.
//! A record of radius `R` lives in one cell — the one containing its position
//! at the finest level with `h_L ≥ R` — so every point within `R` of it lies
//! in that cell or one of its 26 neighbours, and a query visits 27 cells per
//! occupied level. Records are stored by value in their cell.
//!
//! Cells are spread over [`SHARDS`] hash maps by a hash of the cell key;
//! the shards are immutable snapshots, and the array of them is published
//! whole behind one [`ArcSwap`] (read-copy-update). Readers never lock and
//! never write to shared memory: loading the snapshot uses a per-thread
//! slot, so two threads scanning the same cells do not bounce a lock's
//! cache line between cores (with `RwLock`ed shards that was 29 % of a warm
//! cached render, docs/BENCHMARKS.md), and a query loads it once for all the
//! cells it visits (one load per cell was 7 % of a cold preview render). A
//! writer copies one shard's map (cells are `Arc`ed, so that copies one
//! pointer per cell), the one cell it changes and the array of shard
//! pointers, and publishes the copy; writers serialise on a mutex. Readers
//! therefore never wait, and a query sees the index as it was before or
//! after any one write.
//!
//! A cell keeps its records' validity spheres (centre and radius, 32 bytes)
//! apart from the records themselves (about 250 bytes): a query tests every
//! sphere of the cells it visits and reads only the records inside.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use arc_swap::ArcSwap;
use glam::DVec3;

use super::record::Record;

/// Number of shards: a write copies one shard's map, so more shards make
/// writes cheaper.
pub const SHARDS: usize = 64;

/// Identity of a grid cell: level and integer coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CellKey {
    level: u8,
    cell: [i64; 3],
}

/// One cell's records and, in the same order, their validity spheres
/// (position, radius), so the distance test reads 32 bytes per record.
#[derive(Debug)]
struct Cell {
    spheres: Box<[[f64; 4]]>,
    records: Box<[(u64, Record)]>,
}

impl Cell {
    fn new(records: Vec<(u64, Record)>) -> Cell {
        let spheres = records
            .iter()
            .map(|(_, r)| [r.position.x, r.position.y, r.position.z, r.radius])
            .collect();
        Cell {
            spheres,
            records: records.into(),
        }
    }
}

/// Cells hashed with foldhash's fixed-seed hasher: lookups hash up to 8 keys
/// per occupied level, and SipHash (std's default, DoS-resistant) was a
/// sixth of a cached render's time, FNV (one multiply per key byte) still
/// 2.5 % of the cold final preset; the keys are cell coordinates, not
/// attacker-chosen strings.
type Shard = HashMap<CellKey, Arc<Cell>, foldhash::fast::FixedState>;

/// The index (module docs). Record ids are chosen by the caller and unique.
#[derive(Debug)]
pub struct SpatialIndex {
    finest: f64,
    levels: usize,
    shards: ArcSwap<Vec<Arc<Shard>>>,
    /// Held by every write (copy, change, publish) so none is lost.
    writer: Mutex<()>,
    /// Records per level, so queries skip empty levels.
    occupancy: Vec<AtomicUsize>,
}

impl SpatialIndex {
    /// Levels from cell size `min_radius` to the first `≥ max_radius`
    /// (`0 < min_radius ≤ max_radius`, validated by the cache's config).
    pub fn new(min_radius: f64, max_radius: f64) -> Self {
        let levels = ((max_radius / min_radius).log2().ceil().max(0.0) as usize + 1).min(64);
        Self {
            finest: min_radius,
            levels,
            shards: ArcSwap::from_pointee(empty_shards()),
            writer: Mutex::new(()),
            occupancy: (0..levels).map(|_| AtomicUsize::new(0)).collect(),
        }
    }

    fn level_for(&self, radius: f64) -> usize {
        let l = (radius / self.finest).log2().ceil();
        if l.is_nan() || l <= 0.0 {
            0
        } else {
            (l as usize).min(self.levels - 1)
        }
    }

    fn key(&self, level: usize, x: DVec3) -> CellKey {
        let h = self.finest * f64::powi(2.0, level as i32);
        let c = (x / h).floor();
        // `as` saturates far outside the scene; those cells just collide.
        CellKey {
            level: level as u8,
            cell: [c.x as i64, c.y as i64, c.z as i64],
        }
    }

    fn shard(&self, key: &CellKey) -> usize {
        // FNV-1a over the key's words: cheap and spreads neighbouring cells.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for w in [key.level as i64, key.cell[0], key.cell[1], key.cell[2]] {
            h = (h ^ w as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
        (h >> 7) as usize % SHARDS
    }

    fn writer(&self) -> MutexGuard<'_, ()> {
        // The guarded data is the shards, each replaced whole by one store.
        self.writer.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Replace cell `key` by `change(old cell)` (`None` removes it).
    fn update_cell(
        &self,
        key: CellKey,
        change: impl FnOnce(&[(u64, Record)]) -> Option<Vec<(u64, Record)>>,
    ) {
        let index = self.shard(&key);
        let mut shards = Vec::clone(&self.shards.load());
        let mut copy = Shard::clone(&shards[index]);
        let old = copy.get(&key).map_or(&[][..], |c| &c.records[..]);
        match change(old) {
            Some(cell) => {
                copy.insert(key, Arc::new(Cell::new(cell)));
            }
            None => {
                copy.remove(&key);
            }
        }
        shards[index] = Arc::new(copy);
        self.shards.store(Arc::new(shards));
    }

    /// Store `record` under `id`; returns the cell it went to.
    pub fn insert(&self, id: u64, record: Record) -> CellKey {
        let level = self.level_for(record.radius);
        let key = self.key(level, record.position);
        let _writer = self.writer();
        self.update_cell(key, |old| {
            let mut cell = old.to_vec();
            cell.push((id, record));
            Some(cell)
        });
        self.occupancy[level].fetch_add(1, Ordering::Relaxed);
        key
    }

    /// Remove record `id` from cell `key`; whether it was there.
    pub fn remove(&self, key: CellKey, id: u64) -> bool {
        let _writer = self.writer();
        let present = self.shards.load()[self.shard(&key)]
            .get(&key)
            .is_some_and(|c| c.records.iter().any(|(rid, _)| *rid == id));
        if !present {
            return false;
        }
        self.update_cell(key, |old| {
            let cell: Vec<_> = old.iter().filter(|(rid, _)| *rid != id).copied().collect();
            (!cell.is_empty()).then_some(cell)
        });
        self.occupancy[key.level as usize].fetch_sub(1, Ordering::Relaxed);
        true
    }

    /// Replace record `id` in cell `key` by `record` (same position and
    /// radius, so the same cell); whether it was there.
    pub fn replace(&self, key: CellKey, id: u64, record: Record) -> bool {
        let _writer = self.writer();
        let present = self.shards.load()[self.shard(&key)]
            .get(&key)
            .is_some_and(|c| c.records.iter().any(|(rid, _)| *rid == id));
        if present {
            self.update_cell(key, |old| {
                let cell = old
                    .iter()
                    .map(|&(rid, r)| (rid, if rid == id { record } else { r }));
                Some(cell.collect())
            });
        }
        present
    }

    /// Record `id` in cell `key`, if present.
    pub fn get(&self, key: CellKey, id: u64) -> Option<Record> {
        self.shards.load()[self.shard(&key)]
            .get(&key)?
            .records
            .iter()
            .find(|(rid, _)| *rid == id)
            .map(|(_, r)| *r)
    }

    /// Calls `f` for every record with `|x − x_k| < scale · R_k`
    /// (`0 < scale ≤ 1`; Ward's `w_k > 1/a` implies this with `scale = a`).
    pub fn for_each_near(&self, x: DVec3, scale: f64, mut f: impl FnMut(&Record)) {
        let shards = self.shards.load();
        for level in 0..self.levels {
            if self.occupancy[level].load(Ordering::Relaxed) == 0 {
                continue;
            }
            // A record found must lie within `scale · R ≤ scale · h` of `x`,
            // so only the cells overlapping that cube can hold it: 1 or 2
            // per axis for `scale ≤ 1/2`, at most 3.
            let h = self.finest * f64::powi(2.0, level as i32);
            let reach = DVec3::splat(scale.clamp(0.0, 1.0) * h);
            let lo = self.key(level, x - reach);
            let hi = self.key(level, x + reach);
            for cx in lo.cell[0]..=hi.cell[0] {
                for cy in lo.cell[1]..=hi.cell[1] {
                    for cz in lo.cell[2]..=hi.cell[2] {
                        let key = CellKey {
                            level: lo.level,
                            cell: [cx, cy, cz],
                        };
                        let Some(cell) = shards[self.shard(&key)].get(&key) else {
                            continue;
                        };
                        for (sphere, (_, r)) in cell.spheres.iter().zip(&cell.records[..]) {
                            let centre = DVec3::new(sphere[0], sphere[1], sphere[2]);
                            if within(x - centre, scale * sphere[3]) {
                                f(r);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Drop every record.
    pub fn clear(&self) {
        let _writer = self.writer();
        self.shards.store(Arc::new(empty_shards()));
        for level in &self.occupancy {
            level.store(0, Ordering::Relaxed);
        }
    }
}

fn empty_shards() -> Vec<Arc<Shard>> {
    (0..SHARDS).map(|_| Arc::default()).collect()
}

/// `d.length() < reach`, decided without the square root unless `|d|²` is
/// within a relative 2⁻⁴⁰ of `reach²` (far more than the few ulps by which
/// the two forms can round apart), so the answer is that of the exact form.
#[inline(always)]
fn within(d: DVec3, reach: f64) -> bool {
    const SLACK: f64 = 1.0 / 1_099_511_627_776.0;
    let (d2, r2) = (d.length_squared(), reach * reach);
    if d2 < r2 * (1.0 - SLACK) {
        true
    } else if d2 > r2 * (1.0 + SLACK) {
        false
    } else {
        d.length() < reach
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Rgb;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    fn record(position: DVec3, radius: f64) -> Record {
        Record {
            position,
            normal: DVec3::Z,
            irradiance: Rgb::WHITE,
            variance: Rgb::BLACK,
            radius,
            rotation_gradient: [DVec3::ZERO; 3],
            translation_gradient: [DVec3::ZERO; 3],
        }
    }

    /// The distance test without a square root answers as the exact form,
    /// also for points on or next to the sphere (neighbouring f64 values).
    #[test]
    fn within_agrees_with_the_exact_distance_test() {
        let mut rng = Pcg64::seed_from_u64(3);
        for _ in 0..20_000 {
            let d = DVec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - 1.0;
            let d = d * 10f64.powi(rng.random_range(-6..6));
            let length = d.length();
            let mut reach = length;
            for _ in 0..4 {
                reach = reach.next_down();
            }
            for _ in 0..9 {
                assert_eq!(within(d, reach), length < reach, "{d} {reach}");
                reach = reach.next_up();
            }
            let far = length * (0.5 + rng.random::<f64>());
            assert_eq!(within(d, far), length < far);
        }
    }

    /// The index finds exactly what a linear scan finds.
    #[test]
    fn queries_match_brute_force() {
        let index = SpatialIndex::new(0.01, 1.0);
        let mut rng = Pcg64::seed_from_u64(7);
        let mut all = Vec::new();
        for id in 0..2000u64 {
            let p = DVec3::new(rng.random(), rng.random(), rng.random()) * 4.0 - 2.0;
            let r = 0.01 + rng.random::<f64>().powi(3) * 0.99;
            all.push((index.insert(id, record(p, r)), record(p, r), id));
        }
        for (i, (key, _, id)) in all.iter().enumerate() {
            if i % 3 == 0 {
                assert!(index.remove(*key, *id));
                assert!(!index.remove(*key, *id));
            }
        }
        for _ in 0..300 {
            let x = DVec3::new(rng.random(), rng.random(), rng.random()) * 4.0 - 2.0;
            let scale = 0.3 + 0.7 * rng.random::<f64>();
            let mut found = Vec::new();
            index.for_each_near(x, scale, |r| found.push(r.position.x));
            let mut expected: Vec<f64> = all
                .iter()
                .enumerate()
                .filter(|(i, (_, r, _))| i % 3 != 0 && (x - r.position).length() < scale * r.radius)
                .map(|(_, (_, r, _))| r.position.x)
                .collect();
            found.sort_by(f64::total_cmp);
            expected.sort_by(f64::total_cmp);
            assert_eq!(found, expected);
        }
        let (key, r, id) = all[1];
        assert_eq!(index.get(key, id), Some(r));
        index.clear();
        let mut n = 0;
        index.for_each_near(r.position, 1.0, |_| n += 1);
        assert_eq!(n, 0);
    }
}

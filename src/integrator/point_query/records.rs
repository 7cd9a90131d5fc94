//! Records entries held under content keys — reproducible tiles' records
//! and records placed among point queries' own points — as priors of point
//! queries (docs/math.md §10.10, §10.11).
//!
//! A [`RecordsStore`] holds records entries by content key: the service's
//! tile store, or [`HeldRecords`] in memory for one run of the command
//! line. A reproducible tile's records are a function of the scene's
//! content and the tile's request, and a replica holds the same ones
//! whether it computed them, merged them from another replica, loaded them
//! from its log after a restart or imported them. For point queries,
//! the records held for one scene content and one camera depth are gathered
//! into one cache, inserted in the order of their tiles' content keys, so a
//! query meets the same prior, bit for bit, wherever the same tiles are
//! held. A gathering is built once per set of entries held and kept
//! ([`PointRecords`]); its direct-light twins (§10.8) are made by the first
//! query that needs them, all with one rule ([`TWIN_DIRECTIONS`]).
//!
//! A query of at least [`MIN_POINTS_FOR_RECORDS`] points places records
//! among its own points (`integrator::cached::point_records`), and the
//! first such query of a scene content and depth among the calibration's
//! training points too, so the error bars are fitted on points with
//! records placed the same way (§10.11). Both are kept in the store under
//! content keys, like a tile's, and gathered with them.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use moka::sync::Cache;

use crate::bmc::cache::QuadratureCache;
use crate::cache::{CacheConfig, CacheError};
use crate::estimators::calibration::calibration_points;
use crate::integrator::cached::{
    CachedShading, CachedSpec, CachedTileReport, PriorSource, SceneCache, point_records,
};
use crate::integrator::progressive::TileRecords;
use crate::render::{Cancel, PathDepth, QueryPoint, RenderError, Transport};

/// A content key: BLAKE3 of a canonical description of what an entry
/// (records, a pass) depends on.
pub type Key = [u8; 32];

/// Records entries by content key.
pub trait RecordsStore: Sync {
    /// The entry `key`, placed by `place` unless held.
    fn records_or(
        &self,
        key: Key,
        place: impl FnOnce() -> Result<TileRecords, RenderError> + Send,
    ) -> Result<Arc<TileRecords>, RenderError>;

    /// Every entry held for the scene of content digest `scene`, in key order.
    fn records_of(&self, scene: &[u8; 32]) -> Vec<(Key, Arc<TileRecords>)>;
}

/// Records entries in memory, for as long as the value lives (one run of
/// the command line): the same entries a service holds after the same
/// queries on a fresh scene, so the same numbers.
#[derive(Default)]
pub struct HeldRecords {
    entries: Mutex<BTreeMap<Key, Arc<TileRecords>>>,
}

impl RecordsStore for HeldRecords {
    fn records_or(
        &self,
        key: Key,
        place: impl FnOnce() -> Result<TileRecords, RenderError> + Send,
    ) -> Result<Arc<TileRecords>, RenderError> {
        // One caller at a time: a run places each entry once.
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(held) = entries.get(&key) {
            return Ok(held.clone());
        }
        let placed = Arc::new(place()?);
        entries.insert(key, placed.clone());
        Ok(placed)
    }

    fn records_of(&self, scene: &[u8; 32]) -> Vec<(Key, Arc<TileRecords>)> {
        let entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries
            .iter()
            .filter(|(_, t)| &t.scene == scene)
            .map(|(key, t)| (*key, t.clone()))
            .collect()
    }
}

/// Directions of the rule that makes the gathered records' direct-light
/// twins: as many as the final preset's records have, with which the twins
/// were measured (docs/BENCHMARKS.md, direct-light records).
const TWIN_DIRECTIONS: usize = 1024;

/// Paths per direction of the records placed among the points of a query
/// with reflections (§10.11), on the twins' directions: on a sensor grid
/// those records are most of every point's prior and their paths' noise its
/// floor. Measured (docs/BENCHMARKS.md, stop 60): on the Cornell box's floor
/// grid default `bmc` at N = 256 was within 2.84 % nrmse with one path per
/// direction and 1.87 % with four.
const POINT_RECORD_PATHS: u32 = 4;

/// Fewest points of a query that places records among them (module docs):
/// below it, a record's thousand paths would serve too few points to pay.
pub const MIN_POINTS_FOR_RECORDS: usize = 64;

/// Seed of every record placed among query points (shared with no request,
/// so a request's seed changes its own samples, not the records).
const POINT_RECORDS_SEED: u64 = 0x9017_5EC0;

/// A scene's records as a store holds them, and the quadrature cache the
/// rules made for them use: what gathering and placing read.
pub struct SceneRecords<'a, S> {
    pub transport: &'a Transport,
    pub store: &'a S,
    pub quadratures: &'a Arc<QuadratureCache>,
}

// References only: copied whatever `S` is (a derive would ask `S: Copy`).
impl<S> Clone for SceneRecords<'_, S> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<S> Copy for SceneRecords<'_, S> {}

/// Gatherings of a store's records: reproducible tiles' and those placed
/// among query points (module docs).
pub struct PointRecords {
    /// By the content key of the scene, depth and entries gathered.
    gathered: Cache<Key, Arc<SceneCache>>,
    /// The byte budget of one gathering (its oldest tiles' records, in key
    /// order, are dropped beyond it).
    gathering_bytes: usize,
    /// The twins' rule and the point records' rule, built on first use.
    twin_rules: Mutex<Option<CachedShading>>,
    point_record_rules: Mutex<Option<CachedShading>>,
}

impl PointRecords {
    /// Gatherings of `gathering_bytes` each, `total_bytes` together.
    pub fn new(gathering_bytes: usize, total_bytes: u64) -> Self {
        Self {
            gathered: Cache::builder()
                .weigher(|_, gathering: &Arc<SceneCache>| {
                    u32::try_from(gathering.cache.stats().bytes).unwrap_or(u32::MAX)
                })
                .max_capacity(total_bytes)
                .build(),
            gathering_bytes,
            twin_rules: Mutex::new(None),
            point_record_rules: Mutex::new(None),
        }
    }

    /// The gatherings of the records entries the store holds for the
    /// scene's content (tiles' and query points'), one per camera depth.
    pub fn sources<S: RecordsStore>(
        &self,
        at: SceneRecords<S>,
    ) -> Result<Vec<PriorSource>, CacheError> {
        let SceneRecords {
            transport,
            store,
            quadratures,
        } = at;
        let digest = transport.scene().digest.as_bytes();
        let mut by_depth: BTreeMap<u32, Vec<_>> = BTreeMap::new();
        for (key, tile) in store.records_of(digest) {
            if !tile.records.is_empty() {
                by_depth
                    .entry(tile.max_depth.get())
                    .or_default()
                    .push((key, tile));
            }
        }
        let mut sources = Vec::with_capacity(by_depth.len());
        for (depth, tiles) in by_depth {
            let max_depth = tiles[0].1.max_depth;
            let mut hasher = blake3::Hasher::new();
            hasher.update(b"gathered tile records\0");
            hasher.update(digest);
            hasher.update(&depth.to_le_bytes());
            for (key, _) in &tiles {
                hasher.update(key);
            }
            let key = *hasher.finalize().as_bytes();
            let gathering = crate::isolated::try_get_with(&self.gathered, key, || {
                let config = CacheConfig {
                    byte_budget: self.gathering_bytes,
                    ..CacheConfig::default()
                };
                let description = serde_json::json!({
                    "gathered_tiles": tiles.len(),
                    "max_depth": depth,
                });
                let gathering =
                    SceneCache::new(config, self.twin_rules(quadratures)?, description)?;
                for (_, tile) in &tiles {
                    for record in &tile.records {
                        gathering.cache.insert(*record)?;
                    }
                }
                Ok::<_, CacheError>(Arc::new(gathering))
            })
            .map_err(|e: Arc<CacheError>| (*e).clone())?;
            sources.push(PriorSource::new(max_depth, gathering, "records"));
        }
        Ok(sources)
    }

    /// Places records among `points` (when there are at least
    /// [`MIN_POINTS_FOR_RECORDS`] and at most `max_records`) and among the
    /// calibration's training points, for queries of `from_point` segments
    /// from the point (at least 2, so a query of direct light only still
    /// leaves places for twins); each set once per scene content, kept in
    /// the store. Returns the rays traced now.
    pub fn place_among<S: RecordsStore>(
        &self,
        at: SceneRecords<S>,
        points: &[QueryPoint],
        from_point: PathDepth,
        max_records: usize,
        cancel: &Cancel,
    ) -> Result<u64, RenderError> {
        let SceneRecords {
            transport,
            store,
            quadratures,
        } = at;
        if points.len() < MIN_POINTS_FOR_RECORDS || points.len() > max_records {
            return Ok(0);
        }
        // A query of direct light only uses the records as places for twins,
        // and their values never: one path per direction is enough there.
        let (rules, paths) = if from_point.has_reflections() {
            (self.point_record_rules(quadratures)?, POINT_RECORD_PATHS)
        } else {
            (self.twin_rules(quadratures)?, 1)
        };
        let from_point = PathDepth::new(from_point.get().max(2))?;
        // Kept with the camera's depth convention: one segment more.
        let Ok(camera_depth) = PathDepth::new(from_point.get() + 1) else {
            return Ok(0);
        };
        let digest = *transport.scene().digest.as_bytes();
        let mut rays = 0;
        for set in [calibration_points(transport), points.to_vec()] {
            let mut hasher = blake3::Hasher::new();
            hasher.update(b"point records\0");
            hasher.update(env!("CARGO_PKG_VERSION").as_bytes());
            hasher.update(&digest);
            hasher.update(&from_point.get().to_le_bytes());
            hasher.update(&paths.to_le_bytes());
            for p in &set {
                for c in p
                    .position()
                    .to_array()
                    .into_iter()
                    .chain(p.normal().to_array())
                {
                    hasher.update(&c.to_le_bytes());
                }
            }
            let key = *hasher.finalize().as_bytes();
            store.records_or(key, || {
                let (records, placement) = point_records(
                    transport,
                    &rules,
                    &set,
                    from_point,
                    POINT_RECORDS_SEED,
                    cancel,
                )?;
                rays += placement.rays;
                Ok(TileRecords {
                    scene: digest,
                    max_depth: camera_depth,
                    records,
                    report: CachedTileReport {
                        placement,
                        ..CachedTileReport::default()
                    },
                })
            })?;
        }
        Ok(rays)
    }

    /// The rules every gathering's twins are made with.
    fn twin_rules(&self, quadratures: &Arc<QuadratureCache>) -> Result<CachedShading, CacheError> {
        let spec = CachedSpec {
            samples: Some(TWIN_DIRECTIONS),
            ..CachedSpec::default()
        };
        rules_of(&self.twin_rules, spec, quadratures)
    }

    /// The rules of the records placed among the points of a query with
    /// reflections: the twins' directions, [`POINT_RECORD_PATHS`] paths each.
    fn point_record_rules(
        &self,
        quadratures: &Arc<QuadratureCache>,
    ) -> Result<CachedShading, CacheError> {
        let spec = CachedSpec {
            samples: Some(TWIN_DIRECTIONS),
            paths_per_direction: Some(POINT_RECORD_PATHS),
            ..CachedSpec::default()
        };
        rules_of(&self.point_record_rules, spec, quadratures)
    }
}

/// The cached shading of `spec`, built into `slot` on first use.
fn rules_of(
    slot: &Mutex<Option<CachedShading>>,
    spec: CachedSpec,
    quadratures: &Arc<QuadratureCache>,
) -> Result<CachedShading, CacheError> {
    let mut rules = slot.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(rules) = rules.as_ref() {
        return Ok(rules.clone());
    }
    let built = spec.resolve()?.shading(quadratures.clone())?;
    *rules = Some(built.clone());
    Ok(built)
}

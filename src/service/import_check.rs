//! Imported records checked against the scene before they are added
//! (docs/math.md §9.8).
//!
//! An import is a claim about a scene: that its records are what this
//! release computes for it. Tiles shaded from them are served under the
//! ETags of computed tiles, here and on every replica (an added import
//! reaches the others through the shared store), so records scaled by
//! 1,000, which every per-record check passes (finite, non-negative, under
//! `MAX_IRRADIANCE`), made a tile 440× brighter under the genuine ETag.
//! Before an import is added, up to [`CHECKED_RECORDS`] of the records it
//! would add are compared with fresh estimates of what they hold, the
//! indirect irradiance at their place ([`FRESH_PATHS`] path-traced cosine
//! directions each), and the import is refused when more of them disagree
//! than genuine records would with a chance above [`FALSE_REFUSAL`].
//!
//! What the check is, and is not:
//! - It stops imports whose records are broadly wrong: all of them scaled,
//!   another scene's or another depth's values under this scene's digest,
//!   an exporter that wrote the wrong field. An import of genuine records
//!   (another run, another replica) is refused with a chance below
//!   [`FALSE_REFUSAL`].
//! - It is a sample. A genuine record can be many times its true value
//!   (one of its directions found a sun through a glossy bounce; measured
//!   up to 23× in docs/math.md §9.8), so no single record can be refused
//!   for its value alone, and an import of which a share `f` is forged is
//!   refused only when the check draws enough of them (with a chance of
//!   0.57 at `f = 30 %`, 0.97 at 40 %). A forger who changes a few records
//!   is not stopped by any sample; an import remains a matter of trust in
//!   its source, and the check keeps honest mistakes and wholesale
//!   forgeries out.
//! - Which records are checked is drawn from the import's bytes keyed with
//!   a secret this process draws at startup (`AppState::import_key`): the
//!   same import asked twice of one process is checked on the same records,
//!   and a forger cannot tell beforehand which ones will be. Each record's
//!   fresh estimate is seeded by its place, so a record gets the same
//!   estimate wherever and whenever it is checked.
//! - It costs at most `CHECKED_RECORDS × FRESH_PATHS` paths whatever the
//!   import's size, and runs on the CPU pool, stopping between records once
//!   the request is gone.
//!
//! Parts received from other replicas are not checked again: the shared
//! store is inside the cluster's trust (a writer there could change scenes
//! too), and an import reaches it only after this check.

use glam::DVec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use crate::cache::Record;
use crate::estimators::calibration::unseen_light;
use crate::integrator::cached::indirect_paths;
use crate::render::{Cancel, PathDepth, QueryPoint, RenderError, Rgb, TraceStats, Transport};
use crate::stats::binomial_upper_tail;

/// Records of an import checked against fresh estimates (all of them in an
/// import of fewer): enough that a wholly forged import is refused whatever
/// the scene, and that the binomial bound of docs/math.md §9.8 leaves room
/// between genuine imports (at most 18 of 64 may disagree) and forged ones.
pub const CHECKED_RECORDS: usize = 64;

/// Path-traced cosine directions of each fresh estimate: an import's check
/// traces at most 64 × 256 paths, whatever its size.
pub const FRESH_PATHS: u32 = 256;

/// Standard errors of a fresh estimate that the truth is taken to lie
/// within (docs/math.md §9.8).
const FRESH_SIGMAS: f64 = 3.0;

/// How far (a factor, above or below) a genuine record may be from the
/// truth before it counts as disagreeing: on the bundled scenes' draft to
/// final records all but 9 of 4,992 checked were within it (docs/math.md
/// §9.8). The records' own variances are no guide (docs/math.md §12.1,
/// §9.6: they leave out the paths' noise and the secondary cache's error,
/// and an import's author writes them).
const RECORD_FACTOR: f64 = 4.0;

/// The slack near zero, as a share of the scene's level: the floor of the
/// calibrated error bars (docs/math.md §10.5, `max(|Ê|, 0.05 Ē)`).
const LEVEL_FLOOR: f64 = 0.05;

/// The chance, at most, that a genuine record disagrees, assumed for the
/// bound: measured at most 1.3 % on any bundled scene and preset
/// (docs/math.md §9.8), so the bound holds with room to spare.
const GENUINE_DISAGREEMENT: f64 = 0.05;

/// The chance at most, by the binomial bound, that a genuine import is
/// refused (docs/math.md §9.8).
const FALSE_REFUSAL: f64 = 1e-9;

/// A record an import would add, picked for the check.
#[derive(Clone, Copy, Debug)]
pub struct Picked {
    /// Its place in the import: entry, and record within the entry.
    pub entry: usize,
    pub record: usize,
    pub value: Record,
    pub point: QueryPoint,
    /// The camera depth of its tile: the record sums indirect paths of up
    /// to one segment less from its own point (docs/math.md §10.10).
    pub camera_depth: PathDepth,
}

/// A record whose place is no query point (a position beyond the scene
/// model's coordinates), which no computation places; `entry` and `record`
/// name it in the import.
#[derive(Clone, Debug, PartialEq)]
pub struct Unplaced {
    pub entry: usize,
    pub record: usize,
    pub reason: String,
}

/// The records that the check compares with the scene, of `tiles` (the
/// tiles an import would add: their index in the import, records and camera
/// depth): all of them if there are at most [`CHECKED_RECORDS`], else that
/// many drawn uniformly without replacement by a generator seeded with the
/// BLAKE3 of the import's `body` keyed by `key`; in the import's order.
pub fn pick<'a>(
    tiles: impl IntoIterator<Item = (usize, &'a [Record], PathDepth)>,
    body: &[u8],
    key: &[u8; 32],
) -> Result<Vec<Picked>, Unplaced> {
    let tiles: Vec<_> = tiles.into_iter().collect();
    let total: usize = tiles.iter().map(|(_, records, _)| records.len()).sum();
    let mut chosen: Vec<usize> = if total <= CHECKED_RECORDS {
        (0..total).collect()
    } else {
        let mut rng = Pcg64::from_seed(*blake3::keyed_hash(key, body).as_bytes());
        rand::seq::index::sample(&mut rng, total, CHECKED_RECORDS).into_vec()
    };
    chosen.sort_unstable();
    let mut picked = Vec::with_capacity(chosen.len());
    let (mut next, mut before) = (chosen.iter().peekable(), 0);
    for (entry, records, camera_depth) in tiles {
        let count = records.len();
        while let Some(&&at) = next.peek().filter(|&&&at| at < before + count) {
            next.next();
            let record = at - before;
            let value = records[record];
            let point = QueryPoint::new(value.position, value.normal).map_err(|e| Unplaced {
                entry,
                record,
                reason: e.to_string(),
            })?;
            picked.push(Picked {
                entry,
                record,
                value,
                point,
                camera_depth,
            });
        }
        before += count;
    }
    Ok(picked)
}

/// A fresh estimate of a record's value, per channel, W/m², and the
/// variance of that estimate, (W/m²)².
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fresh {
    mean: Rgb,
    variance: Rgb,
}

/// The indirect irradiance at a picked record's place by [`FRESH_PATHS`]
/// cosine directions of paths as long as the record's (docs/math.md §1,
/// `Transport::cosine_hemisphere_irradiance`), from a generator seeded by
/// the record's position and normal; exactly zero, with no spread, where
/// the record's tile counts no indirect paths.
fn fresh_estimate(transport: &Transport, picked: &Picked) -> Fresh {
    let Some(from_point) = picked
        .camera_depth
        .after_first_segment()
        .filter(|d| d.has_reflections())
    else {
        return Fresh {
            mean: Rgb::BLACK,
            variance: Rgb::BLACK,
        };
    };
    let mut rng = Pcg64::from_seed(place_seed(picked.value.position, picked.value.normal));
    let mut stats = TraceStats::default();
    let estimate = transport.cosine_hemisphere_irradiance(
        &picked.point,
        FRESH_PATHS,
        indirect_paths(from_point),
        &mut rng,
        &mut stats,
    );
    Fresh {
        mean: estimate.mean,
        variance: estimate.variance_of_mean,
    }
}

/// The seed of a record's fresh estimate: the BLAKE3 of its place.
fn place_seed(position: DVec3, normal: DVec3) -> [u8; 32] {
    let mut hasher = blake3::Hasher::new();
    hasher.update(b"import check\0");
    for c in position.to_array().into_iter().chain(normal.to_array()) {
        hasher.update(&c.to_le_bytes());
    }
    *hasher.finalize().as_bytes()
}

/// Whether an imported value disagrees with a fresh estimate in some
/// channel (docs/math.md §9.8): no value within [`FRESH_SIGMAS`] standard
/// errors of the fresh estimate (and not negative) lies within a factor
/// [`RECORD_FACTOR`] of it, both shifted by `slack` (so that near zero the
/// factor becomes an allowance of about `slack`).
fn disagrees(value: Rgb, fresh: &Fresh, slack: Rgb) -> bool {
    let (e, f, v, a) = (
        value.to_array(),
        fresh.mean.to_array(),
        fresh.variance.to_array(),
        slack.to_array(),
    );
    (0..3).any(|c| {
        let spread = FRESH_SIGMAS * v[c].max(0.0).sqrt();
        let (low, high) = ((f[c] - spread).max(0.0), f[c] + spread);
        e[c] + a[c] > RECORD_FACTOR * (high + a[c]) || low + a[c] > RECORD_FACTOR * (e[c] + a[c])
    })
}

/// The fewest disagreeing records of `checked` that refuse an import: the
/// smallest count that `checked` genuine records reach with a chance of at
/// most [`FALSE_REFUSAL`] if each disagrees with a chance of at most
/// [`GENUINE_DISAGREEMENT`] (docs/math.md §9.8); all of them when no count
/// is that unlikely (fewer than 7 records: a genuine import of `n` is then
/// refused with a chance of at most `0.05ⁿ`). None for no record.
fn refusing_count(checked: usize) -> Option<usize> {
    (checked > 0).then(|| {
        (1..=checked)
            .find(|&k| {
                binomial_upper_tail(checked as u64, GENUINE_DISAGREEMENT, k as u64) <= FALSE_REFUSAL
            })
            .unwrap_or(checked)
    })
}

/// What the check found; made by [`check`] only (its fields are private),
/// so that what takes one as a proof of a check (`TileStore`'s import) gets
/// one that ran.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    checked: usize,
    disagreeing: usize,
    /// The first record (in the import's order) that disagreed, if any.
    first: Option<Disagreement>,
}

/// A record that disagreed, with what the scene gave at its place.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disagreement {
    pub entry: usize,
    pub record: usize,
    /// The imported value and the fresh estimate, W/m², and the fresh
    /// estimate's standard error.
    pub value: Rgb,
    pub fresh: Rgb,
    pub std_error: Rgb,
}

/// Why an import is refused: `disagreeing` of the `checked` records
/// disagreed, more than the `allowed`; `entry` and `record` name the first,
/// and `detail` says what it holds against what the scene gave.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refused {
    pub entry: usize,
    pub record: usize,
    pub checked: usize,
    pub disagreeing: usize,
    pub allowed: usize,
    pub detail: String,
}

impl Verdict {
    /// Records compared with fresh estimates.
    pub fn checked(&self) -> usize {
        self.checked
    }

    /// Of those, the records that disagreed.
    pub fn disagreeing(&self) -> usize {
        self.disagreeing
    }

    /// The verdict on an import with no record checked, for tests of what
    /// takes a verdict.
    #[cfg(test)]
    pub fn nothing_checked() -> Self {
        Self {
            checked: 0,
            disagreeing: 0,
            first: None,
        }
    }

    /// The refusal of the import, when at least [`refusing_count`] of the
    /// records checked disagreed.
    pub fn refusal(&self) -> Option<Refused> {
        let refusing = refusing_count(self.checked)?;
        let first = self.first.filter(|_| self.disagreeing >= refusing)?;
        let rgb = |c: Rgb| format!("[{:.4e}, {:.4e}, {:.4e}]", c.r, c.g, c.b);
        Some(Refused {
            entry: first.entry,
            record: first.record,
            checked: self.checked,
            disagreeing: self.disagreeing,
            allowed: refusing - 1,
            detail: format!(
                "irradiance {} W/m² where {FRESH_PATHS} fresh paths give {} ± {} W/m²",
                rgb(first.value),
                rgb(first.fresh),
                rgb(first.std_error)
            ),
        })
    }
}

/// Compares each picked record with a fresh estimate at its place
/// (docs/math.md §9.8), in parallel on the calling thread's pool; stops
/// between records once `cancel` is set.
pub fn check(
    transport: &Transport,
    picked: &[Picked],
    cancel: &Cancel,
) -> Result<Verdict, RenderError> {
    let fresh: Vec<Fresh> = picked
        .par_iter()
        .map(|p| {
            cancel.check()?;
            Ok(fresh_estimate(transport, p))
        })
        .collect::<Result<_, RenderError>>()?;
    // The scene's level per channel: the mean of the fresh estimates (the
    // imported values, a forger's, take no part in the allowance).
    let level =
        fresh.iter().fold(Rgb::BLACK, |sum, f| sum + f.mean) * (1.0 / fresh.len().max(1) as f64);
    let slack = level * (LEVEL_FLOOR + unseen_light(FRESH_PATHS));
    let mut verdict = Verdict {
        checked: picked.len(),
        disagreeing: 0,
        first: None,
    };
    for (p, f) in picked.iter().zip(&fresh) {
        if disagrees(p.value.irradiance, f, slack) {
            verdict.disagreeing += 1;
            verdict.first.get_or_insert(Disagreement {
                entry: p.entry,
                record: p.record,
                value: p.value.irradiance,
                fresh: f.mean,
                std_error: f.variance.map(|v| v.max(0.0).sqrt()),
            });
        }
    }
    Ok(verdict)
}

#[cfg(test)]
mod tests;

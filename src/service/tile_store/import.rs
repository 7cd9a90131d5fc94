//! Imports of records exports: why one is refused ([`ImportError`], 422
//! naming the entry), the import decoded and checked as computed records
//! hold ([`TileStore::decode_import`], [`DecodedImport`]), accepted by the
//! check against fresh estimates of the scene ([`CheckedImport`]) and only
//! then added ([`TileStore::add_import`], [`ImportReport`]).

use std::borrow::Cow;
use std::sync::Arc;

use super::{RECORDS, Refusal, TileStore};
use crate::cache::log::{self, LogEntry};
use crate::integrator::progressive::TileRecords;
use crate::service::error::ApiError;
use crate::service::import_check::{Refused, Verdict};

/// Why an import was refused; `entry` counts from 0.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ImportError {
    #[error("not a records export (the `BMCLOG01` magic is missing)")]
    NotALog,
    #[error("entry {entry} is incomplete or fails its checksum")]
    Damaged { entry: usize },
    #[error("entry {entry} is not a records entry (kind {kind})")]
    NotRecords { entry: usize, kind: u8 },
    #[error("entry {entry} holds records that do not decode")]
    Malformed { entry: usize },
    #[error("entry {entry} belongs to another scene content (digest {digest})")]
    OtherScene { entry: usize, digest: String },
    #[error("entry {entry}, record {record}: {reason}")]
    InvalidRecord {
        entry: usize,
        record: usize,
        reason: String,
    },
    /// Too many of the records checked against fresh estimates of the scene
    /// disagree with them (`service::import_check`); `entry` and `record`
    /// name the first that does.
    #[error(
        "entry {entry}, record {record}: {disagreeing} of the {checked} records checked disagree with fresh estimates of the scene's indirect irradiance (at most {allowed} may; docs/math.md §9.8); this one: {detail}"
    )]
    Disagrees {
        entry: usize,
        record: usize,
        checked: usize,
        disagreeing: usize,
        allowed: usize,
        detail: String,
    },
}

impl From<Refused> for ImportError {
    fn from(r: Refused) -> Self {
        ImportError::Disagrees {
            entry: r.entry,
            record: r.record,
            checked: r.checked,
            disagreeing: r.disagreeing,
            allowed: r.allowed,
            detail: r.detail,
        }
    }
}

/// An import names the entry it refuses (422): `body` when the body is not
/// an export at all, `entries[i]` otherwise.
impl From<ImportError> for ApiError {
    fn from(err: ImportError) -> Self {
        let field = match &err {
            ImportError::NotALog => "body".to_owned(),
            ImportError::Damaged { entry }
            | ImportError::NotRecords { entry, .. }
            | ImportError::Malformed { entry }
            | ImportError::OtherScene { entry, .. } => format!("entries[{entry}]"),
            ImportError::InvalidRecord { entry, record, .. }
            | ImportError::Disagrees { entry, record, .. } => {
                format!("entries[{entry}].records[{record}]")
            }
        };
        ApiError::invalid(field, err.to_string())
    }
}

/// What an import added.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, utoipa::ToSchema)]
pub struct ImportReport {
    /// Tiles whose records were added, and those already held.
    pub imported: u64,
    pub already_held: u64,
    /// Records in the added tiles.
    pub records: u64,
    /// Records of the added tiles checked against fresh estimates of the
    /// scene, and those of them that disagreed (docs/math.md §9.8; fewer
    /// than refuse an import).
    pub checked: u64,
    pub disagreeing: u64,
}

/// An import decoded and every record checked as computed records hold
/// ([`TileStore::decode_import`]), not added yet ([`TileStore::add_import`]).
pub struct DecodedImport {
    /// Each entry with its records, in the import's order, and whether this
    /// store held its key when it was decoded.
    entries: Vec<(LogEntry, TileRecords, bool)>,
}

impl DecodedImport {
    /// The entries this store did not hold when the import was decoded (what
    /// adding it would add), with their index in the import.
    pub fn new_tiles(&self) -> impl Iterator<Item = (usize, &TileRecords)> {
        self.entries
            .iter()
            .enumerate()
            .filter(|(_, (_, _, held))| !held)
            .map(|(i, (_, tile, _))| (i, tile))
    }

    /// This import, ready to add, if `verdict` (the check of records picked
    /// from [`Self::new_tiles`], `service::import_check`) does not refuse it.
    pub fn accept(self, verdict: &Verdict) -> Result<CheckedImport, ImportError> {
        if let Some(refusal) = verdict.refusal() {
            return Err(refusal.into());
        }
        Ok(CheckedImport {
            decoded: self,
            checked: verdict.checked() as u64,
            disagreeing: verdict.disagreeing() as u64,
        })
    }
}

/// A decoded import whose check passed ([`DecodedImport::accept`], from a
/// `Verdict` that only the check makes): the only form of an import that
/// [`TileStore::add_import`] takes, so none reaches the store, its log or
/// the other replicas unchecked.
pub struct CheckedImport {
    decoded: DecodedImport,
    /// Records checked, and those that disagreed.
    checked: u64,
    disagreeing: u64,
}

impl TileStore {
    /// Decodes the records entries of an export (`Self::export`) of the
    /// scene content `scene`, whose bounding box is `bounds`, for
    /// [`Self::add_import`]; all or nothing: any entry that is damaged, not
    /// records, of another scene content, or with a record computed records
    /// could not be (outside `bounds`, or failing
    /// [`Record::validate_received`](crate::cache::Record::validate_received))
    /// refuses the whole import. Whether the records agree with the scene is
    /// `service::import_check`'s to say, between the two.
    pub fn decode_import(
        &self,
        scene: &[u8; 32],
        bounds: (glam::DVec3, glam::DVec3),
        image: &[u8],
    ) -> Result<DecodedImport, ImportError> {
        let entries = log::decode_log(image).map_err(|entry| {
            if entry == 0 && !image.starts_with(log::MAGIC) {
                ImportError::NotALog
            } else {
                ImportError::Damaged { entry }
            }
        })?;
        let mut decoded = Vec::with_capacity(entries.len());
        for (i, entry) in entries.into_iter().enumerate() {
            if entry.kind != RECORDS {
                return Err(ImportError::NotRecords {
                    entry: i,
                    kind: entry.kind,
                });
            }
            let tile = self
                .decode_records(&entry.payload)
                .map_err(|found| match found {
                    Refusal::Malformed => ImportError::Malformed { entry: i },
                    Refusal::Record { record, reason } => ImportError::InvalidRecord {
                        entry: i,
                        record,
                        reason,
                    },
                })?;
            if &tile.scene != scene {
                return Err(ImportError::OtherScene {
                    entry: i,
                    digest: tile.scene.iter().map(|b| format!("{b:02x}")).collect(),
                });
            }
            // Records lie on the scene's surfaces; rounding aside, inside its box.
            let slack = 1e-6 * (bounds.1 - bounds.0).length() + 1e-9;
            let (low, high) = (bounds.0 - slack, bounds.1 + slack);
            if let Some(record) = tile
                .records
                .iter()
                .position(|r| r.position.cmplt(low).any() || r.position.cmpgt(high).any())
            {
                return Err(ImportError::InvalidRecord {
                    entry: i,
                    record,
                    reason: format!(
                        "position {:?} lies outside the scene's bounds {:?}",
                        tile.records[record].position.to_array(),
                        [bounds.0.to_array(), bounds.1.to_array()]
                    ),
                });
            }
            let held = self.records.contains_key(&entry.key);
            decoded.push((entry, tile, held));
        }
        Ok(DecodedImport { entries: decoded })
    }

    /// Adds the tiles of an import that this store does not hold (held ones
    /// are kept as they are), logging them and sending them to the other
    /// replicas. Only an import whose records agreed with the scene is
    /// added ([`CheckedImport`]): what is added here is served under the
    /// ETags of computed tiles, here and on every replica.
    pub fn add_import(&self, import: CheckedImport) -> ImportReport {
        let mut report = ImportReport {
            checked: import.checked,
            disagreeing: import.disagreeing,
            ..ImportReport::default()
        };
        for (entry, tile, held) in import.decoded.entries {
            // An entry held when the import was decoded was not among those
            // checked: it stays out even if it has been evicted since.
            if held || self.records.contains_key(&entry.key) {
                report.already_held += 1;
                continue;
            }
            report.imported += 1;
            report.records += tile.records.len() as u64;
            self.records.insert(entry.key, Arc::new(tile));
            self.persist(RECORDS, &entry.key, || Cow::Borrowed(&entry.payload), true);
        }
        report
    }
}

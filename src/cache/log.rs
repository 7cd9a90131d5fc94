//! An append-only, checksummed log of keyed entries on disk: what the
//! service keeps across restarts (Radiance's ambient file `-af` is the same
//! idea for its records).
//!
//! # Format
//! The file starts with the 8-byte magic [`MAGIC`]; each entry follows as
//!
//! `length: u32 LE | checksum: 8 bytes | kind: u8 | key: 32 bytes | payload`
//!
//! where `length` counts `kind`, `key` and `payload`, and `checksum` is the
//! first 8 bytes of BLAKE3 over those same bytes. Entries are appended with
//! one `write_all` each and never rewritten in place.
//!
//! # Damaged entries and torn tails
//! A crash can leave a partial last entry, a full disk a partial entry
//! anywhere, and a disk can return garbage. [`AppendLog::open`] reads
//! entries in order; at one that is incomplete, too long or fails its
//! checksum it looks for the next intact entry (the damaged entry's own
//! length first, then byte by byte) and goes on from there, so damage costs
//! only the entries it touches. Damage after the last intact entry is a torn
//! tail: the file is cut back to that entry, so later appends follow valid
//! data. A damaged magic is repaired when intact entries follow it. Nothing
//! in a bad file makes opening fail, except not being able to read or write
//! it. An append that fails (a full disk) is cut back off the file at once,
//! so it cannot hide the appends that follow.
//!
//! # The same format elsewhere
//! [`encode_entry`] and [`decode_entry`] frame one entry the same way for
//! other transports (the replicas' shared stream), and [`decode_log`] reads
//! a whole log image strictly (an export being imported): there, damage is
//! an error naming the entry, not a tail to cut.
//!
//! # Compaction
//! [`AppendLog::rewrite`] replaces the file by one holding only the given
//! entries (written to a temporary file, synced, then renamed over the log),
//! so the log can be brought back to what its owner still holds.

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// First bytes of every log file (format version 1).
pub const MAGIC: &[u8; 8] = b"BMCLOG01";
/// Largest accepted entry (`kind + key + payload`), bytes: a longer length
/// field is corruption, not an entry.
pub const MAX_ENTRY_BYTES: u32 = 64 << 20;
/// Largest entry kind: kinds are small numbers, so a larger kind byte marks
/// bytes that are not an entry's start (what lets damage be skipped).
pub const MAX_KIND: u8 = 15;
/// Bytes of an entry's header before `kind`: length and checksum.
const HEADER_BYTES: u64 = 12;

/// An entry's identity: a 256-bit content key.
pub type LogKey = [u8; 32];

/// One entry as read back.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogEntry {
    pub kind: u8,
    pub key: LogKey,
    pub payload: Vec<u8>,
}

/// What opening a log found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct LogReport {
    /// Complete entries read.
    pub entries: u64,
    /// Bytes of damaged entries skipped and of a torn tail cut; 0 for a
    /// clean log.
    pub dropped_bytes: u64,
}

/// An open log (module docs); appends are serialised by a mutex.
pub struct AppendLog {
    path: PathBuf,
    file: Mutex<File>,
    /// Current length of the file.
    bytes: AtomicU64,
}

fn checksum(body: &[u8]) -> [u8; 8] {
    let hash = blake3::hash(body);
    let mut out = [0; 8];
    out.copy_from_slice(&hash.as_bytes()[..8]);
    out
}

impl AppendLog {
    /// Opens the log at `path` (creating it and its directory), reads every
    /// complete entry and cuts a damaged tail (module docs).
    pub fn open(path: &Path) -> io::Result<(AppendLog, Vec<LogEntry>, LogReport)> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        // A FIFO or device in its place would block or never end a read.
        let not_regular = || {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{} is not a regular file", path.display()),
            )
        };
        if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
            return Err(not_regular());
        }
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)?;
        if !file.metadata()?.is_file() {
            return Err(not_regular());
        }
        // One process per log: another appending or compacting it would
        // interleave with this one.
        file.try_lock().map_err(|e| match e {
            std::fs::TryLockError::WouldBlock => io::Error::new(
                io::ErrorKind::WouldBlock,
                "the log is in use by another process",
            ),
            std::fs::TryLockError::Error(e) => e,
        })?;
        let len = file.metadata()?.len();
        let mut report = LogReport::default();
        let mut entries = Vec::new();
        // End of the last intact entry; 0 while nothing shows this is a log.
        let mut good = 0;
        if len >= MAGIC.len() as u64 {
            let mut magic = [0; 8];
            file.read_exact_at(&mut magic, 0)?;
            let start = MAGIC.len() as u64;
            let mut at = if &magic == MAGIC {
                Some(start)
            } else {
                // Not our magic: a log all the same if intact entries follow.
                let first = next_intact(&file, start, len)?;
                if let Some(first) = first {
                    file.write_all_at(MAGIC, 0)?;
                    report.dropped_bytes += first - start;
                }
                first
            };
            if at.is_some() {
                good = start;
            }
            while let Some(here) = at.filter(|&here| here < len) {
                match entry_at(&file, here, len)? {
                    Some((entry, size)) => {
                        entries.push(entry);
                        good = here + size;
                        at = Some(good);
                    }
                    None => {
                        at = next_intact(&file, here + 1, len)?;
                        if let Some(next) = at {
                            report.dropped_bytes += next - here;
                        }
                    }
                }
            }
        }
        if good == 0 {
            // Empty, shorter than the magic, or not a log of ours: start over.
            file.set_len(0)?;
            file.seek(SeekFrom::Start(0))?;
            file.write_all(MAGIC)?;
            good = MAGIC.len() as u64;
            report.dropped_bytes = len;
        } else if good < len {
            file.set_len(good)?;
            report.dropped_bytes += len - good;
        }
        file.sync_data()?;
        file.seek(SeekFrom::Start(good))?;
        report.entries = entries.len() as u64;
        Ok((
            AppendLog {
                path: path.to_owned(),
                file: Mutex::new(file),
                bytes: AtomicU64::new(good),
            },
            entries,
            report,
        ))
    }

    /// Appends one entry.
    pub fn append(&self, kind: u8, key: &LogKey, payload: &[u8]) -> io::Result<()> {
        let frame = encode_entry(kind, key, payload)?;
        let mut file = self.file.lock().unwrap_or_else(|p| p.into_inner());
        if let Err(err) = file.write_all(&frame) {
            // Cut off whatever part was written (module docs); if even that
            // fails, the next open skips it.
            let good = self.bytes.load(Ordering::Relaxed);
            let _ = file.set_len(good);
            let _ = file.seek(SeekFrom::Start(good));
            return Err(err);
        }
        self.bytes.fetch_add(frame.len() as u64, Ordering::Relaxed);
        Ok(())
    }

    /// Current size of the file, bytes.
    pub fn bytes(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed)
    }

    /// Replaces the log by one holding exactly `entries` (module docs).
    pub fn rewrite<'a>(
        &self,
        entries: impl IntoIterator<Item = (u8, &'a LogKey, &'a [u8])>,
    ) -> io::Result<()> {
        let mut file = self.file.lock().unwrap_or_else(|p| p.into_inner());
        let temporary = self.path.with_extension("compacting");
        let mut out = BufWriter::new(File::create(&temporary)?);
        out.write_all(MAGIC)?;
        let mut bytes = MAGIC.len() as u64;
        for (kind, key, payload) in entries {
            let frame = encode_entry(kind, key, payload)?;
            out.write_all(&frame)?;
            bytes += frame.len() as u64;
        }
        let written = out.into_inner().map_err(|e| e.into_error())?;
        written.sync_all()?;
        std::fs::rename(&temporary, &self.path)?;
        let mut reopened = OpenOptions::new().read(true).write(true).open(&self.path)?;
        reopened.try_lock().map_err(|_| {
            io::Error::new(io::ErrorKind::WouldBlock, "the compacted log is locked")
        })?;
        reopened.seek(SeekFrom::End(0))?;
        *file = reopened;
        self.bytes.store(bytes, Ordering::Relaxed);
        Ok(())
    }
}

/// The entry framed in exactly `bytes`, if it is complete and intact.
pub fn decode_entry(bytes: &[u8]) -> Option<LogEntry> {
    let mut reader = bytes;
    let entry = read_entry(&mut reader, bytes.len() as u64).ok()??;
    reader.is_empty().then_some(entry)
}

/// Every entry of a whole log image (the magic, then entries), read
/// strictly: `Err(i)` when entry `i` is incomplete or damaged, or the magic
/// is missing (`i = 0`).
pub fn decode_log(bytes: &[u8]) -> Result<Vec<LogEntry>, usize> {
    let mut reader = bytes.strip_prefix(MAGIC.as_slice()).ok_or(0usize)?;
    let mut entries = Vec::new();
    while !reader.is_empty() {
        let remaining = reader.len() as u64;
        match read_entry(&mut reader, remaining) {
            Ok(Some(entry)) => entries.push(entry),
            _ => return Err(entries.len()),
        }
    }
    Ok(entries)
}

/// One entry framed as in the file: length, checksum, kind, key, payload.
pub fn encode_entry(kind: u8, key: &LogKey, payload: &[u8]) -> io::Result<Vec<u8>> {
    if kind > MAX_KIND {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "log entry kind above MAX_KIND",
        ));
    }
    let length = u32::try_from(1 + key.len() + payload.len())
        .ok()
        .filter(|&l| l <= MAX_ENTRY_BYTES)
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "log entry too large"))?;
    let mut body = Vec::with_capacity(length as usize);
    body.push(kind);
    body.extend_from_slice(key);
    body.extend_from_slice(payload);
    let mut frame = Vec::with_capacity(HEADER_BYTES as usize + body.len());
    frame.extend_from_slice(&length.to_le_bytes());
    frame.extend_from_slice(&checksum(&body));
    frame.extend_from_slice(&body);
    Ok(frame)
}

/// The intact entry at byte `at` of a file of `len` bytes, with its framed
/// size; `None` where no complete, intact entry starts there.
fn entry_at(file: &File, at: u64, len: u64) -> io::Result<Option<(LogEntry, u64)>> {
    let Some(remaining) = len.checked_sub(at) else {
        return Ok(None);
    };
    if remaining < HEADER_BYTES + 33 {
        return Ok(None);
    }
    let mut header = [0; HEADER_BYTES as usize + 1];
    file.read_exact_at(&mut header, at)?;
    let Some(size) = plausible(&header, remaining) else {
        return Ok(None);
    };
    let mut framed = vec![0; size as usize];
    file.read_exact_at(&mut framed, at)?;
    let mut reader = &framed[..];
    Ok(read_entry(&mut reader, size)?.map(|entry| (entry, size)))
}

/// The framed size an entry whose first 13 bytes (header and kind) are
/// `head` would have, if it is plausible: a length within bounds that fits
/// in `remaining` bytes, and a kind of at most [`MAX_KIND`].
fn plausible(head: &[u8], remaining: u64) -> Option<u64> {
    let length = u32::from_le_bytes(head.get(..4)?.try_into().ok()?);
    let kind = *head.get(HEADER_BYTES as usize)?;
    let size = HEADER_BYTES + u64::from(length);
    ((33..=MAX_ENTRY_BYTES).contains(&length) && kind <= MAX_KIND && size <= remaining)
        .then_some(size)
}

/// Where the first intact entry at or after byte `from` starts, if any:
/// the place a damaged entry's own length points to first (damage inside an
/// entry leaves its length intact), then every byte in order. A byte is
/// checked in full only if its header is plausible and is followed, where
/// its length says, by the end of the file or another plausible header, so
/// random bytes almost never cost reading and hashing a made-up entry.
fn next_intact(file: &File, from: u64, len: u64) -> io::Result<Option<u64>> {
    const HEAD: u64 = HEADER_BYTES + 1;
    let head_at = |at: u64| -> io::Result<Option<[u8; HEAD as usize]>> {
        if at + HEAD > len {
            return Ok(None);
        }
        let mut head = [0; HEAD as usize];
        file.read_exact_at(&mut head, at)?;
        Ok(Some(head))
    };
    if let Some(damaged) = from.checked_sub(1)
        && let Some(head) = head_at(damaged)?
    {
        let length = u32::from_le_bytes(head[..4].try_into().expect("4 bytes"));
        let after = damaged + HEADER_BYTES + u64::from(length);
        if after < len && entry_at(file, after, len)?.is_some() {
            return Ok(Some(after));
        }
    }
    const WINDOW: u64 = 1 << 20;
    let mut start = from;
    while start + HEADER_BYTES + 33 <= len {
        let n = (len - start).min(WINDOW);
        let mut window = vec![0; n as usize];
        file.read_exact_at(&mut window, start)?;
        // Offsets whose whole head lies in this window.
        for offset in 0..n.saturating_sub(HEAD - 1) {
            let at = start + offset;
            let Some(size) = plausible(&window[offset as usize..], len - at) else {
                continue;
            };
            let next = at + size;
            let chained = next == len
                || head_at(next)?.is_some_and(|head| plausible(&head, len - next).is_some());
            if chained && entry_at(file, at, len)?.is_some() {
                return Ok(Some(at));
            }
        }
        start += n.saturating_sub(HEAD - 1).max(1);
    }
    Ok(None)
}

/// The next complete, intact entry of at most `remaining` bytes, or `None`
/// at the end or at damage.
fn read_entry(reader: &mut impl Read, remaining: u64) -> io::Result<Option<LogEntry>> {
    if remaining < HEADER_BYTES + 33 {
        return Ok(None);
    }
    let mut header = [0; HEADER_BYTES as usize];
    reader.read_exact(&mut header)?;
    let length = u32::from_le_bytes(header[..4].try_into().expect("4 bytes"));
    if !(33..=MAX_ENTRY_BYTES).contains(&length) || HEADER_BYTES + u64::from(length) > remaining {
        return Ok(None);
    }
    let mut body = vec![0; length as usize];
    reader.read_exact(&mut body)?;
    if checksum(&body) != header[4..] {
        return Ok(None);
    }
    let mut key = [0; 32];
    key.copy_from_slice(&body[1..33]);
    Ok(Some(LogEntry {
        kind: body[0],
        key,
        payload: body[33..].to_vec(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(i: u8) -> LogEntry {
        LogEntry {
            kind: i % 3,
            key: [i; 32],
            payload: (0..u32::from(i) * 7).map(|b| b as u8).collect(),
        }
    }

    fn write(path: &Path, entries: &[LogEntry]) -> u64 {
        let (log, read, _) = AppendLog::open(path).unwrap();
        assert!(read.is_empty());
        for e in entries {
            log.append(e.kind, &e.key, &e.payload).unwrap();
        }
        log.bytes()
    }

    #[test]
    fn entries_come_back_in_order_and_appends_continue() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/tiles.log");
        let entries: Vec<_> = (0..20).map(entry).collect();
        let bytes = write(&path, &entries[..10]);
        assert_eq!(std::fs::metadata(&path).unwrap().len(), bytes);
        let (log, read, report) = AppendLog::open(&path).unwrap();
        assert_eq!(read, entries[..10]);
        assert_eq!(
            report,
            LogReport {
                entries: 10,
                dropped_bytes: 0
            }
        );
        for e in &entries[10..] {
            log.append(e.kind, &e.key, &e.payload).unwrap();
        }
        drop(log);
        assert_eq!(AppendLog::open(&path).unwrap().1, entries);
    }

    /// A log cut at any byte opens, keeps every entry that ended before the
    /// cut, and takes appends after it.
    #[test]
    fn a_log_truncated_anywhere_keeps_every_complete_entry() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.log");
        let entries: Vec<_> = (0..6).map(entry).collect();
        write(&path, &entries);
        let full = std::fs::read(&path).unwrap();
        // Where each entry ends.
        let mut ends = vec![];
        let mut at = MAGIC.len();
        for e in &entries {
            at += HEADER_BYTES as usize + 33 + e.payload.len();
            ends.push(at);
        }
        for cut in 0..=full.len() {
            std::fs::write(&path, &full[..cut]).unwrap();
            let (log, read, report) = AppendLog::open(&path).unwrap();
            let complete = ends.iter().filter(|&&end| end <= cut).count();
            assert_eq!(read, entries[..complete], "cut at {cut}");
            let (kept, dropped) = if cut < MAGIC.len() {
                // Not even the magic: started over.
                (MAGIC.len(), cut)
            } else {
                let kept = ends[..complete].last().copied().unwrap_or(MAGIC.len());
                (kept, cut - kept)
            };
            assert_eq!(log.bytes(), kept as u64, "cut at {cut}");
            assert_eq!(report.dropped_bytes, dropped as u64, "cut at {cut}");
            log.append(9, &[7; 32], b"after").unwrap();
            drop(log);
            let (_, again, _) = AppendLog::open(&path).unwrap();
            assert_eq!(again.len(), complete + 1);
            assert_eq!(again.last().unwrap().payload, b"after");
        }
    }

    /// Where each of `entries` starts in a log holding them in order.
    fn starts(entries: &[LogEntry]) -> Vec<usize> {
        let mut at = MAGIC.len();
        entries
            .iter()
            .map(|e| {
                let start = at;
                at += HEADER_BYTES as usize + 33 + e.payload.len();
                start
            })
            .collect()
    }

    /// A flipped bit anywhere in an entry (length, checksum, kind, key or
    /// payload) or in the magic costs that entry at most: every other one
    /// is read, and appends go on.
    #[test]
    fn damage_costs_only_the_entries_it_touches() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.log");
        let entries: Vec<_> = (1..7).map(entry).collect();
        write(&path, &entries);
        let clean = std::fs::read(&path).unwrap();
        let starts = starts(&entries);
        for (damaged, &start) in starts.iter().enumerate() {
            let end = starts.get(damaged + 1).copied().unwrap_or(clean.len());
            for byte in [start, start + 2, start + 5, start + 12, start + 20, end - 1] {
                for bit in [0, 7] {
                    let mut bytes = clean.clone();
                    bytes[byte] ^= 1 << bit;
                    std::fs::write(&path, &bytes).unwrap();
                    let (log, read, report) = AppendLog::open(&path).unwrap();
                    let mut expected = entries.clone();
                    expected.remove(damaged);
                    assert_eq!(read, expected, "entry {damaged}, byte {byte}, bit {bit}");
                    assert!(report.dropped_bytes > 0);
                    log.append(3, &[9; 32], b"after").unwrap();
                    drop(log);
                    let (_, again, _) = AppendLog::open(&path).unwrap();
                    assert_eq!(again.len(), expected.len() + 1);
                    assert_eq!(again.last().unwrap().payload, b"after");
                }
            }
        }
        // The magic.
        let mut bytes = clean.clone();
        bytes[3] ^= 0x10;
        std::fs::write(&path, &bytes).unwrap();
        let (_, read, _) = AppendLog::open(&path).unwrap();
        assert_eq!(read, entries);
        assert!(std::fs::read(&path).unwrap().starts_with(MAGIC));
        // A file that is not a log at all is started over.
        std::fs::write(&path, b"something else entirely").unwrap();
        let (log, read, report) = AppendLog::open(&path).unwrap();
        assert!(read.is_empty());
        assert_eq!(report.dropped_bytes, 23);
        assert_eq!(log.bytes(), MAGIC.len() as u64);
    }

    /// An entry torn in the middle of the log (a full disk that later had
    /// room again) hides none of the entries appended after it.
    #[test]
    fn a_torn_entry_mid_log_hides_nothing_after_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.log");
        let entries: Vec<_> = (1..5).map(entry).collect();
        write(&path, &entries[..2]);
        let torn = encode_entry(entries[2].kind, &entries[2].key, &entries[2].payload).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        bytes.extend(&torn[..torn.len() / 2]);
        bytes.extend(encode_entry(entries[3].kind, &entries[3].key, &entries[3].payload).unwrap());
        std::fs::write(&path, &bytes).unwrap();
        let (_, read, report) = AppendLog::open(&path).unwrap();
        assert_eq!(
            read,
            [entries[0].clone(), entries[1].clone(), entries[3].clone()]
        );
        assert_eq!(report.dropped_bytes, (torn.len() / 2) as u64);
    }

    #[test]
    fn entries_round_trip_outside_a_file() {
        let entries: Vec<_> = (0..5).map(entry).collect();
        let mut image = MAGIC.to_vec();
        for e in &entries {
            let framed = encode_entry(e.kind, &e.key, &e.payload).unwrap();
            assert_eq!(decode_entry(&framed).as_ref(), Some(e));
            assert!(decode_entry(&framed[..framed.len() - 1]).is_none());
            image.extend(framed);
        }
        assert_eq!(decode_log(&image).unwrap(), entries);
        assert_eq!(decode_log(&image[..image.len() - 1]), Err(4));
        assert_eq!(decode_log(b"BMCLOG02"), Err(0));
        let mut flipped = image.clone();
        flipped[MAGIC.len() + 20] ^= 1;
        assert_eq!(decode_log(&flipped), Err(0));
    }

    #[test]
    fn rewrite_keeps_only_the_given_entries() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.log");
        let entries: Vec<_> = (0..8).map(entry).collect();
        write(&path, &entries);
        let (log, _, _) = AppendLog::open(&path).unwrap();
        let keep = [&entries[1], &entries[5]];
        log.rewrite(keep.iter().map(|e| (e.kind, &e.key, e.payload.as_slice())))
            .unwrap();
        log.append(entries[7].kind, &entries[7].key, &entries[7].payload)
            .unwrap();
        assert_eq!(log.bytes(), std::fs::metadata(&path).unwrap().len());
        drop(log);
        let read = AppendLog::open(&path).unwrap().1;
        assert_eq!(
            read,
            vec![entries[1].clone(), entries[5].clone(), entries[7].clone()]
        );
    }
}

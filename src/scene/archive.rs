//! A scene folder packed as a zip, tar or gzipped tar, unpacked into a
//! [`SceneBundle`] under limits that hold whatever the archive claims.
//!
//! What packers write is read: a zip; a tar as POSIX (ustar, pax), GNU and
//! `git archive` write it, the tar parser applying a pax extended header or
//! a GNU long name or link name to the entry after it, and a pax global
//! header (`git archive`'s commit id) skipped; a gzipped tar in one gzip
//! member or several (bgzip, parallel packers, gzips put end to end).
//!
//! Each entry is a regular file (written to the bundle under its name, which
//! the bundle checks: no `..`, no absolute names, no name twice) or a folder
//! (implied by its files, skipped). Entries a packer adds on its own
//! (`__MACOSX/`, `.DS_Store`, AppleDouble `._name` files) are skipped.
//! Links, FIFOs, devices, other entry types and sparse files are refused, as
//! are more entries than the bundle takes, a zip whose central directory
//! names an entry twice (the zip reader would keep one of the two), and a
//! tar that ends inside an entry or without its end-of-archive blocks (cut
//! short, as GNU tar refuses it).
//!
//! Limits: sizes are counted while bytes are unpacked, never taken from the
//! archive's headers, which a crafted archive fills as it likes, and what is
//! skipped is unpacked under the same limits as what is kept (it costs the
//! same to inflate). Each entry may reach `max_entry_bytes` and all of them
//! `max_total_bytes`; of a tar, every byte counts, its headers included.
//! The compression ratio is checked from the first [`RATIO_FLOOR`] bytes
//! on, so a bomb is stopped after a few mebibytes: a zip's per entry, a
//! gzipped tar's over the whole stream. The headers of a tar entry (which
//! the tar parser holds in memory) may take [`MAX_HEADER_BYTES`]. Unpacking
//! stops within one [`CHUNK`] once its cancel flag is set.
//!
//! Every refusal names the entry: field `archive[i]`, its index in the
//! archive (a tar's pax extended headers and long names belong to the entry
//! after them and take no index), the message its name, or for headers the
//! name of the entry before; a tar whose end is missing is refused with
//! field `body`, naming its last entry.
//!
//! The scene file is `file` when given, else the one `.xml` or `.json` file
//! at the archive's root, or at the root of the folder that holds
//! everything (`zip -r lego.zip lego` packs `lego/scene.xml`). Its folder
//! becomes the bundle's root, as the scenes directory treats a scene folder.

use std::cell::Cell;
use std::collections::HashMap;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::rc::Rc;

use super::bundle::{SceneBundle, main_scene_file};
use super::error::SceneError;
use super::formats::DocumentKind;
use crate::cancel::Cancel;

/// Unpacked bytes an entry (or a gzipped tar as a whole) may reach before
/// its compression ratio is checked: small files compress as they like.
pub const RATIO_FLOOR: u64 = 1 << 20;

/// Bytes the headers of a tar entry may take: its header block, the pax
/// extended header and GNU long name and link name entries before it (which
/// the tar parser reads into memory) and the padding of the entry before.
/// Real ones take a few hundred bytes.
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Bytes read from an entry at a time, between checks of the limits and of
/// the cancel flag.
pub const CHUNK: usize = 64 << 10;

/// How the archive is packed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArchiveFormat {
    Zip,
    Tar,
    TarGz,
}

impl ArchiveFormat {
    /// The format its first bytes show (zip's local header, gzip's magic,
    /// POSIX tar's `ustar` at offset 257), if any.
    pub fn sniff(head: &[u8]) -> Option<ArchiveFormat> {
        if head.starts_with(b"PK\x03\x04") || head.starts_with(b"PK\x05\x06") {
            Some(ArchiveFormat::Zip)
        } else if head.starts_with(&[0x1f, 0x8b]) {
            Some(ArchiveFormat::TarGz)
        } else if head.get(257..262) == Some(b"ustar".as_slice()) {
            Some(ArchiveFormat::Tar)
        } else {
            None
        }
    }
}

/// What an archive may unpack to.
#[derive(Clone, Copy, Debug)]
pub struct ArchiveLimits {
    /// Largest entry, unpacked bytes, whether it is kept or skipped.
    pub max_entry_bytes: u64,
    /// Largest sum of the entries, unpacked bytes (of a tar, every byte of
    /// it, headers and skipped entries included).
    pub max_total_bytes: u64,
    /// Most unpacked bytes per packed byte of an entry (of the whole stream
    /// for a gzipped tar), checked past [`RATIO_FLOOR`].
    pub max_ratio: u64,
}

/// An unpacked scene folder.
#[derive(Debug)]
pub struct Unpacked {
    /// The files of the scene file's folder, named relative to it.
    pub bundle: SceneBundle,
    /// The scene file's text.
    pub document: String,
    pub kind: DocumentKind,
    /// The scene file's name in the archive (`lego/scene.xml`).
    pub file: String,
    /// The folder that held the scene file, if any (`lego`): the scene's id
    /// when the request names none.
    pub folder: Option<String>,
    /// Entries outside the scene file's folder, left out.
    pub outside: Vec<String>,
}

/// Unpacks `archive` (module docs) into `bundle`, an empty one, whose
/// `max_assets` bounds the entries; `file` names the scene file (module
/// docs). Stops, with [`SceneError::Cancelled`], once `cancel` is set
/// (asked every chunk).
pub fn unpack(
    archive: std::fs::File,
    format: ArchiveFormat,
    limits: &ArchiveLimits,
    bundle: SceneBundle,
    file: Option<&str>,
    cancel: &Cancel,
) -> Result<Unpacked, SceneError> {
    let mut sink = Sink {
        bundle,
        limits: *limits,
        total: 0,
        buffer: vec![0u8; CHUNK],
        cancel,
    };
    match format {
        ArchiveFormat::Zip => unpack_zip(archive, &mut sink)?,
        ArchiveFormat::Tar => unpack_tar(BufReader::new(archive), None, &mut sink)?,
        ArchiveFormat::TarGz => {
            // The decoder buffers what it reads itself.
            let packed = Counted::new(archive);
            let read = packed.count.clone();
            let inflated = flate2::read::MultiGzDecoder::new(packed);
            unpack_tar(inflated, Some(read), &mut sink)?;
        }
    }
    scene_of(sink.bundle, file)
}

/// Packs the scene folder `folder` into `out` as a gzipped tar whose
/// entries are `<folder's name>/…`, as `tar -czf` of the folder would, so
/// [`unpack`] finds its scene file and names the scene after the folder.
/// Links are packed as links (and refused by [`unpack`]), never followed.
pub fn pack_folder(folder: &Path, out: impl std::io::Write) -> std::io::Result<()> {
    let name = std::fs::canonicalize(folder)?
        .file_name()
        .map(|n| n.to_owned())
        .ok_or_else(|| std::io::Error::other(format!("{} has no name", folder.display())))?;
    let mut tar = tar::Builder::new(flate2::write::GzEncoder::new(
        out,
        flate2::Compression::fast(),
    ));
    tar.follow_symlinks(false);
    tar.append_dir_all(&name, folder)?;
    tar.into_inner()?.finish()?;
    Ok(())
}

/// Where entries go, and what they have taken so far.
struct Sink<'a> {
    bundle: SceneBundle,
    limits: ArchiveLimits,
    /// Bytes of the entries unpacked so far, kept or skipped.
    total: u64,
    /// Bytes between an entry's reader and its file, reused by every entry.
    buffer: Vec<u8>,
    /// Set when the request is gone.
    cancel: &'a Cancel,
}

impl Sink<'_> {
    /// Writes entry `index` (`name`, `packed` bytes in a zip) from `reader`
    /// to the bundle; returns the bytes written.
    fn write(
        &mut self,
        index: usize,
        name: &str,
        reader: &mut dyn Read,
        packed: Option<u64>,
    ) -> Result<u64, SceneError> {
        let out = self.bundle.create(name, &field(index))?;
        self.drain(index, name, reader, packed, Some(out))
    }

    /// Reads entry `index` (`name`) from `reader` to its end without
    /// keeping it, under the same limits as one kept; returns its bytes.
    fn skip(&mut self, index: usize, name: &str, reader: &mut dyn Read) -> Result<u64, SceneError> {
        self.drain(index, name, reader, None, None)
    }

    fn drain(
        &mut self,
        index: usize,
        name: &str,
        reader: &mut dyn Read,
        packed: Option<u64>,
        mut out: Option<std::fs::File>,
    ) -> Result<u64, SceneError> {
        let refuse =
            |reason: String| SceneError::invalid(field(index), format!("entry {name:?}: {reason}"));
        let mut read = 0u64;
        loop {
            if self.cancel.is_cancelled() {
                return Err(SceneError::Cancelled);
            }
            let n = match reader.read(&mut self.buffer) {
                Ok(0) => return Ok(read),
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    return Err(refuse(match refusal(&e) {
                        Some(reason) => reason.to_owned(),
                        None => format!("cannot be unpacked: {e}"),
                    }));
                }
            };
            read += n as u64;
            self.total += n as u64;
            if read > self.limits.max_entry_bytes {
                return Err(refuse(format!(
                    "unpacks to more than {} bytes (limits.max_asset_bytes)",
                    self.limits.max_entry_bytes
                )));
            }
            if self.total > self.limits.max_total_bytes {
                return Err(refuse(past_total(self.limits.max_total_bytes)));
            }
            if let Some(packed) = packed
                && read > RATIO_FLOOR
            {
                let ratio = read / packed.max(1);
                if ratio > self.limits.max_ratio {
                    return Err(refuse(inflates(ratio, self.limits.max_ratio)));
                }
            }
            if let Some(out) = out.as_mut() {
                std::io::Write::write_all(out, &self.buffer[..n]).map_err(|e| SceneError::Io {
                    file: PathBuf::from(name),
                    source: e,
                })?;
            }
        }
    }
}

fn field(index: usize) -> String {
    format!("archive[{index}]")
}

fn past_total(limit: u64) -> String {
    format!("takes the archive past {limit} unpacked bytes (limits.max_unpacked_bytes)")
}

fn inflates(ratio: u64, limit: u64) -> String {
    format!(
        "inflates {ratio} times its packed size, more than {limit} (limits.max_compression_ratio)"
    )
}

/// Whether a packer added entry `name` on its own (module docs): macOS's
/// resource forks and Finder settings, in a zip's `__MACOSX/` folder or,
/// from its tar, as `._name` beside each file.
fn is_packer_litter(name: &str) -> bool {
    let file_name = name.rsplit('/').next().unwrap_or(name);
    name.starts_with("__MACOSX/") || file_name == ".DS_Store" || file_name.starts_with("._")
}

fn unpack_zip(archive: std::fs::File, sink: &mut Sink<'_>) -> Result<(), SceneError> {
    let mut zip = zip::ZipArchive::new(BufReader::new(archive))
        .map_err(|e| SceneError::invalid("body", format!("not a readable zip archive: {e}")))?;
    // The zip reader keeps one entry per name: which of two would be the
    // file is the packer's guess, so neither is taken.
    if zip.has_duplicate_names() {
        return Err(named_twice(zip));
    }
    // The central directory says how many entries there are: too many is
    // refused before anything is written.
    if zip.len() > sink.bundle.max_assets() {
        let name = zip
            .name_for_index(sink.bundle.max_assets())
            .and_then(Result::ok)
            .unwrap_or_default()
            .into_owned();
        return Err(SceneError::invalid(
            field(sink.bundle.max_assets()),
            format!(
                "entry {name:?}: the archive has {} entries, more than {} (limits.max_assets)",
                zip.len(),
                sink.bundle.max_assets()
            ),
        ));
    }
    for index in 0..zip.len() {
        let mut entry = zip
            .by_index(index)
            .map_err(|e| SceneError::invalid(field(index), format!("cannot be read: {e}")))?;
        let name = entry
            .name()
            .map_err(|e| SceneError::invalid(field(index), format!("unreadable name: {e}")))?
            .into_owned();
        let refuse =
            |reason: &str| SceneError::invalid(field(index), format!("entry {name:?}: {reason}"));
        if entry.is_symlink() {
            return Err(refuse(
                "is a link; an uploaded scene holds regular files only",
            ));
        }
        // The Unix file type in the entry's mode: a FIFO or device packed
        // by a Unix zip.
        const S_IFMT: u32 = 0o170_000;
        let special = entry
            .unix_mode()
            .map(|mode| mode & S_IFMT)
            .is_some_and(|kind| kind != 0 && kind != 0o100_000 && kind != 0o040_000);
        if special {
            return Err(refuse(
                "is a special file (FIFO or device), not a regular file",
            ));
        }
        // A zip's entries are read where the central directory says they
        // are: one skipped is never inflated.
        if entry.is_dir() || is_packer_litter(&name) {
            continue;
        }
        let packed = entry.compressed_size();
        sink.write(index, &name, &mut entry, Some(packed))?;
    }
    Ok(())
}

/// The refusal of a zip whose central directory names an entry twice: its
/// second entry of the name, found by reading the central directory again.
fn named_twice(zip: zip::ZipArchive<BufReader<std::fs::File>>) -> SceneError {
    let start = zip.central_directory_start();
    match repeated_name(&mut zip.into_inner(), start) {
        Ok(Some((first, second, name))) => SceneError::invalid(
            field(second),
            format!(
                "entry {name:?} is named twice ({} and {})",
                field(first),
                field(second)
            ),
        ),
        // Names told apart in the central directory and made alike by an
        // extra field (a Unicode path): no index to give.
        _ => SceneError::invalid("body", "the zip names an entry twice"),
    }
}

/// The first entry of the central directory at `start` named as an entry
/// before it: (that one's index, its index, the name).
fn repeated_name(
    reader: &mut (impl Read + Seek),
    start: u64,
) -> std::io::Result<Option<(usize, usize, String)>> {
    // A central directory header: its signature, fixed fields with the
    // lengths of the name, extra field and comment at 28, 30 and 32, then
    // those three.
    const SIGNATURE: &[u8] = b"PK\x01\x02";
    const FIXED: usize = 46;
    reader.seek(SeekFrom::Start(start))?;
    let mut seen: HashMap<Vec<u8>, usize> = HashMap::new();
    let mut index = 0;
    loop {
        let mut fixed = [0u8; FIXED];
        reader.read_exact(&mut fixed)?;
        if &fixed[..4] != SIGNATURE {
            return Ok(None);
        }
        let length = |at: usize| u16::from_le_bytes([fixed[at], fixed[at + 1]]);
        let mut name = vec![0u8; length(28).into()];
        reader.read_exact(&mut name)?;
        reader.seek_relative(i64::from(length(30)) + i64::from(length(32)))?;
        if let Some(first) = seen.insert(name.clone(), index) {
            return Ok(Some((
                first,
                index,
                String::from_utf8_lossy(&name).into_owned(),
            )));
        }
        index += 1;
    }
}

/// Unpacks the tar `reader` reads (inflated from the packed bytes
/// `packed` counts, for a gzipped tar).
fn unpack_tar<R: Read>(
    reader: R,
    packed: Option<Rc<Cell<u64>>>,
    sink: &mut Sink<'_>,
) -> Result<(), SceneError> {
    let meter = Rc::new(TarMeter {
        limits: sink.limits,
        packed,
        read: Cell::new(0),
        headers_from: Cell::new(None),
        ended: Cell::new(false),
    });
    let mut tar = tar::Archive::new(Metered {
        inner: reader,
        meter: meter.clone(),
    });
    let mut entries = tar
        .entries()
        .map_err(|e| SceneError::invalid("body", format!("not a readable tar archive: {e}")))?;
    let mut last: Option<String> = None;
    for index in 0.. {
        meter.headers_from.set(Some(meter.read.get()));
        let Some(entry) = entries.next() else {
            break;
        };
        let mut entry = entry.map_err(|e| {
            let reason = match refusal(&e) {
                Some(reason) => reason.to_owned(),
                None => format!("cannot be read: {e}"),
            };
            let after = match &last {
                Some(name) => format!("the entry after {name:?}"),
                None => "the first entry".to_owned(),
            };
            SceneError::invalid(field(index), format!("{after}: {reason}"))
        })?;
        meter.headers_from.set(None);
        let raw = String::from_utf8_lossy(&entry.path_bytes()).into_owned();
        // `tar -C dir -cf x.tar .` names everything `./…`.
        let name = raw.strip_prefix("./").unwrap_or(&raw).to_owned();
        let refuse =
            |reason: &str| SceneError::invalid(field(index), format!("entry {raw:?}: {reason}"));
        use tar::EntryType as T;
        let kept = match entry.header().entry_type() {
            T::Regular | T::Continuous if is_sparse(&mut entry) => {
                return Err(refuse(
                    "is a sparse file (`tar --sparse`), which is not read; pack it without",
                ));
            }
            T::Regular | T::Continuous => !(name.is_empty() || is_packer_litter(&name)),
            // A folder is implied by its files. A pax global header (`git
            // archive`'s commit id) holds defaults for the headers after
            // it, of which a scene needs none.
            T::Directory | T::XGlobalHeader => false,
            T::Symlink | T::Link => {
                return Err(refuse(
                    "is a link; an uploaded scene holds regular files only",
                ));
            }
            T::Fifo | T::Char | T::Block => {
                return Err(refuse(
                    "is a special file (FIFO or device), not a regular file",
                ));
            }
            other => return Err(refuse(&format!("has an unsupported entry type {other:?}"))),
        };
        let size = entry.size();
        let read = if kept {
            sink.write(index, &name, &mut entry, None)?
        } else {
            sink.skip(index, &raw, &mut entry)?
        };
        if read < size {
            return Err(refuse(&format!(
                "is cut short: the archive ends {read} bytes into its {size}"
            )));
        }
        last = Some(raw);
    }
    // The parser stops at the end-of-archive blocks, or at the end of the
    // stream, which a whole tar never reaches.
    if meter.ended.get() {
        let after = match &last {
            Some(name) => format!("after entry {name:?}"),
            None => "before its first entry".to_owned(),
        };
        return Err(SceneError::invalid(
            "body",
            format!("the tar ends {after}, without its end-of-archive blocks: it is cut short"),
        ));
    }
    Ok(())
}

/// Whether regular entry `entry` is a sparse file of the pax formats, whose
/// data is a map of its holes, then the rest: its pax extended header (read
/// with the entry's headers) has `GNU.sparse.` keys.
fn is_sparse<R: Read>(entry: &mut tar::Entry<'_, R>) -> bool {
    let Ok(Some(mut pax)) = entry.pax_extensions() else {
        return false;
    };
    pax.any(|e| e.is_ok_and(|e| e.key_bytes().starts_with(b"GNU.sparse.")))
}

/// Why reading failed, if it was a refusal of [`Metered`].
fn refusal(error: &std::io::Error) -> Option<&str> {
    let refused = error.get_ref()?.downcast_ref::<Refused>()?;
    Some(&refused.0)
}

/// A limit the tar stream passed (the reason), carried by an I/O error
/// through the tar parser.
#[derive(Debug)]
struct Refused(String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Refused {}

/// A tar as the tar parser reads it, every byte counted by its
/// [`TarMeter`], which refuses the read that passes a limit.
struct Metered<R> {
    inner: R,
    meter: Rc<TarMeter>,
}

/// What the tar parser has read, and where the unpacking loop is (the
/// parser hides both from it).
struct TarMeter {
    limits: ArchiveLimits,
    /// Packed bytes read so far (a gzipped tar).
    packed: Option<Rc<Cell<u64>>>,
    /// Bytes read so far, headers and entries, kept or skipped.
    read: Cell<u64>,
    /// While the parser reads an entry's headers, where they began (bytes
    /// into the tar); `None` while an entry's data is read.
    headers_from: Cell<Option<u64>>,
    /// Whether the stream ended (a read found nothing more).
    ended: Cell<bool>,
}

impl TarMeter {
    /// Why the tar may not be read past `read` bytes, if it may not.
    fn check(&self, read: u64) -> Result<(), String> {
        if let Some(from) = self.headers_from.get()
            && read - from > MAX_HEADER_BYTES
        {
            return Err(format!(
                "its headers (pax extended header, GNU long name or link name) \
                 take more than {MAX_HEADER_BYTES} bytes"
            ));
        }
        if read > self.limits.max_total_bytes {
            return Err(past_total(self.limits.max_total_bytes));
        }
        if let Some(packed) = &self.packed
            && read > RATIO_FLOOR
        {
            let ratio = read / packed.get().max(1);
            if ratio > self.limits.max_ratio {
                return Err(inflates(ratio, self.limits.max_ratio));
            }
        }
        Ok(())
    }
}

impl<R: Read> Read for Metered<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        let meter = &self.meter;
        if n == 0 && !buf.is_empty() {
            meter.ended.set(true);
        }
        let read = meter.read.get() + n as u64;
        meter.read.set(read);
        meter
            .check(read)
            .map_err(|reason| std::io::Error::other(Refused(reason)))?;
        Ok(n)
    }
}

/// A reader that counts the bytes read through it.
struct Counted<R> {
    inner: R,
    count: Rc<Cell<u64>>,
}

impl<R> Counted<R> {
    fn new(inner: R) -> Self {
        Counted {
            inner,
            count: Default::default(),
        }
    }
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count.set(self.count.get() + n as u64);
        Ok(n)
    }
}

/// Finds the scene file (module docs) and makes its folder the bundle's root.
fn scene_of(mut bundle: SceneBundle, file: Option<&str>) -> Result<Unpacked, SceneError> {
    let names: Vec<PathBuf> = bundle.names().map(Path::to_path_buf).collect();
    // The folder that holds every entry, if one does.
    let top = names
        .first()
        .and_then(|n| n.components().next())
        .map(|c| PathBuf::from(c.as_os_str()))
        .filter(|top| names.iter().all(|n| n.starts_with(top) && n != top));
    let path = match file {
        Some(file) => {
            let given = PathBuf::from(file);
            let inside = top.as_ref().map(|top| top.join(file));
            [Some(given), inside]
                .into_iter()
                .flatten()
                .find(|p| names.contains(p))
                .ok_or_else(|| {
                    SceneError::invalid("file", format!("the archive has no file {file:?}"))
                })?
        }
        None => {
            let at = |folder: &Path| -> Vec<PathBuf> {
                names
                    .iter()
                    .filter(|n| n.parent() == Some(folder))
                    .filter(|n| DocumentKind::of_file_name(n).is_some())
                    .cloned()
                    .collect()
            };
            let (mut candidates, mut folder) = (at(Path::new("")), None);
            if candidates.is_empty()
                && let Some(top) = &top
            {
                candidates = at(top);
                folder = top.to_str();
            }
            match (main_scene_file(&candidates, folder), candidates.as_slice()) {
                (Some(one), _) => one.to_path_buf(),
                (None, []) => {
                    return Err(SceneError::invalid(
                        "file",
                        "the archive has no scene file (.xml or .json) at its root; \
                         name it with the `file` parameter",
                    ));
                }
                (None, several) => {
                    return Err(SceneError::invalid(
                        "file",
                        format!(
                            "the archive has several scene files at its root ({}); \
                             name one with the `file` parameter",
                            several
                                .iter()
                                .map(|p| p.display().to_string())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ));
                }
            }
        }
    };
    let kind = DocumentKind::of_file_name(&path).unwrap_or(DocumentKind::Json);
    let bytes = std::fs::read(bundle.path_of(&path)).map_err(|e| SceneError::Io {
        file: path.clone(),
        source: e,
    })?;
    let document = String::from_utf8(bytes).map_err(|_| {
        SceneError::invalid("file", format!("{} is not UTF-8 text", path.display()))
    })?;
    let folder = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map(Path::to_path_buf);
    let outside = match &folder {
        Some(folder) => bundle.rebase(folder)?,
        None => Vec::new(),
    };
    Ok(Unpacked {
        bundle,
        document,
        kind,
        file: path.display().to_string(),
        folder: folder.map(|f| f.display().to_string()),
        outside: outside.iter().map(|p| p.display().to_string()).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Seek, Write};

    const LIMITS: ArchiveLimits = ArchiveLimits {
        max_entry_bytes: 64 << 20,
        max_total_bytes: 128 << 20,
        max_ratio: 100,
    };

    /// [`super::unpack`], never cancelled.
    fn unpack(
        archive: std::fs::File,
        format: ArchiveFormat,
        limits: &ArchiveLimits,
        max_entries: usize,
        file: Option<&str>,
    ) -> Result<Unpacked, SceneError> {
        let bundle = SceneBundle::new(max_entries)?;
        super::unpack(archive, format, limits, bundle, file, &Cancel::never())
    }

    fn zip_of(entries: &[(&str, &[u8])]) -> std::fs::File {
        let mut file = tempfile::tempfile().unwrap();
        let mut zip = zip::ZipWriter::new(&mut file);
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        for (name, bytes) in entries {
            if let Some(dir) = name.strip_suffix('/') {
                zip.add_directory(dir, options).unwrap();
            } else {
                zip.start_file(*name, options).unwrap();
                zip.write_all(bytes).unwrap();
            }
        }
        zip.finish().unwrap();
        file.rewind().unwrap();
        file
    }

    fn tar_of(build: impl FnOnce(&mut tar::Builder<&mut std::fs::File>)) -> std::fs::File {
        let mut file = tempfile::tempfile().unwrap();
        let mut tar = tar::Builder::new(&mut file);
        build(&mut tar);
        tar.finish().unwrap();
        drop(tar);
        file.rewind().unwrap();
        file
    }

    fn append(
        tar: &mut tar::Builder<&mut std::fs::File>,
        name: &str,
        kind: tar::EntryType,
        bytes: &[u8],
    ) {
        let mut header = tar::Header::new_gnu();
        header.set_entry_type(kind);
        header.set_size(bytes.len() as u64);
        header.set_mode(0o644);
        // `set_path` refuses `..`; a crafted archive writes the name raw.
        header.as_gnu_mut().unwrap().name[..name.len()].copy_from_slice(name.as_bytes());
        header.set_cksum();
        tar.append(&header, bytes).unwrap();
    }

    #[test]
    fn a_zipped_folder_unpacks_with_its_scene_file_at_the_root() {
        let zip = zip_of(&[
            ("lego/", b""),
            ("lego/scene.xml", b"<scene version=\"3.0.0\"/>"),
            ("lego/meshes/a.ply", b"ply"),
            ("__MACOSX/lego/._scene.xml", b"x"),
        ]);
        let unpacked = unpack(zip, ArchiveFormat::Zip, &LIMITS, 16, None).unwrap();
        assert_eq!(unpacked.kind, DocumentKind::MitsubaXml);
        assert_eq!(unpacked.folder.as_deref(), Some("lego"));
        assert_eq!(unpacked.file, "lego/scene.xml");
        let names: Vec<_> = unpacked.bundle.names().map(Path::to_path_buf).collect();
        assert_eq!(
            names,
            [PathBuf::from("scene.xml"), PathBuf::from("meshes/a.ply")]
        );
        assert_eq!(
            std::fs::read(unpacked.bundle.path_of(Path::new("meshes/a.ply"))).unwrap(),
            b"ply"
        );
    }

    #[test]
    fn the_scene_file_is_the_one_at_the_root_or_the_one_named() {
        // `scene.xml` is the scene beside others, as in the tutorials' lego.
        let lego: &[(&str, &[u8])] = &[("l/scene_box.xml", b""), ("l/scene.xml", b"<s/>")];
        let unpacked = unpack(zip_of(lego), ArchiveFormat::Zip, &LIMITS, 16, None).unwrap();
        assert_eq!(unpacked.document, "<s/>");
        let entries: &[(&str, &[u8])] = &[("a.xml", b"<a/>"), ("b.json", b"{}"), ("m/c.xml", b"")];
        let err = unpack(zip_of(entries), ArchiveFormat::Zip, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("file"));
        assert!(err.to_string().contains("a.xml, b.json"), "{err}");
        let named = unpack(
            zip_of(entries),
            ArchiveFormat::Zip,
            &LIMITS,
            16,
            Some("b.json"),
        )
        .unwrap();
        assert_eq!(
            (named.kind, named.document.as_str()),
            (DocumentKind::Json, "{}")
        );
        let err = unpack(
            zip_of(entries),
            ArchiveFormat::Zip,
            &LIMITS,
            16,
            Some("x.xml"),
        )
        .unwrap_err();
        assert_eq!(err.field(), Some("file"));
        // A file named inside a folder makes that folder the root; what is
        // outside it is left out and listed.
        let inner = unpack(
            zip_of(entries),
            ArchiveFormat::Zip,
            &LIMITS,
            16,
            Some("m/c.xml"),
        )
        .unwrap();
        assert_eq!(inner.folder.as_deref(), Some("m"));
        assert_eq!(inner.outside, ["a.xml", "b.json"]);
    }

    #[test]
    fn links_special_files_and_escaping_names_are_refused_naming_the_entry() {
        for (kind, name, says) in [
            (tar::EntryType::Symlink, "s/link", "is a link"),
            (tar::EntryType::Link, "s/hard", "is a link"),
            (tar::EntryType::Fifo, "s/fifo", "special file"),
            (tar::EntryType::Char, "s/dev", "special file"),
            (tar::EntryType::Regular, "s/../../evil", "`..`"),
            (tar::EntryType::Regular, "/etc/evil", "absolute"),
        ] {
            let tar = tar_of(|tar| {
                append(tar, "s/scene.xml", tar::EntryType::Regular, b"<scene/>");
                append(tar, name, kind, b"");
            });
            let err = unpack(tar, ArchiveFormat::Tar, &LIMITS, 16, None).unwrap_err();
            assert_eq!(err.field(), Some("archive[1]"), "{name}");
            let text = err.to_string();
            assert!(text.contains(name) && text.contains(says), "{text}");
        }
    }

    #[test]
    fn bombs_and_floods_are_refused_after_little_work() {
        // 512 MiB of zeros packs to about half a mebibyte; it is refused
        // for its ratio once a mebibyte is out.
        let mut file = tempfile::tempfile().unwrap();
        {
            let mut zip = zip::ZipWriter::new(&mut file);
            let options = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Deflated)
                .large_file(true);
            zip.start_file("bomb/zeros.bin", options).unwrap();
            let zeros = vec![0u8; 1 << 20];
            for _ in 0..512 {
                zip.write_all(&zeros).unwrap();
            }
            zip.finish().unwrap();
        }
        file.rewind().unwrap();
        let err = unpack(file, ArchiveFormat::Zip, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[0]"));
        assert!(err.to_string().contains("max_compression_ratio"), "{err}");
        // The same through a gzipped tar: the stream's ratio.
        let mut gz = tempfile::tempfile().unwrap();
        {
            let encoder = flate2::write::GzEncoder::new(&mut gz, flate2::Compression::fast());
            let mut tar = tar::Builder::new(encoder);
            let mut header = tar::Header::new_gnu();
            header.set_size(512 << 20);
            header.set_mode(0o644);
            header.set_path("zeros.bin").unwrap();
            header.set_cksum();
            tar.append(&header, std::io::repeat(0).take(512 << 20))
                .unwrap();
            tar.into_inner().unwrap().finish().unwrap();
        }
        gz.rewind().unwrap();
        let err = unpack(gz, ArchiveFormat::TarGz, &LIMITS, 16, None).unwrap_err();
        assert!(err.to_string().contains("max_compression_ratio"), "{err}");
        // Past the per-entry and total limits, named.
        let small = ArchiveLimits {
            max_entry_bytes: 10,
            max_total_bytes: 15,
            max_ratio: 100,
        };
        let entries: &[(&str, &[u8])] = &[("a.xml", b"<scene/>"), ("b", &[1; 11])];
        let err = unpack(zip_of(entries), ArchiveFormat::Zip, &small, 16, None).unwrap_err();
        assert!(err.to_string().contains("limits.max_asset_bytes"), "{err}");
        let entries: &[(&str, &[u8])] = &[("a.xml", b"<scene/>"), ("b", &[1; 10])];
        let err = unpack(zip_of(entries), ArchiveFormat::Zip, &small, 16, None).unwrap_err();
        assert!(
            err.to_string().contains("limits.max_unpacked_bytes"),
            "{err}"
        );
        // More entries than the bundle takes: the first one over is named
        // before anything is unpacked.
        let many: Vec<(String, Vec<u8>)> = (0..20).map(|i| (format!("f{i}"), vec![])).collect();
        let many: Vec<(&str, &[u8])> = many
            .iter()
            .map(|(n, b)| (n.as_str(), b.as_slice()))
            .collect();
        let err = unpack(zip_of(&many), ArchiveFormat::Zip, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[16]"));
        assert!(err.to_string().contains("\"f16\""), "{err}");
    }

    #[test]
    fn a_packed_folder_unpacks_to_the_same_files() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("lego");
        std::fs::create_dir_all(folder.join("meshes")).unwrap();
        std::fs::write(folder.join("scene.xml"), "<scene/>").unwrap();
        std::fs::write(folder.join("meshes/a.ply"), [7u8; 3000]).unwrap();
        let mut packed = tempfile::tempfile().unwrap();
        pack_folder(&folder, &mut packed).unwrap();
        packed.rewind().unwrap();
        let unpacked = unpack(packed, ArchiveFormat::TarGz, &LIMITS, 16, None).unwrap();
        assert_eq!(unpacked.folder.as_deref(), Some("lego"));
        assert_eq!(unpacked.document, "<scene/>");
        let mesh = unpacked.bundle.path_of(Path::new("meshes/a.ply"));
        assert_eq!(std::fs::read(mesh).unwrap(), [7u8; 3000]);
        // A link inside is packed as a link, which unpacking refuses.
        std::os::unix::fs::symlink("/etc/passwd", folder.join("meshes/b.ply")).unwrap();
        let mut packed = tempfile::tempfile().unwrap();
        pack_folder(&folder, &mut packed).unwrap();
        packed.rewind().unwrap();
        let err = unpack(packed, ArchiveFormat::TarGz, &LIMITS, 16, None).unwrap_err();
        assert!(err.to_string().contains("is a link"), "{err}");
    }

    /// A pax record: `<length> <key>=<value>\n`, the length counting itself.
    fn pax_record(key: &str, value: &str) -> Vec<u8> {
        let rest = format!(" {key}={value}\n");
        let mut length = rest.len() + 1;
        while format!("{length}{rest}").len() != length {
            length += 1;
        }
        format!("{length}{rest}").into_bytes()
    }

    /// The bytes of a tar of `entries` (name, type, data), names written raw.
    fn tar_bytes(entries: &[(&str, tar::EntryType, &[u8])]) -> Vec<u8> {
        let mut file = tar_of(|tar| {
            for (name, kind, bytes) in entries {
                append(tar, name, *kind, bytes);
            }
        });
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).unwrap();
        bytes
    }

    fn file_of(bytes: &[u8]) -> std::fs::File {
        let mut file = tempfile::tempfile().unwrap();
        file.write_all(bytes).unwrap();
        file.rewind().unwrap();
        file
    }

    /// `bytes` gzipped in members of at most `member` bytes each, then an
    /// empty member, as bgzip and parallel packers write them.
    fn gzip_members(bytes: &[u8], member: usize) -> Vec<u8> {
        let mut out = Vec::new();
        for chunk in bytes.chunks(member).chain([&[][..]]) {
            let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            gz.write_all(chunk).unwrap();
            out.extend(gz.finish().unwrap());
        }
        out
    }

    fn names(unpacked: &Unpacked) -> Vec<String> {
        let mut names: Vec<_> = unpacked
            .bundle
            .names()
            .map(|n| n.display().to_string())
            .collect();
        names.sort();
        names
    }

    /// What `git archive` (a pax global header with the commit id), GNU
    /// tar's pax format (an extended header before every entry), its GNU
    /// format (a long name entry before a name past 100 bytes) and macOS's
    /// tar (AppleDouble `._` files beside the others) write is read, the
    /// headers and the litter left out.
    #[test]
    fn what_the_usual_packers_write_unpacks() {
        use tar::EntryType as T;
        let long = format!("lego/meshes/{}.ply", "m".repeat(120));
        let global = pax_record("comment", "42f8eabaac46bf4535570586e2f3c1a5a6ff8a01");
        let extended = pax_record("path", "lego/meshes/named-by-pax.ply");
        let tar = tar_of(|tar| {
            append(tar, "pax_global_header", T::XGlobalHeader, &global);
            append(tar, "lego/", T::Directory, b"");
            append(tar, "lego/scene.xml", T::Regular, b"<scene/>");
            append(tar, "lego/._scene.xml", T::Regular, b"\x00\x05\x16\x07");
            append(tar, "lego/PaxHeaders/x", T::XHeader, &extended);
            append(tar, "lego/meshes/trunc", T::Regular, b"pax");
            let mut header = tar::Header::new_gnu();
            header.set_size(3);
            header.set_mode(0o644);
            tar.append_data(&mut header, &long, b"gnu".as_slice())
                .unwrap();
        });
        let unpacked = unpack(tar, ArchiveFormat::Tar, &LIMITS, 16, None).unwrap();
        assert_eq!(unpacked.folder.as_deref(), Some("lego"));
        let long_inside = long.strip_prefix("lego/").unwrap();
        let mut expected = vec!["meshes/named-by-pax.ply", long_inside, "scene.xml"];
        expected.sort();
        assert_eq!(names(&unpacked), expected);
        let read = |name: &str| std::fs::read(unpacked.bundle.path_of(Path::new(name))).unwrap();
        assert_eq!(read("meshes/named-by-pax.ply"), b"pax");
        assert_eq!(read(long_inside), b"gnu");
    }

    /// A gzip of several members (bgzip, parallel packers, `cat a.gz b.gz`)
    /// is read to its end, not to the end of its first member.
    #[test]
    fn a_gzip_of_several_members_unpacks_whole() {
        use tar::EntryType as T;
        let mesh: Vec<u8> = (0..200_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let tar = tar_bytes(&[
            ("s/scene.xml", T::Regular, b"<scene/>"),
            ("s/a.ply", T::Regular, &mesh),
            ("s/b.ply", T::Regular, b"last"),
        ]);
        let gz = gzip_members(&tar, 64 << 10);
        let unpacked = unpack(file_of(&gz), ArchiveFormat::TarGz, &LIMITS, 16, None).unwrap();
        assert_eq!(names(&unpacked), ["a.ply", "b.ply", "scene.xml"]);
        let read = |name: &str| std::fs::read(unpacked.bundle.path_of(Path::new(name))).unwrap();
        assert_eq!(read("a.ply"), mesh);
        assert_eq!(read("b.ply"), b"last");
    }

    /// A tar header of an entry of `size` bytes whose data follows.
    fn header_bytes(name: &str, kind: tar::EntryType, size: u64) -> Vec<u8> {
        let mut header = tar::Header::new_gnu();
        header.set_entry_type(kind);
        header.set_size(size);
        header.set_mode(0o644);
        header.as_gnu_mut().unwrap().name[..name.len()].copy_from_slice(name.as_bytes());
        header.set_cksum();
        header.as_bytes().to_vec()
    }

    /// A gzipped tar of a scene file, then entry `name` of `kind` holding
    /// `mib` mebibytes of zeros, then another file and the end.
    fn bomb(name: &str, kind: tar::EntryType, mib: u64) -> std::fs::File {
        let scene = tar_bytes(&[("s/scene.xml", tar::EntryType::Regular, b"<scene/>")]);
        // The scene's entry without the end-of-archive blocks.
        let mut before = scene[..scene.len() - 1024].to_vec();
        before.extend(header_bytes(name, kind, mib << 20));
        let after = tar_bytes(&[("s/after.ply", tar::EntryType::Regular, b"after")]);
        file_of(&crate::testing::gzip_with_zeros(&before, mib, &after))
    }

    /// Entries that are not unpacked (folders, a packer's litter, a pax
    /// global header) and the headers the tar parser reads itself (a pax
    /// extended header, held in memory) are inflated under the same limits
    /// as files: 8 GiB of zeros packed in 8 MB is refused once a few
    /// mebibytes are out, and a header of 64 MiB once one is.
    #[test]
    fn what_is_skipped_inflates_under_the_limits() {
        use tar::EntryType as T;
        for (name, kind, says) in [
            ("s/.DS_Store", T::Regular, "max_compression_ratio"),
            ("__MACOSX/s/._a", T::Regular, "max_compression_ratio"),
            ("s/folder/", T::Directory, "max_compression_ratio"),
            (
                "pax_global_header",
                T::XGlobalHeader,
                "max_compression_ratio",
            ),
            ("s/PaxHeaders/a", T::XHeader, "headers"),
            ("././@LongLink", T::GNULongName, "headers"),
        ] {
            let mib = if says == "headers" { 64 } else { 8 << 10 };
            let archive = bomb(name, kind, mib);
            let packed = archive.metadata().unwrap().len();
            let mut read = archive.try_clone().unwrap();
            let err = unpack(archive, ArchiveFormat::TarGz, &LIMITS, 16, None).unwrap_err();
            assert_eq!(err.field(), Some("archive[1]"), "{name}: {err}");
            assert!(err.to_string().contains(says), "{name}: {err}");
            // The clone shares the file's offset: how far the packed bytes
            // were read (the decoder reads 32 KiB at a time). Deflate
            // inflates at most 1,032 times, so that bounds the inflation.
            let read = read.stream_position().unwrap();
            assert!(
                read < 256 << 10,
                "{name}: {read} of {packed} packed bytes read"
            );
        }
        // Without compression: a pax header past its bound, and a skipped
        // entry past an entry's.
        let tar = tar_bytes(&[
            ("s/scene.xml", T::Regular, b"<scene/>"),
            ("s/PaxHeaders/a", T::XHeader, &vec![b'9'; 2 << 20]),
            ("s/a", T::Regular, b""),
        ]);
        let err = unpack(file_of(&tar), ArchiveFormat::Tar, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[1]"), "{err}");
        assert!(err.to_string().contains("headers"), "{err}");
        let small = ArchiveLimits {
            max_entry_bytes: 10,
            ..LIMITS
        };
        let tar = tar_bytes(&[
            ("s/scene.xml", T::Regular, b"<scene/>"),
            ("s/.DS_Store", T::Regular, &[1; 11]),
        ]);
        let err = unpack(file_of(&tar), ArchiveFormat::Tar, &small, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[1]"), "{err}");
        assert!(err.to_string().contains("max_asset_bytes"), "{err}");
    }

    /// A zip whose central directory names an entry twice, as Python's
    /// `zipfile` writes when asked to: refused naming the second, where
    /// reading it would keep only one of the two.
    #[test]
    fn a_zip_naming_an_entry_twice_is_refused_naming_the_second() {
        let mut bytes = Vec::new();
        zip_of(&[
            ("s/", b""),
            ("s/scene.xml", b"<scene>first</scene>"),
            ("s/scene.xmX", b"<scene>second</scene>"),
        ])
        .read_to_end(&mut bytes)
        .unwrap();
        // The writer refuses a name twice; rename the third entry in its
        // local header and in the central directory.
        let mut renamed = 0;
        for at in 0..bytes.len() - 11 {
            if &bytes[at..at + 11] == b"s/scene.xmX" {
                bytes[at + 10] = b'l';
                renamed += 1;
            }
        }
        assert_eq!(renamed, 2);
        let err = unpack(file_of(&bytes), ArchiveFormat::Zip, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[2]"), "{err}");
        let text = err.to_string();
        assert!(
            text.contains("\"s/scene.xml\"") && text.contains("archive[1]"),
            "{text}"
        );
    }

    /// A tar that ends inside an entry, or without its end-of-archive
    /// blocks (what keeping only a gzip's first member made of a bgzip'd
    /// tar), is refused, as GNU tar refuses it: files may be missing.
    #[test]
    fn a_tar_cut_short_is_refused() {
        use tar::EntryType as T;
        let tar = tar_bytes(&[
            ("s/scene.xml", T::Regular, b"<scene/>"),
            ("s/a.ply", T::Regular, &[7; 3000]),
        ]);
        // Inside `a.ply`'s data.
        let err = unpack(file_of(&tar[..2048]), ArchiveFormat::Tar, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[1]"), "{err}");
        assert!(err.to_string().contains("cut short"), "{err}");
        // After `a.ply`, before the end-of-archive blocks.
        let end = tar.len() - 1024;
        let err = unpack(file_of(&tar[..end]), ArchiveFormat::Tar, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("body"), "{err}");
        assert!(
            err.to_string().contains("cut short") && err.to_string().contains("s/a.ply"),
            "{err}"
        );
        // The whole tar is fine.
        unpack(file_of(&tar), ArchiveFormat::Tar, &LIMITS, 16, None).unwrap();
    }

    /// A sparse file of the pax formats (its data a map of its holes, then
    /// the rest) is refused, not unpacked as it is stored.
    #[test]
    fn a_sparse_file_is_refused_naming_it() {
        use tar::EntryType as T;
        let pax = [
            pax_record("GNU.sparse.major", "1"),
            pax_record("GNU.sparse.minor", "0"),
            pax_record("GNU.sparse.name", "s/a.ply"),
            pax_record("GNU.sparse.realsize", "4096"),
        ]
        .concat();
        let tar = tar_bytes(&[
            ("s/scene.xml", T::Regular, b"<scene/>"),
            ("s/PaxHeaders/a.ply", T::XHeader, &pax),
            ("s/GNUSparseFile.0/a.ply", T::Regular, b"1\n0\n512\n"),
        ]);
        let err = unpack(file_of(&tar), ArchiveFormat::Tar, &LIMITS, 16, None).unwrap_err();
        assert_eq!(err.field(), Some("archive[1]"), "{err}");
        assert!(err.to_string().contains("sparse"), "{err}");
    }

    /// Unpacking stops once its request is gone.
    #[test]
    fn a_cancelled_unpacking_stops() {
        let zip = zip_of(&[("scene.xml", b"<scene/>")]);
        let cancel = Cancel::new();
        cancel.cancel();
        let bundle = SceneBundle::new(16).unwrap();
        let err =
            super::unpack(zip, ArchiveFormat::Zip, &LIMITS, bundle, None, &cancel).unwrap_err();
        assert!(matches!(err, SceneError::Cancelled), "{err}");
    }

    #[test]
    fn formats_are_known_by_their_first_bytes() {
        let mut head = Vec::new();
        zip_of(&[("a", b"")]).read_to_end(&mut head).unwrap();
        assert_eq!(ArchiveFormat::sniff(&head), Some(ArchiveFormat::Zip));
        let mut head = Vec::new();
        tar_of(|t| append(t, "a", tar::EntryType::Regular, b""))
            .read_to_end(&mut head)
            .unwrap();
        assert_eq!(ArchiveFormat::sniff(&head), Some(ArchiveFormat::Tar));
        assert_eq!(
            ArchiveFormat::sniff(&[0x1f, 0x8b, 8]),
            Some(ArchiveFormat::TarGz)
        );
        assert_eq!(ArchiveFormat::sniff(b"<scene/>"), None);
    }
}

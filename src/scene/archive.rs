//! A scene folder packed as a zip, tar or gzipped tar, unpacked into a
//! [`SceneBundle`] under limits that hold whatever the archive claims.
//!
//! Each entry is a regular file (written to the bundle under its name, which
//! the bundle checks: no `..`, no absolute names) or a folder (implied by its
//! files, skipped). Links, FIFOs and devices are refused, as are more entries
//! than the bundle takes, an entry or a total past its unpacked-size limit
//! and an entry that inflates more than `max_ratio` times its packed size
//! (a zip bomb). Sizes are counted while bytes are written, never taken from
//! the archive's headers, which a crafted archive fills as it likes; the
//! ratio is checked from the first [`RATIO_FLOOR`] bytes on, so a bomb is
//! stopped after a mebibyte. Every refusal names the entry: field
//! `archive[i]` (its index in the archive), the message its name.
//!
//! The scene file is `file` when given, else the one `.xml` or `.json` file
//! at the archive's root, or at the root of the folder that holds
//! everything (`zip -r lego.zip lego` packs `lego/scene.xml`). Its folder
//! becomes the bundle's root, as the scenes directory treats a scene folder.
//! Entries a packer adds on its own (`__MACOSX/`, `.DS_Store`) are skipped.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::bundle::{DocumentKind, SceneBundle, main_scene_file};
use super::error::SceneError;

/// Unpacked bytes an entry (or a gzipped tar as a whole) may reach before
/// its compression ratio is checked: small files compress as they like.
pub const RATIO_FLOOR: u64 = 1 << 20;

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
    /// Largest entry, unpacked bytes.
    pub max_entry_bytes: u64,
    /// Largest sum of the entries, unpacked bytes.
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

/// Unpacks `archive` (module docs) into a bundle of at most `max_entries`
/// files; `file` names the scene file (module docs).
pub fn unpack(
    archive: std::fs::File,
    format: ArchiveFormat,
    limits: &ArchiveLimits,
    max_entries: usize,
    file: Option<&str>,
) -> Result<Unpacked, SceneError> {
    let mut sink = Sink {
        bundle: SceneBundle::new(max_entries)?,
        limits: *limits,
        total: 0,
        buffer: vec![0u8; 64 * 1024],
    };
    match format {
        ArchiveFormat::Zip => unpack_zip(archive, &mut sink)?,
        ArchiveFormat::Tar => unpack_tar(archive, &mut sink, None)?,
        ArchiveFormat::TarGz => {
            let packed = Counted::new(std::io::BufReader::new(archive));
            let read = packed.count.clone();
            unpack_tar(flate2::read::GzDecoder::new(packed), &mut sink, Some(read))?;
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
struct Sink {
    bundle: SceneBundle,
    limits: ArchiveLimits,
    total: u64,
    /// Bytes between an entry's reader and its file, reused by every entry.
    buffer: Vec<u8>,
}

impl Sink {
    /// Writes entry `index` (`name`, `packed` bytes in the archive) from
    /// `reader`; `stream_packed` counts a gzipped tar's packed bytes.
    fn write(
        &mut self,
        index: usize,
        name: &str,
        reader: &mut dyn Read,
        packed: Option<u64>,
        stream_packed: Option<&std::sync::atomic::AtomicU64>,
    ) -> Result<(), SceneError> {
        let field = field(index);
        let refuse =
            |reason: String| SceneError::invalid(&field, format!("entry {name:?}: {reason}"));
        let mut out = self.bundle.create(name, &field)?;
        let mut written = 0u64;
        loop {
            let n = reader
                .read(&mut self.buffer)
                .map_err(|e| refuse(format!("cannot be unpacked: {e}")))?;
            if n == 0 {
                return Ok(());
            }
            written += n as u64;
            self.total += n as u64;
            if written > self.limits.max_entry_bytes {
                return Err(refuse(format!(
                    "unpacks to more than {} bytes (limits.max_asset_bytes)",
                    self.limits.max_entry_bytes
                )));
            }
            if self.total > self.limits.max_total_bytes {
                return Err(refuse(format!(
                    "takes the archive past {} unpacked bytes (limits.max_unpacked_bytes)",
                    self.limits.max_total_bytes
                )));
            }
            let ratio = |unpacked: u64, packed: u64| unpacked / packed.max(1);
            let inflated = match (packed, stream_packed) {
                (Some(packed), _) if written > RATIO_FLOOR => Some(ratio(written, packed)),
                (None, Some(read)) if self.total > RATIO_FLOOR => Some(ratio(
                    self.total,
                    read.load(std::sync::atomic::Ordering::Relaxed),
                )),
                _ => None,
            };
            if let Some(inflated) = inflated.filter(|r| *r > self.limits.max_ratio) {
                return Err(refuse(format!(
                    "inflates {inflated} times its packed size, more than {} \
                     (limits.max_compression_ratio)",
                    self.limits.max_ratio
                )));
            }
            std::io::Write::write_all(&mut out, &self.buffer[..n]).map_err(|e| SceneError::Io {
                file: PathBuf::from(name),
                source: e,
            })?;
        }
    }
}

fn field(index: usize) -> String {
    format!("archive[{index}]")
}

/// Whether a packer added entry `name` on its own (module docs).
fn is_packer_litter(name: &str) -> bool {
    name.starts_with("__MACOSX/") || name == ".DS_Store" || name.ends_with("/.DS_Store")
}

fn unpack_zip(archive: std::fs::File, sink: &mut Sink) -> Result<(), SceneError> {
    let mut zip = zip::ZipArchive::new(std::io::BufReader::new(archive))
        .map_err(|e| SceneError::invalid("body", format!("not a readable zip archive: {e}")))?;
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
        if entry.is_dir() || is_packer_litter(&name) {
            continue;
        }
        let packed = entry.compressed_size();
        sink.write(index, &name, &mut entry, Some(packed), None)?;
    }
    Ok(())
}

fn unpack_tar<R: Read>(
    reader: R,
    sink: &mut Sink,
    stream_packed: Option<std::sync::Arc<std::sync::atomic::AtomicU64>>,
) -> Result<(), SceneError> {
    let mut tar = tar::Archive::new(reader);
    let entries = tar
        .entries()
        .map_err(|e| SceneError::invalid("body", format!("not a readable tar archive: {e}")))?;
    for (index, entry) in entries.enumerate() {
        let mut entry =
            entry.map_err(|e| SceneError::invalid(field(index), format!("cannot be read: {e}")))?;
        let raw = String::from_utf8_lossy(&entry.path_bytes()).into_owned();
        // `tar -C dir -cf x.tar .` names everything `./…`.
        let name = raw.strip_prefix("./").unwrap_or(&raw).to_owned();
        let refuse =
            |reason: &str| SceneError::invalid(field(index), format!("entry {raw:?}: {reason}"));
        use tar::EntryType as T;
        match entry.header().entry_type() {
            T::Regular | T::Continuous => {}
            T::Directory => continue,
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
        }
        if name.is_empty() || is_packer_litter(&name) {
            continue;
        }
        sink.write(index, &name, &mut entry, None, stream_packed.as_deref())?;
    }
    Ok(())
}

/// A reader that counts the bytes read through it.
struct Counted<R> {
    inner: R,
    count: std::sync::Arc<std::sync::atomic::AtomicU64>,
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
        self.count
            .fetch_add(n as u64, std::sync::atomic::Ordering::Relaxed);
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

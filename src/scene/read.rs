//! Opening the files a scene names (scene documents, OBJ and PLY meshes, EXR
//! maps, PNG textures): only regular files, and never more bytes than a limit.
//!
//! A scenes directory may hold special files: a FIFO blocks `open()` until a
//! writer appears (forever, holding a worker thread), and a character device
//! such as a twin of `/dev/zero` reads endlessly while reporting size 0. So
//! the type is checked before opening (and again on the open handle), and
//! every read goes through [`Capped`], which counts bytes instead of trusting
//! the size the metadata reports.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::Path;

/// Opens `path` for reading if it is a regular file (after following links);
/// FIFOs, devices, sockets and directories are refused without opening them.
pub(crate) fn open_regular(path: &Path) -> io::Result<File> {
    let not_regular = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a directory, FIFO, socket or device)",
        )
    };
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let file = File::open(path)?;
    // The path could have been replaced between the check and the open.
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    Ok(file)
}

/// [`open_regular`], read through a [`Capped`] of `limit` bytes.
pub(crate) fn open_capped(path: &Path, limit: u64) -> io::Result<Capped<File>> {
    Ok(Capped::new(open_regular(path)?, limit))
}

/// The whole of a regular file as UTF-8 text, at most `limit` bytes.
pub(crate) fn read_to_string(path: &Path, limit: u64) -> io::Result<String> {
    let mut text = String::new();
    open_capped(path, limit)?.read_to_string(&mut text)?;
    Ok(text)
}

/// A reader that fails once more than `limit` bytes have been read (or a
/// seek goes past `limit`), so a file larger than announced, or endless,
/// costs at most `limit` bytes.
pub(crate) struct Capped<R> {
    inner: R,
    /// Offset of the next byte to read.
    position: u64,
    limit: u64,
    exceeded: bool,
}

impl<R> Capped<R> {
    pub(crate) fn new(inner: R, limit: u64) -> Self {
        Capped {
            inner,
            position: 0,
            limit,
            exceeded: false,
        }
    }

    /// True once a read or seek went past the limit; parsers that turn I/O
    /// errors into their own can be asked afterwards.
    pub(crate) fn exceeded(&self) -> bool {
        self.exceeded
    }

    fn too_large(&mut self) -> io::Error {
        self.exceeded = true;
        io::Error::new(
            io::ErrorKind::FileTooLarge,
            format!("larger than the {}-byte limit", self.limit),
        )
    }
}

impl<R: Read> Read for Capped<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        // One byte past the limit tells "exactly at the limit" from "over it".
        let allowed = (self.limit + 1).saturating_sub(self.position);
        if allowed == 0 {
            return Err(self.too_large());
        }
        let len = buf
            .len()
            .min(usize::try_from(allowed).unwrap_or(usize::MAX));
        let n = self.inner.read(&mut buf[..len])?;
        self.position += n as u64;
        if self.position > self.limit {
            return Err(self.too_large());
        }
        Ok(n)
    }
}

impl<R: Seek> Seek for Capped<R> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let position = self.inner.seek(to)?;
        self.position = position;
        if position > self.limit {
            return Err(self.too_large());
        }
        Ok(position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_up_to_the_limit_and_fails_past_it() {
        let mut text = String::new();
        Capped::new(&b"hello"[..], 5)
            .read_to_string(&mut text)
            .unwrap();
        assert_eq!(text, "hello");
        let mut reader = Capped::new(&b"hello!"[..], 5);
        let err = reader.read_to_string(&mut String::new()).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::FileTooLarge);
        assert!(reader.exceeded());
    }

    #[test]
    fn an_endless_reader_stops_at_the_limit() {
        let mut buf = Vec::new();
        let err = Capped::new(io::repeat(0), 1 << 20)
            .read_to_end(&mut buf)
            .unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::FileTooLarge);
        assert!(buf.len() <= (1 << 20) + 1);
    }

    #[test]
    fn special_files_are_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        assert!(open_regular(dir.path()).is_err());
        let fifo = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if made {
            // Opening a FIFO for reading would block until a writer appears.
            let err = open_regular(&fifo).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        }
        let err = open_regular(Path::new("/dev/zero")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        let file = dir.path().join("f.txt");
        std::fs::write(&file, "abc").unwrap();
        assert_eq!(read_to_string(&file, 3).unwrap(), "abc");
        assert!(read_to_string(&file, 2).is_err());
    }
}

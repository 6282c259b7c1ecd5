//! Reading a file whole, bounded: every file savsim reads into memory (scenes and the files
//! they name, manifests, DAIDALUS files, encounter models, flight logs, key files) goes through
//! [`read`], so a file larger than its kind allows, a device that never ends (`/dev/zero`), or a
//! FIFO that keeps writing is an error, never an allocation without bound or a read without
//! end. A FIFO or pipe is read up to the bound; a character or block device is refused.
//!
//! Every file savsim writes for others to read (shards, reports, summaries) goes through
//! [`write_atomic`]: whole or not at all.

use std::io::Read;
use std::path::Path;

/// The most a scene file, or a file a scene names (a mesh, a raster, an OSM extract, a city
/// model), may hold: 4 GiB.
pub const MAX_SCENE_FILE_BYTES: u64 = 4 << 30;
/// The most a manifest (batch or study), a DAIDALUS state file or configuration, or an
/// encounter model may hold: 4 GiB (one shard of a generated manifest stays well within:
/// docs/batch.md).
pub const MAX_TABLE_FILE_BYTES: u64 = 4 << 30;
/// The most a flight log read whole (ULog, DataFlash) may hold: 8 GiB.
pub const MAX_LOG_BYTES: u64 = 8 << 30;

/// Read the file at `path` whole, at most `limit` bytes. An error (`InvalidData`) names the
/// bound when the file holds more, and (`InvalidInput`) refuses a device.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("f");
/// std::fs::write(&path, b"12345").unwrap();
/// assert_eq!(savsim::files::read(&path, 5).unwrap(), b"12345");
/// assert!(savsim::files::read(&path, 4).is_err());
/// assert!(savsim::files::read(std::path::Path::new("/dev/zero"), 1 << 30).is_err());
/// ```
pub fn read(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    let kind = meta.file_type();
    if device(&kind) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "a device, not a file",
        ));
    }
    let too_large = || {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("larger than {limit} bytes, the most savsim reads of such a file"),
        )
    };
    if kind.is_file() && meta.len() > limit {
        return Err(too_large());
    }
    let mut bytes = Vec::with_capacity(if kind.is_file() {
        meta.len() as usize
    } else {
        0
    });
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large());
    }
    Ok(bytes)
}

/// Write the file at `path` whole or not at all: `write` fills `<path>.tmp` beside it, which is
/// synced and renamed into place, so that a reader (or a re-run looking for finished files)
/// sees the whole file or none, even when savsim is stopped. On any failure the temporary
/// file is removed and `path` is left as it was.
///
/// ```
/// use std::io::Write;
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("f.json");
/// savsim::files::write_atomic(&path, |w| w.write_all(b"{}")).unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), b"{}");
/// // A failed write leaves the file as it was, and nothing beside it.
/// let failed = savsim::files::write_atomic(&path, |_| Err(std::io::Error::other("no")));
/// assert!(failed.is_err());
/// assert_eq!(std::fs::read(&path).unwrap(), b"{}");
/// assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
/// // A directory in the way: an error, and no temporary file left.
/// assert!(savsim::files::write_atomic(dir.path(), |w| w.write_all(b"x")).is_err());
/// assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
/// ```
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".tmp");
    let tmp = path.with_file_name(name);
    let written = (|| {
        let mut out = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        write(&mut out)?;
        let file = out
            .into_inner()
            .map_err(std::io::IntoInnerError::into_error)?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// [`read`] as UTF-8 text.
pub fn read_text(path: &Path, limit: u64) -> std::io::Result<String> {
    String::from_utf8(read(path, limit)?)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))
}

/// Open `path` to stream it (a tlog): a device is refused, as by [`read`].
pub fn open_stream(path: &Path) -> std::io::Result<std::fs::File> {
    let file = std::fs::File::open(path)?;
    if device(&file.metadata()?.file_type()) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "a device, not a file",
        ));
    }
    Ok(file)
}

#[cfg(unix)]
fn device(kind: &std::fs::FileType) -> bool {
    use std::os::unix::fs::FileTypeExt;
    kind.is_char_device() || kind.is_block_device()
}

#[cfg(not(unix))]
fn device(_: &std::fs::FileType) -> bool {
    false
}

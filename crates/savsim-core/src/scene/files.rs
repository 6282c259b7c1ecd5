//! Where a scene's files come from. The core parses bytes; it does not open files. A caller
//! hands the loader a [`Files`]: the savsim binary reads the disk, a test or an embedding
//! program hands in bytes it holds ([`MemoryFiles`]).

use std::collections::BTreeMap;
use std::io;
use std::path::{Path, PathBuf};

/// Reads a file a scene names (the scene itself, a mesh, an elevation file, a CityJSON city).
pub trait Files {
    /// The whole file at `path`.
    fn read(&self, path: &Path) -> io::Result<Vec<u8>>;

    /// The whole file at `path` as UTF-8 text.
    fn read_text(&self, path: &Path) -> io::Result<String> {
        String::from_utf8(self.read(path)?)
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))
    }
}

/// Files held in memory, by path.
///
/// ```
/// use savsim_core::scene::files::{Files, MemoryFiles};
/// let mut files = MemoryFiles::default();
/// files.insert("a/b.txt", b"hello".to_vec());
/// assert_eq!(files.read_text("a/b.txt".as_ref()).unwrap(), "hello");
/// assert_eq!(files.read("c".as_ref()).unwrap_err().kind(), std::io::ErrorKind::NotFound);
/// ```
#[derive(Debug, Clone, Default)]
pub struct MemoryFiles {
    by_path: BTreeMap<PathBuf, Vec<u8>>,
}

impl MemoryFiles {
    /// Hold `bytes` as the file at `path`.
    pub fn insert(&mut self, path: impl Into<PathBuf>, bytes: Vec<u8>) {
        self.by_path.insert(path.into(), bytes);
    }
}

impl Files for MemoryFiles {
    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        self.by_path
            .get(path)
            .cloned()
            .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "no such file"))
    }
}

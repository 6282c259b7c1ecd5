//! Scenes ([`savsim_core::scene`]), read from the disk: the core parses the bytes, this module
//! opens the files.

use std::path::Path;

pub use savsim_core::scene::*;

/// The files of the machine savsim runs on.
#[derive(Debug, Clone, Copy, Default)]
pub struct Disk;

impl Files for Disk {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        crate::files::read(path, crate::files::MAX_SCENE_FILE_BYTES)
    }
}

/// Load the scene file at `path` from the disk (the files it names are read relative to it).
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("s.toml");
/// std::fs::write(&path, "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n").unwrap();
/// let scene = savsim::scene::load(&path).unwrap();
/// assert!(scene.obstacles.is_empty());
/// assert!(savsim::scene::load(&dir.path().join("missing.toml")).is_err());
/// ```
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    savsim_core::scene::load(path, &Disk)
}

/// Parse scene text from the disk's point of view: `path` names the file in errors, and the
/// files the scene names are read from the disk relative to it.
pub fn parse(text: &str, path: &Path, name: &str) -> Result<Scene, SceneError> {
    savsim_core::scene::format::parse(text, path, name, &Disk)
}

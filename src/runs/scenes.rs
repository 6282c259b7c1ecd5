//! The scenes a manifest's rows name, each loaded once per process (a scene that fails to load
//! fails every row that names it, with the same error), and open air for rows that name none.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use crate::scene::{self, Scene, SceneError};

/// Scenes by the path the rows give.
#[derive(Debug)]
pub struct SceneCache {
    open_air: Arc<Scene>,
    by_path: HashMap<String, Result<Arc<Scene>, Arc<SceneError>>>,
}

/// Why a row's scene is not there.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SceneLookup {
    /// The scene did not load (the error is shared by every row naming it).
    #[error(transparent)]
    Failed(Arc<SceneError>),
    /// A path that was not among those loaded (a bug of the caller).
    #[error("{0}: scene not loaded")]
    NotLoaded(String),
}

impl SceneCache {
    /// Load every scene `paths` names (empty paths mean [`open_air`]).
    pub fn load<'a>(paths: impl Iterator<Item = &'a str>) -> Self {
        let mut by_path = HashMap::new();
        for path in paths.filter(|p| !p.is_empty()) {
            if !by_path.contains_key(path) {
                let loaded = scene::load(Path::new(path)).map(Arc::new).map_err(Arc::new);
                by_path.insert(path.to_owned(), loaded);
            }
        }
        Self {
            open_air: Arc::new(open_air()),
            by_path,
        }
    }

    /// The scene at `path` (open air for none or an empty path).
    pub fn get(&self, path: Option<&str>) -> Result<Arc<Scene>, SceneLookup> {
        match path.filter(|p| !p.is_empty()) {
            None => Ok(self.open_air.clone()),
            Some(p) => match self.by_path.get(p) {
                Some(Ok(scene)) => Ok(scene.clone()),
                Some(Err(e)) => Err(SceneLookup::Failed(e.clone())),
                None => Err(SceneLookup::NotLoaded(p.to_owned())),
            },
        }
    }
}

/// A scene with nothing in it, around ArduPilot SITL's default home (CMAC, Canberra), whose
/// ENU frame encounters are written in.
pub fn open_air() -> Scene {
    let o = crate::scene::gen::DEFAULT_ORIGIN;
    let text = format!(
        "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n",
        o.lat_deg, o.lon_deg, o.alt_m
    );
    scene::parse(&text, Path::new("open-air.toml"), "open-air")
        .expect("the open-air scene is valid")
}

//! The TOML scene file: parse, validate, and build a [`Scene`]. The format, with every unit, is
//! documented in scenes/README.md. Errors name the file, the obstacle and the field. The items
//! as written are `scene::spec`'s, their shapes and positions `scene::build`'s, each section's
//! reading `scene::sections`'.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::scene::build::{field_of, Builder};
use crate::scene::sections::{self, Threats};
use crate::scene::spec::OriginSpec;
use crate::scene::{models, Files, Kind, Scene};

/// A scene file that cannot be used: which file, which item, which field, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {}{}{message}", item.as_ref().map(|i| format!("{i}: ")).unwrap_or_default(), field.as_ref().map(|f| format!("field `{f}`: ")).unwrap_or_default())]
pub struct SceneError {
    /// The scene file.
    pub file: PathBuf,
    /// The item, e.g. `obstacle "tower-1" (#3)`.
    pub item: Option<String>,
    /// The field within the item.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

/// Load the scene file at `path`, reading it and the files it names through `files`.
///
/// ```
/// use savsim_core::scene::{load, MemoryFiles};
/// let mut files = MemoryFiles::default();
/// files.insert("scenes/s.toml", br#"
/// [origin]
/// lat_deg = -35.363261
/// lon_deg = 149.165230
/// alt_m = 584.0
///
/// [[obstacle]]
/// id = "tower-1"
/// kind = "building"
/// shape = { box = [20.0, 20.0, 120.0] }
/// position_enu_m = [100.0, 250.0, 0.0]
/// yaw_deg = 0.0
/// "#.to_vec());
/// let scene = load("scenes/s.toml".as_ref(), &files).unwrap();
/// assert_eq!(scene.obstacles.len(), 1);
/// assert_eq!(scene.obstacles[0].aabb_enu_m.max.z, 120.0);
///
/// files.insert("scenes/s.toml", b"[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n\
///     [[obstacle]]\nid = \"x\"\nkind = \"castle\"\nshape = { box = [1.0, 1.0, 1.0] }\n\
///     position_enu_m = [0.0, 0.0, 0.0]\n".to_vec());
/// let e = load("scenes/s.toml".as_ref(), &files).unwrap_err().to_string();
/// assert!(e.contains("s.toml") && e.contains("obstacle \"x\"") && e.contains("castle"), "{e}");
/// ```
pub fn load(path: &Path, files: &dyn Files) -> Result<Scene, SceneError> {
    let text = files.read_text(path).map_err(|e| SceneError {
        file: path.to_path_buf(),
        item: None,
        field: None,
        message: e.to_string(),
    })?;
    let name = path
        .file_stem()
        .map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned());
    parse(&text, path, &name, files)
}

/// Parse scene text; `path` names the file in errors and anchors relative paths, which are
/// read through `files`.
pub fn parse(text: &str, path: &Path, name: &str, files: &dyn Files) -> Result<Scene, SceneError> {
    let fail = |item: Option<String>, field: Option<String>, message: String| SceneError {
        file: path.to_path_buf(),
        item,
        field,
        message,
    };
    let root = read_sections(text, &fail)?;
    let origin = read_origin(&root, &fail)?;
    let mut b = Builder {
        file: path,
        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        files,
        plane: LocalTangentPlane::new(origin),
        geometries: Vec::new(),
        mesh_files: BTreeMap::new(),
    };
    // Geometry 0 is the default vehicle model.
    b.add(models::quad());

    let threats = Threats::read(&b, root.get("threat"))?;
    let array = |key: &str| -> Result<Vec<toml::Value>, SceneError> {
        match root.get(key) {
            None => Ok(Vec::new()),
            Some(toml::Value::Array(a)) => Ok(a.clone()),
            Some(_) => Err(fail(
                None,
                Some(key.into()),
                format!("write it as [[{key}]] tables"),
            )),
        }
    };

    let vehicle_models = sections::vehicles(&mut b, &array("vehicle")?)?;
    let mut ids = std::collections::HashSet::new();
    let mut obstacles = Vec::new();
    sections::obstacles(
        &mut b,
        &array("obstacle")?,
        &threats,
        &mut ids,
        &mut obstacles,
    )?;
    sections::terrain(&mut b, &array("terrain")?, &threats, &mut obstacles)?;
    sections::cities(&mut b, &array("city")?, &threats, &mut ids, &mut obstacles)?;
    let osm = sections::osm(&mut b, &array("osm")?, &threats, &mut ids, &mut obstacles)?;

    let mut kind_models = Vec::new();
    for kind in Kind::ALL {
        let g = models::for_kind(kind).map_err(|m| b.err(None, None, m))?;
        kind_models.push((kind, b.add(g)));
    }

    let dynamic = sections::dynamic(&mut b, &array("dynamic")?, &threats, &kind_models, &mut ids)?;
    let sensors = sections::sensors(&b, &array("sensor")?)?;

    Ok(Scene {
        name: name.to_owned(),
        origin,
        threat_by_kind: threats.0,
        obstacles,
        dynamic,
        geometries: b.geometries,
        vehicle_models,
        kind_models,
        osm,
        sensors,
    })
}

/// The file's TOML, every top-level key a known section.
fn read_sections(
    text: &str,
    fail: &dyn Fn(Option<String>, Option<String>, String) -> SceneError,
) -> Result<toml::Table, SceneError> {
    let root: toml::Table = toml::from_str(text).map_err(|e| {
        let message = e.to_string().trim().to_owned();
        fail(None, None, message)
    })?;
    for key in root.keys() {
        if ![
            "origin", "threat", "vehicle", "obstacle", "dynamic", "terrain", "city", "osm",
            "sensor",
        ]
        .contains(&key.as_str())
        {
            return Err(fail(
                None,
                Some(key.clone()),
                "unknown section (known: origin, threat, vehicle, obstacle, dynamic, terrain, city, osm, sensor)"
                    .into(),
            ));
        }
    }
    Ok(root)
}

/// `[origin]`: the scene's geodetic origin, a valid position.
fn read_origin(
    root: &toml::Table,
    fail: &dyn Fn(Option<String>, Option<String>, String) -> SceneError,
) -> Result<Geodetic, SceneError> {
    let origin_value = root
        .get("origin")
        .ok_or_else(|| fail(None, Some("origin".into()), "missing [origin]".into()))?;
    let origin: OriginSpec = OriginSpec::deserialize(origin_value.clone()).map_err(|e| {
        let message = e.to_string().trim().to_owned();
        fail(Some("[origin]".into()), field_of(&message), message)
    })?;
    let origin = Geodetic::new(origin.lat_deg, origin.lon_deg, origin.alt_m);
    if !origin.is_valid() {
        return Err(fail(
            Some("[origin]".into()),
            None,
            format!("{origin:?} is not a valid position"),
        ));
    }
    Ok(origin)
}

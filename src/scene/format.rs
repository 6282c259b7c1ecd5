//! The TOML scene file: parse, validate, and build a [`Scene`]. The format, with every unit, is
//! documented in scenes/README.md. Errors name the file, the obstacle and the field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};
use serde::Deserialize;

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
use crate::scene::mesh_files::load_mesh_file;
use crate::scene::terrain::{self, Elevation};
use crate::scene::{
    cityjson, gen, models, DynamicObstacle, DynamicSource, Kind, Placement, Scene, StaticObstacle,
    Waypoint,
};

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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OriginSpec {
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
}

/// A shape as written in a scene file: exactly one of `box`, `mesh`, `blocks`, `model`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeSpec {
    /// Box size east, north, up, metres (base centre at the position).
    #[serde(rename = "box")]
    pub box_m: Option<[f64; 3]>,
    /// A mesh file (OBJ, STL, glTF/GLB), relative to the scene file.
    pub mesh: Option<String>,
    /// Scale applied to a mesh (metres per file unit). Default 1.
    pub scale: Option<f64>,
    /// The mesh's up axis, "z" or "y". Default "y" for OBJ and glTF, "z" for STL.
    pub up: Option<String>,
    /// Blocks `[x0, y0, z0, x1, y1, z1]`, metres in the obstacle frame.
    pub blocks: Option<Vec<[f64; 6]>>,
    /// Facade cell size for blocks, metres (0 = two triangles per face). Default 0.
    pub tessellate_m: Option<f64>,
    /// A built-in model name.
    pub model: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum ModelSpec {
    Name(String),
    Shape(ShapeSpec),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObstacleSpec {
    id: String,
    kind: Kind,
    shape: ShapeSpec,
    position_enu_m: Option<[f64; 3]>,
    position_geo: Option<[f64; 3]>,
    #[serde(default)]
    yaw_deg: f64,
    threat: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct VehicleSpec {
    system_id: Option<u8>,
    model: ModelSpec,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DynamicSpec {
    id: String,
    kind: Kind,
    model: Option<ModelSpec>,
    waypoints: Option<Vec<Waypoint>>,
    system_id: Option<u8>,
    icao: Option<u32>,
    threat: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GeneratedTerrainSpec {
    seed: u64,
    size_m: [f64; 2],
    cell_m: f64,
    relief_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TerrainSpec {
    id: String,
    #[serde(default = "default_terrain_kind")]
    kind: Kind,
    file: Option<String>,
    generated: Option<GeneratedTerrainSpec>,
    /// South-west corner of the grid, scene ENU metres. Default: the grid centred on the origin.
    position_enu_m: Option<[f64; 3]>,
    /// Cells per patch side. Default 32.
    patch_cells: Option<usize>,
    threat: Option<f64>,
    /// For files: the area to load. Default 4 km x 4 km around the scene origin.
    area: Option<AreaSpec>,
    /// For files: grid spacing, metres. Default: the file's own spacing, within 10..25 m.
    cell_m: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CitySpec {
    id: String,
    file: String,
    /// Where the dataset's anchor goes: [lat_deg, lon_deg, alt_m AMSL].
    anchor_geo: [f64; 3],
    /// The anchor in dataset coordinates. Default: bounding-box centre at z = 0.
    anchor_xyz: Option<[f64; 3]>,
    /// Grid north of the dataset's projection, counter-clockwise from true north, degrees.
    #[serde(default)]
    rotation_deg: f64,
    /// CityObject types to load. Default: Building, BuildingPart, Bridge.
    types: Option<Vec<String>>,
    threat: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AreaSpec {
    /// Centre, [lat_deg, lon_deg]. Default: the scene origin.
    center_geo: Option<[f64; 2]>,
    /// Size east, north, metres.
    size_m: [f64; 2],
}

fn default_terrain_kind() -> Kind {
    Kind::Mountain
}

struct Builder<'a> {
    file: &'a Path,
    dir: PathBuf,
    plane: LocalTangentPlane,
    geometries: Vec<Arc<Geometry>>,
    mesh_files: BTreeMap<(PathBuf, u64, bool), usize>,
}

impl Builder<'_> {
    fn err(&self, item: Option<String>, field: Option<&str>, message: impl ToString) -> SceneError {
        SceneError {
            file: self.file.to_path_buf(),
            item,
            field: field.map(str::to_owned),
            message: message.to_string(),
        }
    }

    fn add(&mut self, geometry: Geometry) -> usize {
        self.geometries.push(Arc::new(geometry));
        self.geometries.len() - 1
    }

    fn shape(&mut self, spec: &ShapeSpec, item: &str, field: &str) -> Result<usize, SceneError> {
        let e = |b: &Self, m: String| b.err(Some(item.to_owned()), Some(field), m);
        let given = [
            spec.box_m.is_some(),
            spec.mesh.is_some(),
            spec.blocks.is_some(),
            spec.model.is_some(),
        ];
        if given.iter().filter(|&&g| g).count() != 1 {
            return Err(e(
                self,
                "give exactly one of `box`, `mesh`, `blocks`, `model`".into(),
            ));
        }
        if let Some([x, y, z]) = spec.box_m {
            let half = Vec3::new(x as f32 / 2.0, y as f32 / 2.0, 0.0);
            let g = Geometry::cuboid(-half, Vec3::new(half.x, half.y, z as f32))
                .map_err(|m| e(self, format!("box {:?}: {m}", [x, y, z])))?;
            return Ok(self.add(g));
        }
        if let Some(blocks) = &spec.blocks {
            let blocks = blocks
                .iter()
                .map(|b| {
                    (
                        Vec3::new(b[0] as f32, b[1] as f32, b[2] as f32),
                        Vec3::new(b[3] as f32, b[4] as f32, b[5] as f32),
                    )
                })
                .collect();
            let g = Geometry::blocks(blocks, spec.tessellate_m.unwrap_or(0.0) as f32)
                .map_err(|m| e(self, format!("blocks: {m}")))?;
            return Ok(self.add(g));
        }
        if let Some(name) = &spec.model {
            let g = models::by_name(name).ok_or_else(|| {
                e(
                    self,
                    format!(
                        "unknown model {name:?} (known: {})",
                        models::MODEL_NAMES.join(", ")
                    ),
                )
            })?;
            return Ok(self.add(g));
        }
        let mesh = spec.mesh.as_deref().unwrap_or_default();
        let path = self.dir.join(mesh);
        let scale = spec.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale > 0.0) {
            return Err(self.err(
                Some(item.to_owned()),
                Some("shape.scale"),
                format!("{scale} is not a positive number"),
            ));
        }
        let is_stl = path
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("stl"));
        let is_dae = path
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("dae"));
        let y_up = match spec.up.as_deref() {
            None => !is_stl && !is_dae,
            Some("y") => true,
            Some("z") => false,
            Some(other) => {
                return Err(self.err(
                    Some(item.to_owned()),
                    Some("shape.up"),
                    format!("{other:?}: use \"y\" or \"z\""),
                ))
            }
        };
        let key = (path.clone(), scale.to_bits(), y_up);
        if let Some(&index) = self.mesh_files.get(&key) {
            return Ok(index);
        }
        let (vertices, indices) =
            load_mesh_file(&path).map_err(|m| e(self, format!("{}: {m}", path.display())))?;
        let vertices = vertices
            .into_iter()
            .map(|v| {
                let v = if y_up { Vec3::new(v.x, -v.z, v.y) } else { v };
                v * scale as f32
            })
            .collect();
        let g = Geometry::mesh(vertices, indices)
            .map_err(|m| e(self, format!("{}: {m}", path.display())))?;
        let index = self.add(g);
        self.mesh_files.insert(key, index);
        Ok(index)
    }

    fn model(&mut self, spec: &ModelSpec, item: &str) -> Result<usize, SceneError> {
        match spec {
            ModelSpec::Name(name) => self.shape(
                &ShapeSpec {
                    model: Some(name.clone()),
                    ..ShapeSpec::default()
                },
                item,
                "model",
            ),
            ModelSpec::Shape(shape) => self.shape(shape, item, "model"),
        }
    }

    fn position(
        &self,
        enu: Option<[f64; 3]>,
        geo: Option<[f64; 3]>,
        item: &str,
    ) -> Result<DVec3, SceneError> {
        let p = match (enu, geo) {
            (Some(p), None) => DVec3::from(p),
            (None, Some([lat, lon, alt])) => {
                let g = Geodetic::new(lat, lon, alt);
                if !g.is_valid() {
                    return Err(self.err(
                        Some(item.to_owned()),
                        Some("position_geo"),
                        format!(
                            "{:?} is not a valid [lat_deg, lon_deg, alt_m]",
                            [lat, lon, alt]
                        ),
                    ));
                }
                self.plane.enu_m_from_geodetic(&g)
            }
            _ => {
                return Err(self.err(
                    Some(item.to_owned()),
                    Some("position_enu_m"),
                    "give exactly one of `position_enu_m` and `position_geo`",
                ))
            }
        };
        if !p.is_finite() {
            return Err(self.err(Some(item.to_owned()), Some("position_enu_m"), "not finite"));
        }
        Ok(p)
    }
}

fn item_name(what: &str, table: &toml::Value, index: usize) -> String {
    match table.get("id").and_then(toml::Value::as_str) {
        Some(id) => format!("{what} {id:?} (#{})", index + 1),
        None => format!("{what} #{}", index + 1),
    }
}

/// Split a serde error message into the field it names and the rest.
fn field_of(message: &str) -> Option<String> {
    let start = message.find('`')? + 1;
    let end = start + message[start..].find('`')?;
    Some(message[start..end].to_owned())
}

fn parse_item<T: serde::de::DeserializeOwned>(
    b: &Builder<'_>,
    value: &toml::Value,
    item: &str,
) -> Result<T, SceneError> {
    T::deserialize(value.clone()).map_err(|e| {
        let message = e.to_string().trim().to_owned();
        b.err(
            Some(item.to_owned()),
            field_of(&message).as_deref(),
            message,
        )
    })
}

/// Load a scene file.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("s.toml");
/// std::fs::write(&path, r#"
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
/// "#).unwrap();
/// let scene = savsim::scene::load(&path).unwrap();
/// assert_eq!(scene.obstacles.len(), 1);
/// assert_eq!(scene.obstacles[0].aabb_enu_m.max.z, 120.0);
///
/// std::fs::write(&path, "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n\
///     [[obstacle]]\nid = \"x\"\nkind = \"castle\"\nshape = { box = [1.0, 1.0, 1.0] }\n\
///     position_enu_m = [0.0, 0.0, 0.0]\n").unwrap();
/// let e = savsim::scene::load(&path).unwrap_err().to_string();
/// assert!(e.contains("s.toml") && e.contains("obstacle \"x\"") && e.contains("castle"), "{e}");
/// ```
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError {
        file: path.to_path_buf(),
        item: None,
        field: None,
        message: e.to_string(),
    })?;
    let name = path
        .file_stem()
        .map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned());
    parse(&text, path, &name)
}

/// Parse scene text; `path` names the file in errors and anchors relative paths.
pub fn parse(text: &str, path: &Path, name: &str) -> Result<Scene, SceneError> {
    let fail = |item: Option<String>, field: Option<String>, message: String| SceneError {
        file: path.to_path_buf(),
        item,
        field,
        message,
    };
    let root: toml::Table = toml::from_str(text).map_err(|e| {
        let message = e.to_string().trim().to_owned();
        fail(None, None, message)
    })?;
    for key in root.keys() {
        if ![
            "origin", "threat", "vehicle", "obstacle", "dynamic", "terrain", "city",
        ]
        .contains(&key.as_str())
        {
            return Err(fail(
                None,
                Some(key.clone()),
                "unknown section (known: origin, threat, vehicle, obstacle, dynamic, terrain, city)"
                    .into(),
            ));
        }
    }
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
    let mut b = Builder {
        file: path,
        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        plane: LocalTangentPlane::new(origin),
        geometries: Vec::new(),
        mesh_files: BTreeMap::new(),
    };
    // Geometry 0 is the default vehicle model.
    b.add(models::quad());

    let threat_overrides: BTreeMap<Kind, f64> = match root.get("threat") {
        Some(v) => parse_item(&b, v, "[threat]")?,
        None => BTreeMap::new(),
    };
    let mut threat_by_kind = Vec::new();
    for kind in Kind::ALL {
        let t = threat_overrides
            .get(&kind)
            .copied()
            .unwrap_or(kind.paper_threat());
        if !t.is_finite() {
            return Err(b.err(Some("[threat]".into()), Some(kind.name()), "not finite"));
        }
        threat_by_kind.push((kind, t));
    }
    let threat_of = |kind: Kind, own: Option<f64>| {
        own.unwrap_or_else(|| threat_by_kind.iter().find(|(k, _)| *k == kind).unwrap().1)
    };

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

    let mut vehicle_models = vec![(None, 0)];
    for (i, value) in array("vehicle")?.iter().enumerate() {
        let item = item_name("vehicle", value, i);
        let spec: VehicleSpec = parse_item(&b, value, &item)?;
        let g = b.model(&spec.model, &item)?;
        vehicle_models.retain(|(id, _)| *id != spec.system_id);
        vehicle_models.push((spec.system_id, g));
    }

    let mut ids = std::collections::HashSet::new();
    let mut obstacles = Vec::new();
    for (i, value) in array("obstacle")?.iter().enumerate() {
        let item = item_name("obstacle", value, i);
        let spec: ObstacleSpec = parse_item(&b, value, &item)?;
        if !ids.insert(spec.id.clone()) {
            return Err(b.err(Some(item), Some("id"), "duplicate id"));
        }
        let geometry_index = b.shape(&spec.shape, &item, "shape")?;
        let position = b.position(spec.position_enu_m, spec.position_geo, &item)?;
        if !spec.yaw_deg.is_finite() {
            return Err(b.err(Some(item), Some("yaw_deg"), "not finite"));
        }
        let placement = Placement::from_yaw(position, spec.yaw_deg);
        let geometry = b.geometries[geometry_index].clone();
        obstacles.push(StaticObstacle {
            id: spec.id,
            kind: spec.kind,
            threat: threat_of(spec.kind, spec.threat),
            aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
            placement,
            geometry,
            geometry_index,
        });
    }

    for (i, value) in array("terrain")?.iter().enumerate() {
        let item = item_name("terrain", value, i);
        let spec: TerrainSpec = parse_item(&b, value, &item)?;
        let (grid, file_corner) = match (&spec.file, &spec.generated) {
            (None, Some(g)) => {
                if !(g.cell_m > 0.0 && g.size_m.iter().all(|s| *s >= g.cell_m) && g.relief_m >= 0.0)
                    || g.size_m.iter().any(|s| s / g.cell_m > 20_000.0)
                {
                    return Err(b.err(
                        Some(item),
                        Some("generated"),
                        "need cell_m > 0, size_m >= cell_m (at most 20000 cells a side), relief_m >= 0",
                    ));
                }
                (
                    gen::terrain_grid(g.seed, g.size_m, g.cell_m, g.relief_m),
                    None,
                )
            }
            (Some(file), None) => {
                let path = b.dir.join(file);
                let elevation = Elevation::load(&path).map_err(|m| {
                    b.err(
                        Some(item.clone()),
                        Some("file"),
                        format!("{}: {m}", path.display()),
                    )
                })?;
                let (centre, size_m) = match &spec.area {
                    Some(a) => (a.center_geo, a.size_m),
                    None => (None, [4000.0, 4000.0]),
                };
                let centre_enu = match centre {
                    Some([lat, lon]) => {
                        let g = Geodetic::new(lat, lon, 0.0);
                        if !g.is_valid() {
                            return Err(b.err(
                                Some(item),
                                Some("area.center_geo"),
                                "not a valid [lat_deg, lon_deg]",
                            ));
                        }
                        let p = b.plane.enu_m_from_geodetic(&g);
                        DVec3::new(p.x, p.y, 0.0)
                    }
                    None => DVec3::ZERO,
                };
                // Default: the file's spacing, but at most 25 m, so the triangles follow the
                // file's bilinear surface closely.
                let cell_m = spec
                    .cell_m
                    .unwrap_or_else(|| elevation.spacing_m().clamp(10.0, 25.0));
                if !(cell_m > 0.0
                    && size_m
                        .iter()
                        .all(|s| *s >= cell_m && s / cell_m <= 20_000.0))
                {
                    return Err(b.err(
                        Some(item),
                        Some("area.size_m"),
                        "need size_m >= cell_m > 0, at most 20000 cells a side",
                    ));
                }
                let corner = centre_enu - DVec3::new(size_m[0], size_m[1], 0.0) * 0.5;
                let grid = terrain::resample(&elevation, &b.plane, corner, size_m, cell_m)
                    .map_err(|m| {
                        b.err(
                            Some(item.clone()),
                            Some("area"),
                            format!("{}: {m}", path.display()),
                        )
                    })?;
                (grid, Some(corner))
            }
            _ => {
                return Err(b.err(
                    Some(item),
                    Some("file"),
                    "give exactly one of `file` and `generated`",
                ))
            }
        };
        let grid = Arc::new(grid);
        let extent = DVec3::new(
            (grid.nx - 1) as f64 * grid.cell_m as f64,
            (grid.ny - 1) as f64 * grid.cell_m as f64,
            0.0,
        );
        let corner = match (spec.position_enu_m, file_corner) {
            (Some(p), _) => DVec3::from(p),
            (None, Some(c)) => c,
            (None, None) => -extent * 0.5,
        };
        let patch_cells = spec.patch_cells.unwrap_or(32).max(1);
        let threat = threat_of(spec.kind, spec.threat);
        for (geometry, x0, y0) in terrain_patches(&grid, patch_cells) {
            let geometry_index = b.add(geometry);
            let geometry = b.geometries[geometry_index].clone();
            let placement = Placement::from_yaw(
                corner + DVec3::new(x0 as f64, y0 as f64, 0.0) * grid.cell_m as f64,
                0.0,
            );
            obstacles.push(StaticObstacle {
                id: format!("{}/{}_{}", spec.id, x0 / patch_cells, y0 / patch_cells),
                kind: spec.kind,
                threat,
                aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
                placement,
                geometry,
                geometry_index,
            });
        }
    }

    for (i, value) in array("city")?.iter().enumerate() {
        let item = item_name("city", value, i);
        let spec: CitySpec = parse_item(&b, value, &item)?;
        let path = b.dir.join(&spec.file);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            b.err(
                Some(item.clone()),
                Some("file"),
                format!("{}: {e}", path.display()),
            )
        })?;
        let [lat, lon, alt] = spec.anchor_geo;
        let anchor = Geodetic::new(lat, lon, alt);
        if !anchor.is_valid() || !spec.rotation_deg.is_finite() {
            return Err(b.err(
                Some(item),
                Some("anchor_geo"),
                "not a valid [lat_deg, lon_deg, alt_m]",
            ));
        }
        let types = spec.types.clone().unwrap_or_else(|| {
            ["Building", "BuildingPart", "Bridge"]
                .map(str::to_owned)
                .to_vec()
        });
        let city = cityjson::buildings(&text, &types, spec.anchor_xyz, spec.rotation_deg).map_err(
            |m| {
                b.err(
                    Some(item.clone()),
                    Some("file"),
                    format!("{}: {m}", path.display()),
                )
            },
        )?;
        let anchor_enu = b.plane.enu_m_from_geodetic(&anchor);
        // The dataset's axes are the anchor's local east, north, up, turned into the plane's.
        let plane_from_local = b.plane.plane_enu_from_local_enu_at(&anchor);
        let rotation = glam::DQuat::from_mat3(&plane_from_local);
        let threat = threat_of(Kind::Building, spec.threat);
        for building in city {
            let id = format!("{}/{}", spec.id, building.id);
            if !ids.insert(id.clone()) {
                return Err(b.err(Some(item), Some("id"), format!("duplicate id {id:?}")));
            }
            let geometry_index = b.add(building.geometry);
            let geometry = b.geometries[geometry_index].clone();
            let placement = Placement {
                position_enu_m: anchor_enu + plane_from_local * building.origin_from_anchor_m,
                enu_from_local: rotation,
            };
            obstacles.push(StaticObstacle {
                id,
                kind: Kind::Building,
                threat,
                aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
                placement,
                geometry,
                geometry_index,
            });
        }
    }

    let mut kind_models = Vec::new();
    for kind in Kind::ALL {
        let g = models::for_kind(kind).map_err(|m| b.err(None, None, m))?;
        kind_models.push((kind, b.add(g)));
    }

    let mut dynamic = Vec::new();
    for (i, value) in array("dynamic")?.iter().enumerate() {
        let item = item_name("dynamic", value, i);
        let spec: DynamicSpec = parse_item(&b, value, &item)?;
        if !ids.insert(spec.id.clone()) {
            return Err(b.err(Some(item), Some("id"), "duplicate id"));
        }
        let source = match (spec.waypoints, spec.system_id, spec.icao) {
            (Some(w), None, None) => {
                if w.is_empty()
                    || w.windows(2).any(|p| p[1].t_s <= p[0].t_s)
                    || w.iter()
                        .any(|p| !p.t_s.is_finite() || !DVec3::from(p.position_enu_m).is_finite())
                {
                    return Err(b.err(
                        Some(item),
                        Some("waypoints"),
                        "need at least one waypoint, finite values, t_s strictly increasing",
                    ));
                }
                DynamicSource::Waypoints(w)
            }
            (None, Some(id), None) => DynamicSource::SystemId(id),
            (None, None, Some(icao)) => DynamicSource::Icao(icao),
            _ => {
                return Err(b.err(
                    Some(item),
                    Some("waypoints"),
                    "give exactly one of `waypoints`, `system_id`, `icao`",
                ))
            }
        };
        let geometry_index = match &spec.model {
            Some(m) => b.model(m, &item)?,
            None => kind_models.iter().find(|(k, _)| *k == spec.kind).unwrap().1,
        };
        dynamic.push(DynamicObstacle {
            id: spec.id.into(),
            kind: spec.kind,
            threat: threat_of(spec.kind, spec.threat),
            geometry: b.geometries[geometry_index].clone(),
            geometry_index,
            source,
        });
    }

    Ok(Scene {
        name: name.to_owned(),
        origin,
        threat_by_kind: threat_by_kind.clone(),
        obstacles,
        dynamic,
        geometries: b.geometries,
        vehicle_models,
        kind_models,
    })
}

/// Cut a grid into patches of `patch_cells` cells a side (sharing their edge samples).
fn terrain_patches(
    grid: &Arc<HeightGrid>,
    patch_cells: usize,
) -> impl Iterator<Item = (Geometry, usize, usize)> + '_ {
    let ys = (0..grid.ny - 1).step_by(patch_cells);
    ys.flat_map(move |y0| {
        (0..grid.nx - 1).step_by(patch_cells).filter_map(move |x0| {
            let patch = TerrainPatch {
                grid: grid.clone(),
                x0,
                y0,
                nx: (patch_cells + 1).min(grid.nx - x0),
                ny: (patch_cells + 1).min(grid.ny - y0),
                base_m: 0.0,
            };
            Geometry::terrain(patch).ok().map(|g| (g, x0, y0))
        })
    })
}

//! Building a scene from its items: geometries (boxes, blocks, models, mesh files) and
//! positions, with errors that name the file, the item and the field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::scene::geometry::Geometry;
use crate::scene::mesh_files::load_mesh_file;
use crate::scene::models;
use crate::scene::spec::{ModelSpec, ShapeSpec};
use crate::scene::{Files, Kind, Placement, SceneError, StaticObstacle};

/// What building a scene keeps while it reads the file: where it is, the local plane, the
/// geometries so far and the mesh files already loaded.
pub(crate) struct Builder<'a> {
    pub(crate) file: &'a Path,
    pub(crate) dir: PathBuf,
    /// Where the files the scene names are read from.
    pub(crate) files: &'a dyn Files,
    pub(crate) plane: LocalTangentPlane,
    pub(crate) geometries: Vec<Arc<Geometry>>,
    pub(crate) mesh_files: BTreeMap<(PathBuf, u64, bool), usize>,
}

impl Builder<'_> {
    pub(crate) fn err(
        &self,
        item: Option<String>,
        field: Option<&str>,
        message: impl ToString,
    ) -> SceneError {
        SceneError {
            file: self.file.to_path_buf(),
            item,
            field: field.map(str::to_owned),
            message: message.to_string(),
        }
    }

    /// A static obstacle `id` of `kind` and `threat`: geometry `geometry_index` placed at
    /// `placement`, its bounds computed.
    pub(crate) fn obstacle(
        &self,
        id: String,
        kind: Kind,
        threat: f64,
        placement: Placement,
        geometry_index: usize,
    ) -> StaticObstacle {
        let geometry = self.geometries[geometry_index].clone();
        StaticObstacle {
            id,
            kind,
            threat,
            aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
            placement,
            geometry,
            geometry_index,
        }
    }

    /// An error of item `item`'s `file` field: the file at `path` and what is wrong with it.
    pub(crate) fn file_err(
        &self,
        item: &str,
        path: &std::path::Path,
        why: impl std::fmt::Display,
    ) -> SceneError {
        self.err(
            Some(item.to_owned()),
            Some("file"),
            format!("{}: {why}", path.display()),
        )
    }

    pub(crate) fn add(&mut self, geometry: Geometry) -> usize {
        self.geometries.push(Arc::new(geometry));
        self.geometries.len() - 1
    }

    pub(crate) fn shape(
        &mut self,
        spec: &ShapeSpec,
        item: &str,
        field: &str,
    ) -> Result<usize, SceneError> {
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
        let (vertices, indices) = load_mesh_file(&path, self.files)
            .map_err(|m| e(self, format!("{}: {m}", path.display())))?;
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

    pub(crate) fn model(&mut self, spec: &ModelSpec, item: &str) -> Result<usize, SceneError> {
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

    pub(crate) fn position(
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

pub(crate) fn item_name(what: &str, table: &toml::Value, index: usize) -> String {
    match table.get("id").and_then(toml::Value::as_str) {
        Some(id) => format!("{what} {id:?} (#{})", index + 1),
        None => format!("{what} #{}", index + 1),
    }
}

/// Split a serde error message into the field it names and the rest.
pub(crate) fn field_of(message: &str) -> Option<String> {
    let start = message.find('`')? + 1;
    let end = start + message[start..].find('`')?;
    Some(message[start..end].to_owned())
}

pub(crate) fn parse_item<T: serde::de::DeserializeOwned>(
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

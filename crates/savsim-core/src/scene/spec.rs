//! The scene file's items as written (serde), before they are checked and built: the format,
//! with every unit, is documented in scenes/README.md.

use serde::Deserialize;

use crate::scene::{Kind, Waypoint};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct OriginSpec {
    pub(crate) lat_deg: f64,
    pub(crate) lon_deg: f64,
    pub(crate) alt_m: f64,
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
pub(crate) enum ModelSpec {
    /// A built-in model's name.
    Name(String),
    /// A shape.
    Shape(ShapeSpec),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObstacleSpec {
    pub(crate) id: String,
    pub(crate) kind: Kind,
    pub(crate) shape: ShapeSpec,
    pub(crate) position_enu_m: Option<[f64; 3]>,
    pub(crate) position_geo: Option<[f64; 3]>,
    #[serde(default)]
    pub(crate) yaw_deg: f64,
    pub(crate) threat: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct VehicleSpec {
    pub(crate) system_id: Option<u8>,
    pub(crate) model: ModelSpec,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DynamicSpec {
    pub(crate) id: String,
    pub(crate) kind: Kind,
    pub(crate) model: Option<ModelSpec>,
    pub(crate) waypoints: Option<Vec<Waypoint>>,
    pub(crate) system_id: Option<u8>,
    pub(crate) icao: Option<u32>,
    pub(crate) threat: Option<f64>,
    pub(crate) transponder: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GeneratedTerrainSpec {
    pub(crate) seed: u64,
    pub(crate) size_m: [f64; 2],
    pub(crate) cell_m: f64,
    pub(crate) relief_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TerrainSpec {
    pub(crate) id: String,
    #[serde(default = "default_terrain_kind")]
    pub(crate) kind: Kind,
    pub(crate) file: Option<String>,
    pub(crate) generated: Option<GeneratedTerrainSpec>,
    /// Heights given in the file, metres: rows from south to north, each from west to east,
    /// `cell_m` apart.
    pub(crate) heights_m: Option<Vec<Vec<f64>>>,
    /// South-west corner of the grid, scene ENU metres. Default: the grid centred on the origin.
    pub(crate) position_enu_m: Option<[f64; 3]>,
    /// Cells per patch side. Default 32.
    pub(crate) patch_cells: Option<usize>,
    pub(crate) threat: Option<f64>,
    /// For files: the area to load. Default 4 km x 4 km around the scene origin.
    pub(crate) area: Option<AreaSpec>,
    /// For files: grid spacing, metres. Default: the file's own spacing, within 10..25 m. For
    /// `heights_m`: the spacing of the heights (required).
    pub(crate) cell_m: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CitySpec {
    pub(crate) id: String,
    pub(crate) file: String,
    /// Where the dataset's anchor goes: [lat_deg, lon_deg, alt_m AMSL].
    pub(crate) anchor_geo: [f64; 3],
    /// The anchor in dataset coordinates. Default: bounding-box centre at z = 0.
    pub(crate) anchor_xyz: Option<[f64; 3]>,
    /// Grid north of the dataset's projection, counter-clockwise from true north, degrees.
    #[serde(default)]
    pub(crate) rotation_deg: f64,
    /// CityObject types to load. Default: Building, BuildingPart, Bridge.
    pub(crate) types: Option<Vec<String>>,
    pub(crate) threat: Option<f64>,
}

/// `[[osm]]`: an OpenStreetMap file's buildings.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct OsmSpec {
    pub(crate) id: String,
    /// `.osm` (XML) or `.osm.pbf`.
    pub(crate) file: String,
    /// Metres per level (`building:levels`). Default 3.
    pub(crate) level_m: Option<f64>,
    /// The height of a building that gives neither `height` nor `building:levels`. Default 10.
    pub(crate) default_height_m: Option<f64>,
    pub(crate) threat: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct AreaSpec {
    /// Centre, [lat_deg, lon_deg]. Default: the scene origin.
    pub(crate) center_geo: Option<[f64; 2]>,
    /// Size east, north, metres.
    pub(crate) size_m: [f64; 2],
}

pub(crate) fn default_terrain_kind() -> Kind {
    Kind::Mountain
}

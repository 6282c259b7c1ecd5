//! Scenes: a geodetic origin, static obstacles, dynamic obstacles and vehicle models.
//!
//! - [`geometry`]: shapes kept as descriptions, triangles on demand; [`surface`]: queries of a
//!   terrain patch's surface.
//! - [`format`](mod@format): the TOML scene file (documented in scenes/README.md) and its loader;
//!   `spec` (the items as written), `build` (shapes, positions), `sections` (each section read).
//! - [`mesh_files`]: OBJ, STL, glTF/GLB and COLLADA readers.
//! - [`models`]: built-in models (the default quadcopter, airliners, balloons).
//! - [`gen`]: the deterministic `city` and `mountain` generators.
//!
//! The loaded [`Scene`] is plain data in local ENU metres relative to the origin; nothing here
//! builds colliders (that is `collision`'s job) or knows of MAVLink sockets.

pub(crate) mod build;
pub mod cityjson;
pub mod extrude;
pub mod files;
pub mod format;
pub mod gen;
pub mod geometry;
pub mod info;
pub mod mesh_files;
pub mod models;
pub mod osm;
pub(crate) mod sections;
pub mod spec;
pub mod surface;
pub mod terrain;

use std::sync::Arc;

use glam::{DQuat, DVec3};
use parry3d::bounding_volume::Aabb;

use crate::geo::Geodetic;
pub use files::{Files, MemoryFiles};
pub use format::{load, SceneError};
use geometry::Geometry;

/// What an obstacle is: decides its threat T (paper Table 1) and its default model.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Airbus A320 (dynamic), T = 75.
    A320,
    /// Boeing 737 (dynamic), T = 75.
    B737,
    /// Small multirotor, DJI class (dynamic), T = 45.
    Dji,
    /// Airship (dynamic), T = 30.
    Airship,
    /// Hot-air balloon (dynamic), T = 25.
    Balloon,
    /// Building (static), T = 60.
    Building,
    /// Mountain or terrain (static), T = 65.
    Mountain,
    /// Tree (static), T = 20.
    Tree,
}

impl Kind {
    /// Every kind, in table order.
    pub const ALL: [Kind; 8] = [
        Kind::A320,
        Kind::B737,
        Kind::Dji,
        Kind::Airship,
        Kind::Balloon,
        Kind::Building,
        Kind::Mountain,
        Kind::Tree,
    ];

    /// The paper's threat value T for this kind (Table 1).
    ///
    /// ```
    /// use savsim_core::scene::Kind;
    /// assert_eq!(Kind::Building.paper_threat(), 60.0);
    /// assert_eq!(Kind::Tree.paper_threat(), 20.0);
    /// ```
    pub fn paper_threat(self) -> f64 {
        match self {
            Kind::A320 | Kind::B737 => 75.0,
            Kind::Dji => 45.0,
            Kind::Airship => 30.0,
            Kind::Balloon => 25.0,
            Kind::Building => 60.0,
            Kind::Mountain => 65.0,
            Kind::Tree => 20.0,
        }
    }

    /// The snake_case name used in scene files and events.
    pub fn name(self) -> &'static str {
        match self {
            Kind::A320 => "a320",
            Kind::B737 => "b737",
            Kind::Dji => "dji",
            Kind::Airship => "airship",
            Kind::Balloon => "balloon",
            Kind::Building => "building",
            Kind::Mountain => "mountain",
            Kind::Tree => "tree",
        }
    }

    /// The kind of a name as [`Kind::name`] gives it.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The kind an ADS-B emitter type (ADSB_EMITTER_TYPE) stands for.
    pub fn from_adsb_emitter(emitter_type: u8) -> Kind {
        match emitter_type {
            3..=5 => Kind::A320,        // large, high-vortex large, heavy
            7 | 14 => Kind::Dji,        // rotorcraft, UAV
            10 => Kind::Balloon,        // lighter than air
            1 | 2 | 6 | 9 => Kind::Dji, // light, small, manoeuvrable, glider: small aircraft
            _ => Kind::A320,            // unknown: assume the worst
        }
    }
}

/// A rigid placement in the scene: position (f64, local ENU metres) and orientation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Where the geometry's local origin is, metres from the scene origin.
    pub position_enu_m: DVec3,
    /// Rotation from the geometry's frame to ENU.
    pub enu_from_local: DQuat,
}

impl Placement {
    /// A placement with a yaw (degrees, counter-clockwise seen from above, from east).
    pub fn from_yaw(position_enu_m: DVec3, yaw_deg: f64) -> Self {
        Self {
            position_enu_m,
            enu_from_local: DQuat::from_rotation_z(yaw_deg.to_radians()),
        }
    }

    /// A point of the geometry's frame in ENU.
    pub fn enu_from_local_point(&self, local: DVec3) -> DVec3 {
        self.position_enu_m + self.enu_from_local * local
    }

    /// The ENU bounding box of a local box under this placement.
    pub fn enu_aabb(&self, local: &Aabb) -> Aabb64 {
        let mut out = Aabb64::EMPTY;
        for i in 0..8 {
            let corner = DVec3::new(
                if i & 1 == 0 {
                    local.mins.x
                } else {
                    local.maxs.x
                } as f64,
                if i & 2 == 0 {
                    local.mins.y
                } else {
                    local.maxs.y
                } as f64,
                if i & 4 == 0 {
                    local.mins.z
                } else {
                    local.maxs.z
                } as f64,
            );
            out = out.including(self.enu_from_local_point(corner));
        }
        out
    }
}

/// An axis-aligned box in f64 (scene ENU metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb64 {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb64 {
    /// The empty box (contains nothing; grows with `including`).
    pub const EMPTY: Aabb64 = Aabb64 {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// A box from corners.
    pub fn new(min: DVec3, max: DVec3) -> Self {
        Self { min, max }
    }

    /// The box around `centre` reaching `half` each way.
    pub fn around(centre: DVec3, half: DVec3) -> Self {
        Self::new(centre - half, centre + half)
    }

    /// This box grown to contain `p`.
    pub fn including(self, p: DVec3) -> Self {
        Self::new(self.min.min(p), self.max.max(p))
    }

    /// The union of two boxes.
    pub fn union(self, other: Aabb64) -> Self {
        Self::new(self.min.min(other.min), self.max.max(other.max))
    }

    /// This box grown by `margin` on every side.
    pub fn inflated(self, margin: f64) -> Self {
        Self::new(
            self.min - DVec3::splat(margin),
            self.max + DVec3::splat(margin),
        )
    }

    /// True when the boxes overlap (touching counts).
    pub fn intersects(&self, other: &Aabb64) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }

    /// True when `p` is inside or on the box.
    pub fn contains(&self, p: DVec3) -> bool {
        self.min.cmple(p).all() && p.cmple(self.max).all()
    }

    /// Centre of the box.
    pub fn centre(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    /// Slab test: does the segment from `origin` along `dir` (unit) up to `max_m` meet the box?
    ///
    /// ```
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let b = Aabb64::new(DVec3::new(10.0, -1.0, -1.0), DVec3::new(12.0, 1.0, 1.0));
    /// assert!(b.ray_hits(DVec3::ZERO, DVec3::X, 10.5));
    /// assert!(!b.ray_hits(DVec3::ZERO, DVec3::X, 9.5));
    /// assert!(!b.ray_hits(DVec3::ZERO, DVec3::NEG_X, 100.0));
    /// ```
    pub fn ray_hits(&self, origin: DVec3, dir: DVec3, max_m: f64) -> bool {
        self.ray_entry(origin, dir, max_m).is_some()
    }

    /// Where the segment from `origin` along `dir` (unit) up to `max_m` enters the box: the
    /// distance (0 when it starts inside), or `None` if it misses.
    ///
    /// ```
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let b = Aabb64::new(DVec3::new(10.0, -1.0, -1.0), DVec3::new(12.0, 1.0, 1.0));
    /// assert_eq!(b.ray_entry(DVec3::ZERO, DVec3::X, 100.0), Some(10.0));
    /// assert_eq!(b.ray_entry(DVec3::new(11.0, 0.0, 0.0), DVec3::X, 100.0), Some(0.0));
    /// assert_eq!(b.ray_entry(DVec3::ZERO, DVec3::Y, 100.0), None);
    /// assert_eq!(b.ray_entry(DVec3::ZERO, DVec3::ZERO, 100.0), None);
    /// assert_eq!(b.ray_entry(DVec3::ZERO, DVec3::NAN, 100.0), None);
    /// ```
    pub fn ray_entry(&self, origin: DVec3, dir: DVec3, max_m: f64) -> Option<f64> {
        if !(dir.is_finite() && origin.is_finite()) || dir == DVec3::ZERO {
            return None;
        }
        let (mut enter, mut exit) = (0.0f64, max_m);
        for axis in 0..3 {
            let (o, d) = (origin[axis], dir[axis]);
            let (lo, hi) = (self.min[axis], self.max[axis]);
            if d == 0.0 {
                // Parallel to this slab: inside it (its faces included) or never.
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((lo - o) / d, (hi - o) / d);
            enter = enter.max(t0.min(t1));
            exit = exit.min(t0.max(t1));
        }
        (enter <= exit).then_some(enter)
    }

    /// Distance from `p` to the box (0 inside).
    pub fn distance_to(&self, p: DVec3) -> f64 {
        (self.min - p).max(p - self.max).max(DVec3::ZERO).length()
    }

    /// Euclidean distance between the nearest points of this box and `other` (0 when they
    /// meet).
    ///
    /// ```
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let a = Aabb64::new(DVec3::ZERO, DVec3::ONE);
    /// let b = Aabb64::new(DVec3::new(4.0, 5.0, 0.5), DVec3::new(5.0, 6.0, 2.0));
    /// assert_eq!(a.distance_to_box(&b), 5.0);
    /// assert_eq!(a.distance_to_box(&a), 0.0);
    /// ```
    pub fn distance_to_box(&self, other: &Aabb64) -> f64 {
        (self.min - other.max)
            .max(other.min - self.max)
            .max(DVec3::ZERO)
            .length()
    }
}

/// A static obstacle (building, terrain patch, tree).
#[derive(Debug, Clone)]
pub struct StaticObstacle {
    /// Unique id from the scene file.
    pub id: String,
    /// Kind (threat class).
    pub kind: Kind,
    /// Threat T used in beta (Table 1 or the scene's override).
    pub threat: f64,
    /// Where the geometry is.
    pub placement: Placement,
    /// The shape, shared between obstacles that use the same model.
    pub geometry: Arc<Geometry>,
    /// Index of `geometry` in [`Scene::geometries`] (the mesh cache key).
    pub geometry_index: usize,
    /// Bounds in scene ENU metres.
    pub aabb_enu_m: Aabb64,
}

impl StaticObstacle {
    /// Height (ENU up, metres) of this terrain patch's surface at (east, north), if it is
    /// terrain and lies there.
    pub fn terrain_height_enu_m(&self, east_m: f64, north_m: f64) -> Option<f64> {
        let local = self.placement.enu_from_local.inverse()
            * (DVec3::new(east_m, north_m, 0.0) - self.placement.position_enu_m);
        let h = self
            .geometry
            .terrain_height_at(local.x as f32, local.y as f32)?;
        Some(self.placement.position_enu_m.z + f64::from(h))
    }
}

/// One timed point of a scripted track.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Waypoint {
    /// Seconds after the flight's first position.
    pub t_s: f64,
    /// Position, scene ENU metres.
    pub position_enu_m: [f64; 3],
}

/// Where a dynamic obstacle's motion comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum DynamicSource {
    /// A scripted track (linear between waypoints, held at the ends).
    Waypoints(Vec<Waypoint>),
    /// Another MAVLink vehicle, by system id.
    SystemId(u8),
    /// ADS-B traffic, by ICAO address.
    Icao(u32),
}

/// A moving obstacle declared in the scene.
#[derive(Debug, Clone)]
pub struct DynamicObstacle {
    /// Unique id.
    pub id: Arc<str>,
    /// Kind (threat class and default model).
    pub kind: Kind,
    /// Threat T.
    pub threat: f64,
    /// Its shape (the kind's built-in model unless the scene says otherwise).
    pub geometry: Arc<Geometry>,
    /// Mesh cache key.
    pub geometry_index: usize,
    /// Where its motion comes from.
    pub source: DynamicSource,
    /// Whether it carries a transponder (ADS-B out): ADS-B devices report it; without one,
    /// only radar and EO/IR see it. Default true.
    pub transponder: bool,
}

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Name (file stem or generator name), for summaries.
    pub name: String,
    /// The geodetic origin of the local ENU frame.
    pub origin: Geodetic,
    /// Threat T per kind after overrides.
    pub threat_by_kind: Vec<(Kind, f64)>,
    /// Static obstacles.
    pub obstacles: Vec<StaticObstacle>,
    /// Declared dynamic obstacles.
    pub dynamic: Vec<DynamicObstacle>,
    /// Every distinct geometry (obstacles, dynamic obstacles, vehicles, kind models).
    pub geometries: Vec<Arc<Geometry>>,
    /// Vehicle model per system id (`None` = default for all), as a geometry index.
    pub vehicle_models: Vec<(Option<u8>, usize)>,
    /// Geometry index of the model used for traffic of each kind that has no declared model.
    pub kind_models: Vec<(Kind, usize)>,
    /// What each `[[osm]]` file gave.
    pub osm: Vec<OsmStats>,
    /// The vehicles' sensors the scene defines (`[[sensor]]`), each checked; empty when it
    /// defines none (the run's `--sensors` decides).
    pub sensors: Vec<crate::sensors::spec::DeviceSpec>,
}

/// What one `[[osm]]` file gave: its buildings and where their heights came from.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct OsmStats {
    /// The `[[osm]]` id.
    pub id: String,
    /// Buildings (and building parts) made obstacles.
    pub buildings: usize,
    /// Of those, `building:part`s.
    pub parts: usize,
    /// Inner rings (courtyards) of the buildings and parts assembled, as OpenStreetMap draws
    /// them (libosmium's count).
    pub holes: usize,
    /// Holes the parts cut in the outlines they leave (where a part stands inside its
    /// outline): filled by the part, not courtyards.
    pub holes_cut_by_parts: usize,
    /// Heights from `height`.
    pub height_from_tag: usize,
    /// Heights from `building:levels`.
    pub height_from_levels: usize,
    /// Heights defaulted.
    pub height_defaulted: usize,
    /// Outlines their parts cover entirely: replaced by them.
    pub outlines_replaced: usize,
    /// Outlines their parts cover in part: kept as the pieces the parts leave.
    pub outlines_trimmed: usize,
    /// Pieces of trimmed outlines too thin or small to keep (`scene::osm::SLIVER_WIDTH_M`).
    pub slivers_dropped: usize,
    /// Building ways not closed, relations whose rings do not close, footprints with no area
    /// or with a base not below the top: not obstacles.
    pub skipped: usize,
}

impl Scene {
    /// Threat T of a kind in this scene.
    pub fn threat_of(&self, kind: Kind) -> f64 {
        self.threat_by_kind
            .iter()
            .find(|(k, _)| *k == kind)
            .map_or(kind.paper_threat(), |(_, t)| *t)
    }

    /// Geometry index of the model for vehicle `system_id`.
    pub fn vehicle_model(&self, system_id: u8) -> usize {
        self.vehicle_models
            .iter()
            .find(|(id, _)| *id == Some(system_id))
            .or_else(|| self.vehicle_models.iter().find(|(id, _)| id.is_none()))
            .map(|(_, g)| *g)
            .unwrap_or(0)
    }

    /// Geometry index of the model for traffic of `kind`.
    pub fn kind_model(&self, kind: Kind) -> usize {
        self.kind_models
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|(_, g)| *g)
            .unwrap_or(0)
    }

    /// Add a scripted track of `kind` (the kind's model; linear between `waypoints`, held at
    /// the ends), e.g. a study row's intruder, with a transponder. False, and nothing added,
    /// when `id` is taken.
    pub fn push_track(&mut self, id: &str, kind: Kind, waypoints: Vec<Waypoint>) -> bool {
        if self.dynamic.iter().any(|d| &*d.id == id) {
            return false;
        }
        let geometry_index = self.kind_model(kind);
        self.dynamic.push(DynamicObstacle {
            id: id.into(),
            kind,
            threat: self.threat_of(kind),
            geometry: self.geometries[geometry_index].clone(),
            geometry_index,
            source: DynamicSource::Waypoints(waypoints),
            transponder: true,
        });
        true
    }

    /// Height (ENU up, metres) of the highest terrain surface at (east, north), if any terrain
    /// lies there. A scan of the terrain patches, for set-up code; the collision core asks its
    /// octree instead.
    pub fn ground_height_enu_m(&self, east_m: f64, north_m: f64) -> Option<f64> {
        let mut ground: Option<f64> = None;
        for o in self.obstacles.iter().filter(|o| o.geometry.is_terrain()) {
            let b = &o.aabb_enu_m;
            if !(b.min.x <= east_m && east_m <= b.max.x && b.min.y <= north_m && north_m <= b.max.y)
            {
                continue;
            }
            if let Some(z) = o.terrain_height_enu_m(east_m, north_m) {
                ground = Some(ground.map_or(z, |g| g.max(z)));
            }
        }
        ground
    }

    /// Bounds of all static obstacles, scene ENU metres.
    pub fn bounds_enu_m(&self) -> Aabb64 {
        self.obstacles
            .iter()
            .fold(Aabb64::EMPTY, |b, o| b.union(o.aabb_enu_m))
    }
}

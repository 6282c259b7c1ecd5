//! Exact ray fans: what a range sensor on the vehicle measures. Each ray is cast against the
//! exact shape of every obstacle it can reach (static ones front to back through the static `Bvh`,
//! stopping at the nearest hit; moving ones by a scan), whatever collider the sensing layer
//! holds for it: a sensor sees the world, not the model of it. The closed-loop feed casts its
//! sectors here (`crate::feed`).
//!
//! Pure and synchronous; imports no I/O.

use glam::DVec3;

use crate::collision::bodies::{BodySource, ObstacleRef};
use crate::collision::contact::queries;
use crate::collision::meshes::MeshCache;
use crate::collision::view::{view, World};
use crate::scene::{Aabb64, Kind};
use crate::sensors::image::{Segment, SegmentClass};

/// A fan of rays from one point: unit directions, ENU, and how far they reach.
#[derive(Debug, Clone, Copy)]
pub struct Rays<'a> {
    /// Where they start, scene ENU metres.
    pub origin_enu_m: DVec3,
    /// Their directions, ENU unit vectors.
    pub dirs_enu: &'a [DVec3],
    /// How far they reach, metres.
    pub max_m: f64,
}

/// The nearest obstacle along the ray from `origin_enu_m` in direction `dir_enu` (unit), and
/// its distance, metres, up to `max_m`. An origin inside a solid (or under the terrain) is at
/// distance 0.
pub(crate) fn nearest(
    world: &World<'_>,
    meshes: &mut MeshCache,
    origin_enu_m: DVec3,
    dir_enu: DVec3,
    max_m: f64,
) -> Option<(ObstacleRef, f64)> {
    // Under the terrain is inside it, however far below its box.
    if let Some((i, ground)) = world.statics.terrain_under(world.scene, origin_enu_m) {
        if origin_enu_m.z < ground {
            return Some((ObstacleRef::Static(i), 0.0));
        }
    }
    // `bounds_checked`: the broad phase already knows the ray meets the obstacle's bounds.
    let mut test = |o: ObstacleRef, limit: f64, bounds_checked: bool| {
        let v = view(world.scene, world.dynamic, o)?;
        if !bounds_checked && !v.aabb_enu_m.ray_hits(origin_enu_m, dir_enu, limit) {
            return None;
        }
        let body = world
            .shapes
            .body(v.geometry_index, v.geometry, meshes, v.current, false);
        queries::ray_distance_m(origin_enu_m, dir_enu, limit, &body.placed())
            .filter(|&d| d <= limit)
    };
    let mut best = world
        .statics
        .cast_ray(origin_enu_m, dir_enu, max_m, |i, limit| {
            test(ObstacleRef::Static(i), limit, true)
        })
        .map(|(i, d)| (ObstacleRef::Static(i), d));
    let reach = Aabb64::new(origin_enu_m, origin_enu_m).union(Aabb64::new(
        origin_enu_m + dir_enu * max_m,
        origin_enu_m + dir_enu * max_m,
    ));
    world.moving_near(&reach, 0.0, |_, d| {
        let limit = best.map_or(max_m, |b| b.1);
        let o = ObstacleRef::Dynamic(d.key);
        if let Some(distance) = test(o, limit, false).filter(|&x| x < limit) {
            best = Some((o, distance));
        }
    });
    best
}

/// The first segment id of a scene's moving obstacle (`| index`); static obstacles are
/// `index + 1` below it.
pub const SEGMENT_SCRIPTED: u32 = 0x0100_0000;
/// The first segment id of a vehicle (`| system id << 8 | component id`).
pub const SEGMENT_VEHICLE: u32 = 0x0200_0000;
/// The first segment id of ADS-B traffic (`| ICAO address`).
pub const SEGMENT_TRAFFIC: u32 = 0x0300_0000;

/// What obstacle `o` is in a segmentation: its id (a static obstacle's index + 1; a moving
/// obstacle's, a vehicle's and an aircraft's by the constants above, so that an id names the
/// same body in every frame) and its class (a static obstacle's from its kind, which
/// `static_kind` gives by index: `|i| scene.obstacles.get(i).map(|o| o.kind)`).
///
/// ```
/// use savsim_core::collision::fan::{segment_of, SEGMENT_VEHICLE};
/// use savsim_core::pipeline::{BodyKey, BodySource, ObstacleRef};
/// use savsim_core::sensors::image::SegmentClass;
/// let other = BodyKey {
///     source: BodySource::Vehicle { vehicle: 2, component_id: 1 },
///     generation: 0,
/// };
/// let s = segment_of(ObstacleRef::Dynamic(other), |_| None);
/// assert_eq!((s.id, s.class), (SEGMENT_VEHICLE | 0x0201, SegmentClass::Vehicle));
/// ```
pub fn segment_of(o: ObstacleRef, static_kind: impl FnOnce(usize) -> Option<Kind>) -> Segment {
    match o {
        ObstacleRef::Static(i) => Segment {
            id: i.saturating_add(1).min(SEGMENT_SCRIPTED - 1),
            class: match static_kind(i as usize) {
                Some(Kind::Mountain) => SegmentClass::Terrain,
                Some(Kind::Tree) => SegmentClass::Tree,
                _ => SegmentClass::Building,
            },
        },
        ObstacleRef::Dynamic(key) => match key.source {
            BodySource::Scripted(j) => Segment {
                id: SEGMENT_SCRIPTED | (j & 0x00FF_FFFF),
                class: SegmentClass::Aircraft,
            },
            BodySource::Vehicle {
                vehicle,
                component_id,
            } => Segment {
                id: SEGMENT_VEHICLE | (u32::from(vehicle) & 0xFFFF) << 8 | u32::from(component_id),
                class: SegmentClass::Vehicle,
            },
            BodySource::Traffic(icao) => Segment {
                id: SEGMENT_TRAFFIC | (icao & 0x00FF_FFFF),
                class: SegmentClass::Aircraft,
            },
        },
    }
}

//! Exact ray fans: what a range sensor on the vehicle measures. Each ray is cast against the
//! exact shape of every obstacle it can reach (static ones found for chunks of neighbouring
//! rays, stretch by stretch outwards, or through the static `Bvh` where a stretch holds many;
//! moving ones by a scan), whatever collider the sensing layer holds for it: a sensor sees the
//! world, not the model of it. The closed-loop feed casts its sectors and its devices' images
//! here (`crate::feed`); [`segment_of`] names what a ray met in a segmentation.
//!
//! Pure and synchronous; imports no I/O.

use glam::DVec3;

use crate::collision::bodies::{BodyKey, BodySource, ObstacleRef};
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

/// Consecutive rays of a fan cast together: they share their candidates.
const CHUNK: usize = 32;
/// The first stretch of a chunk's rays looked at, metres; each next one twice as long.
const FIRST_STRETCH_M: f64 = 16.0;
/// A stretch whose box holds more static obstacles than this: the chunk's rays not yet
/// answered go through the tree instead.
const LINEAR_MAX: usize = 64;

/// Scratch of a fan's cast, kept between fans (no allocation once grown).
#[derive(Debug, Clone, Default)]
pub(crate) struct FanScratch {
    statics: Vec<u32>,
    movers: Vec<BodyKey>,
}

/// Every ray of `rays`: `put(i, hit)` with the nearest obstacle along ray `i` and its
/// distance, by the exact tests a single ray's cast makes (so the same distances).
///
/// Rays are taken in chunks of consecutive ones (neighbours in an image or a scan), and each
/// chunk outwards in stretches of distance (8 m, then 16, 32, ...): the static obstacles whose
/// boxes meet a stretch's box (over the chunk's rays not yet answered) are found once, each
/// such ray tries their boxes (f64) and the exact shapes it enters, and a ray is answered once
/// its nearest hit lies within the stretches looked at (any obstacle not yet tried is beyond
/// them). A stretch with many obstacles in its box sends the rest of the chunk's rays through
/// the tree, one by one. Moving bodies near the chunk are tried by every ray; the terrain
/// under the origin is looked up once.
pub(crate) fn cast_fan(
    world: &World<'_>,
    meshes: &mut MeshCache,
    rays: Rays<'_>,
    scratch: &mut FanScratch,
    mut put: impl FnMut(usize, Option<(ObstacleRef, f64)>),
) {
    let origin = rays.origin_enu_m;
    if let Some((i, ground)) = world.statics.terrain_under(world.scene, origin) {
        if origin.z < ground {
            for k in 0..rays.dirs_enu.len() {
                put(k, Some((ObstacleRef::Static(i), 0.0)));
            }
            return;
        }
    }
    for (c, chunk) in rays.dirs_enu.chunks(CHUNK).enumerate() {
        let mut best = [None; CHUNK];
        cast_statics(world, meshes, origin, chunk, rays.max_m, scratch, &mut best);
        let reach = chunk.iter().fold(Aabb64::new(origin, origin), |b, d| {
            let end = origin + *d * rays.max_m;
            b.union(Aabb64::new(end, end))
        });
        scratch.movers.clear();
        world.moving_near(&reach, 0.0, |_, d| scratch.movers.push(d.key));
        for (j, dir) in chunk.iter().enumerate() {
            let mut best = best[j];
            for &key in &scratch.movers {
                let limit = best.map_or(rays.max_m, |b: (ObstacleRef, f64)| b.1);
                let o = ObstacleRef::Dynamic(key);
                if let Some(d) = exact_distance(world, meshes, o, origin, *dir, limit, false)
                    .filter(|&x| x < limit)
                {
                    best = Some((o, d));
                }
            }
            put(c * CHUNK + j, best);
        }
    }
}

/// The nearest static obstacle along each ray of `chunk`, into `best`: stretch by stretch
/// outwards (see [`cast_fan`]).
fn cast_statics(
    world: &World<'_>,
    meshes: &mut MeshCache,
    origin: DVec3,
    chunk: &[DVec3],
    max_m: f64,
    scratch: &mut FanScratch,
    best: &mut [Option<(ObstacleRef, f64)>; CHUNK],
) {
    let mut done = [false; CHUNK];
    let (mut near, mut far) = (0.0, FIRST_STRETCH_M.min(max_m));
    loop {
        let stretch =
            chunk
                .iter()
                .zip(&done)
                .filter(|(_, &d)| !d)
                .fold(Aabb64::EMPTY, |b, (dir, _)| {
                    let (a, z) = (origin + *dir * near, origin + *dir * far);
                    b.union(Aabb64::new(a.min(z), a.max(z)))
                });
        scratch.statics.clear();
        world
            .statics
            .query_aabb(&stretch, |i| scratch.statics.push(i));
        let through_tree = scratch.statics.len() > LINEAR_MAX;
        for (j, dir) in chunk.iter().enumerate() {
            if done[j] {
                continue;
            }
            let mut test = |i: u32, limit: f64| {
                exact_distance(
                    world,
                    meshes,
                    ObstacleRef::Static(i),
                    origin,
                    *dir,
                    limit,
                    true,
                )
            };
            if through_tree {
                best[j] = world
                    .statics
                    .cast_ray(origin, *dir, max_m, test)
                    .map(|(i, d)| (ObstacleRef::Static(i), d));
                done[j] = true;
                continue;
            }
            for &i in &scratch.statics {
                let limit = best[j].map_or(max_m, |b| b.1);
                let entered = world
                    .statics
                    .boxes()
                    .get(i as usize)
                    .and_then(|b| b.ray_entry(origin, *dir, limit));
                if entered.is_none() {
                    continue;
                }
                if let Some(d) = test(i, limit).filter(|&d| d < limit) {
                    best[j] = Some((ObstacleRef::Static(i), d));
                }
            }
            done[j] = best[j].is_some_and(|b| b.1 <= far);
        }
        if far >= max_m || done.iter().take(chunk.len()).all(|&d| d) {
            return;
        }
        (near, far) = (far, (far * 2.0).min(max_m));
    }
}

/// The exact distance to obstacle `o` along the ray, if it is hit within `limit`
/// (`bounds_checked`: its box is known to be entered).
fn exact_distance(
    world: &World<'_>,
    meshes: &mut MeshCache,
    o: ObstacleRef,
    origin_enu_m: DVec3,
    dir_enu: DVec3,
    limit: f64,
    bounds_checked: bool,
) -> Option<f64> {
    let v = view(world.scene, world.dynamic, o)?;
    if !bounds_checked && !v.aabb_enu_m.ray_hits(origin_enu_m, dir_enu, limit) {
        return None;
    }
    let body = world
        .shapes
        .body(v.geometry_index, v.geometry, meshes, v.current, false);
    queries::ray_distance_m(origin_enu_m, dir_enu, limit, &body.placed()).filter(|&d| d <= limit)
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

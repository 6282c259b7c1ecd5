//! The bench's flight set: deterministic flights built from the scene's own content (its
//! streets, towers, concave buildings, thin obstacles and terrain), so that the same command
//! gives the same flights on any machine, and a user's own scene gets flights of the same
//! families.
//!
//! A flight's description says what it was built to do ("passes 2.0 m from b17's east
//! face"); the bench's truth is the `reference` mode, never the description.
//!
//! [`flight_set`] reads the scene once (`Setting`) and asks each family for its flights
//! (`families`); where a family's flights go is found in the scene's boxes and blocks
//! (`search`).

mod families;
mod search;

use std::f64::consts::PI;

use glam::{DQuat, DVec3};

use crate::geo::LocalTangentPlane;
use crate::pipeline::{BodyKey, BodyPose, BodySource, DynamicBody};
use crate::scene::{Kind, Scene};
use crate::world::{Attitude, TrackSample};

/// Every flight's clock starts here, seconds (any value would do; not 0, so that a clock
/// that starts at 0 is not special).
const T0_S: f64 = 1000.0;

/// Another aircraft on a straight course.
#[derive(Debug, Clone, PartialEq)]
pub struct Traffic {
    /// Id in events.
    pub id: std::sync::Arc<str>,
    /// What it is (threat class and model).
    pub kind: Kind,
    /// Where it is at the flight's first sample, scene ENU metres.
    pub start_enu_m: DVec3,
    /// Its constant velocity, ENU m/s.
    pub velocity_enu_mps: DVec3,
}

impl Traffic {
    /// Its pose at `t_s` (the flights' clock).
    pub fn pose_at(&self, t_s: f64) -> BodyPose {
        BodyPose {
            position_enu_m: self.start_enu_m + self.velocity_enu_mps * (t_s - T0_S),
            enu_from_body: level_frd(self.velocity_enu_mps),
        }
    }

    /// The moving obstacle between two sample times; `index` numbers it in its flight.
    pub fn body(&self, scene: &Scene, index: u32, t_before_s: f64, t_now_s: f64) -> DynamicBody {
        DynamicBody {
            key: BodyKey {
                source: BodySource::Scripted(index),
                generation: 0,
            },
            id: self.id.clone(),
            kind: self.kind,
            threat: scene.threat_of(self.kind),
            geometry_index: scene.kind_model(self.kind),
            previous: self.pose_at(t_before_s),
            current: self.pose_at(t_now_s),
            speed_mps: self.velocity_enu_mps.length(),
        }
    }
}

/// One bench flight.
#[derive(Debug, Clone, PartialEq)]
pub struct Flight {
    /// Short unique name (`near-miss-2m`).
    pub name: String,
    /// What it was built to do.
    pub what: String,
    /// Telemetry rate, Hz.
    pub rate_hz: f64,
    /// Ground speed, m/s (the largest, for terrain following).
    pub speed_mps: f64,
    /// The vehicle's samples.
    pub samples: Vec<TrackSample>,
    /// Other aircraft.
    pub traffic: Vec<Traffic>,
}

impl Flight {
    /// A flight without other aircraft.
    fn alone(
        name: String,
        what: String,
        rate_hz: f64,
        speed_mps: f64,
        samples: Vec<TrackSample>,
    ) -> Self {
        Flight {
            name,
            what,
            rate_hz,
            speed_mps,
            samples,
            traffic: vec![],
        }
    }
}

/// Rotation from a level body flying along `velocity` (nose east when still) to ENU.
fn level_frd(velocity_enu_mps: DVec3) -> DQuat {
    let heading = if velocity_enu_mps.truncate().length() > 1e-9 {
        velocity_enu_mps.y.atan2(velocity_enu_mps.x)
    } else {
        0.0
    };
    DQuat::from_rotation_z(heading) * DQuat::from_rotation_x(PI)
}

/// Samples of `position(t)` (t in seconds from the start) for `duration_s` at `rate_hz`, level,
/// nose along the velocity.
fn sampled(
    plane: &LocalTangentPlane,
    rate_hz: f64,
    duration_s: f64,
    position: impl Fn(f64) -> DVec3,
) -> Vec<TrackSample> {
    sampled_banked(plane, rate_hz, duration_s, position, |_| 0.0)
}

/// As [`sampled`], the nose also pitched along a climb and the body rolled by `roll_rad(t)`.
fn sampled_banked(
    plane: &LocalTangentPlane,
    rate_hz: f64,
    duration_s: f64,
    position: impl Fn(f64) -> DVec3,
    roll_rad: impl Fn(f64) -> f64,
) -> Vec<TrackSample> {
    let n = (duration_s * rate_hz).round().max(1.0) as usize;
    let h = 0.25 / rate_hz;
    (0..=n)
        .map(|i| {
            let t = i as f64 / rate_hz;
            let p = position(t);
            // Central difference inside the flight, one-sided at its ends (the path is held
            // outside [0, duration], which would halve the speed there).
            let (t0, t1) = ((t - h).max(0.0), (t + h).min(duration_s));
            let velocity = if t1 > t0 {
                (position(t1) - position(t0)) / (t1 - t0)
            } else {
                DVec3::ZERO
            };
            TrackSample {
                t_s: T0_S + t,
                time_boot_ms: (5_000.0 + t * 1000.0).round() as u32,
                position: plane.geodetic_from_enu_m(p),
                position_enu_m: p,
                velocity_enu_mps: velocity,
                attitude: Attitude {
                    time_boot_ms: (5_000.0 + t * 1000.0).round() as u32,
                    // Pitch up along a climb (about FRD y), then roll (about FRD x).
                    enu_from_frd: level_frd(velocity)
                        * DQuat::from_rotation_y(velocity.z.atan2(velocity.truncate().length()))
                        * DQuat::from_rotation_x(roll_rad(t)),
                    body_rates_radps: DVec3::ZERO,
                },
            }
        })
        .collect()
}

/// A straight flight from `a` to `b`.
pub(crate) fn line_samples(
    plane: &LocalTangentPlane,
    a: DVec3,
    b: DVec3,
    speed_mps: f64,
    rate_hz: f64,
) -> Vec<TrackSample> {
    let duration_s = (b - a).length() / speed_mps;
    let velocity = (b - a) / duration_s;
    sampled(plane, rate_hz, duration_s, |t| {
        a + velocity * t.clamp(0.0, duration_s)
    })
}

/// Half extents (ENU) of a model flying level along `velocity`.
fn half_extents(scene: &Scene, geometry_index: usize, velocity_enu_mps: DVec3) -> (DVec3, DVec3) {
    let placement = crate::scene::Placement {
        position_enu_m: DVec3::ZERO,
        enu_from_local: level_frd(velocity_enu_mps),
    };
    let b = placement.enu_aabb(&scene.geometries[geometry_index].local_aabb);
    (-b.min, b.max)
}

/// The flight set for `scene`: crossings, low passes along streets, near misses beside
/// towers, grazing passes through concave obstacles, fast movers, traffic, hovering, and over
/// terrain: terrain following and flight into a ridge. Families the scene has nothing for
/// (no terrain, no concave obstacle) are left out. The same scene gives the same flights, in
/// the same order.
pub fn flight_set(scene: &Scene) -> Vec<Flight> {
    let setting = Setting::of(scene);
    let mut flights = Vec::new();
    families::crossings(&setting, &mut flights);
    if !setting.has_terrain {
        families::street_passes(&setting, &mut flights);
    }
    families::tower_passes(&setting, &mut flights);
    families::concave_grazes(&setting, &mut flights);
    families::fast_movers(&setting, &mut flights);
    let course = families::EncounterCourse::of(&setting);
    families::traffic(&setting, &course, &mut flights);
    families::manoeuvres(&setting, &mut flights);
    families::vehicle_head_on(&course, &mut flights);
    if setting.has_terrain {
        families::terrain(&setting, &mut flights);
    }
    flights
}

/// What every family reads of the scene, found once.
struct Setting<'a> {
    scene: &'a Scene,
    plane: LocalTangentPlane,
    /// The scene origin clamped into the scene's bounds, ENU metres.
    centre: DVec3,
    has_terrain: bool,
    /// Half the span crossed by the crossings, metres (50 to 600).
    half: f64,
    /// The vehicle's model (system id 1).
    vehicle: usize,
    /// 30 m above everything static, ENU metres.
    clear_z: f64,
    /// Static obstacles other than terrain, nearest the centre first.
    order: Vec<usize>,
}

impl<'a> Setting<'a> {
    fn of(scene: &'a Scene) -> Self {
        let bounds = scene.bounds_enu_m();
        let centre = DVec3::new(0.0, 0.0, 0.0).clamp(bounds.min, bounds.max);
        Setting {
            scene,
            plane: LocalTangentPlane::new(scene.origin),
            centre,
            has_terrain: scene.obstacles.iter().any(|o| o.geometry.is_terrain()),
            half: 600.0_f64
                .min(0.5 * (bounds.max.x - bounds.min.x))
                .min(0.5 * (bounds.max.y - bounds.min.y))
                .max(50.0),
            vehicle: scene.vehicle_model(1),
            clear_z: bounds.max.z + 30.0,
            order: search::by_distance(scene, centre),
        }
    }

    /// The terrain's height at (x, y), ENU metres (0 where there is none, or no terrain).
    fn ground(&self, x: f64, y: f64) -> f64 {
        if self.has_terrain {
            self.scene.ground_height_enu_m(x, y).unwrap_or(0.0)
        } else {
            0.0
        }
    }

    /// The point `agl` metres above the ground at (x, y).
    fn at(&self, x: f64, y: f64, agl: f64) -> DVec3 {
        DVec3::new(x, y, self.ground(x, y) + agl)
    }

    /// The tallest obstacle's height above the ground under its centre, metres (0 without
    /// obstacles).
    fn tallest_m(&self) -> f64 {
        self.scene
            .obstacles
            .iter()
            .filter(|o| !o.geometry.is_terrain())
            .map(|o| {
                let c = o.aabb_enu_m.centre();
                o.aabb_enu_m.max.z - self.ground(c.x, c.y)
            })
            .fold(0.0, f64::max)
    }

    /// The vehicle's largest half extent across its path (sideways or up) flying east, metres.
    fn vehicle_half_side_m(&self) -> f64 {
        let (lo, hi) = half_extents(self.scene, self.vehicle, DVec3::X);
        lo.max(hi).y.max(lo.max(hi).z)
    }
}

//! Who is who across ticks, and where: stable identities of vehicles and moving obstacles, and
//! body poses (the colliders placed for a query are in `placed`).
//!
//! Identities outlive a tick (rapier's generational handles): a moving obstacle is named by
//! where it comes from (a scene track, a MAVLink (sysid, compid), an ICAO address) and by a
//! generation that changes when its track restarts (reboot, expiry and return). A per-tick
//! position in a `Vec` is never an identity. Imports no I/O, no tokio, no mavlink.

use std::sync::Arc;

use glam::{DQuat, DVec3};

use crate::scene::geometry::Geometry;
use crate::scene::Kind;
use crate::world::TrackSample;

/// Where a moving body comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum BodySource {
    /// A moving obstacle declared in the scene (index into `Scene::dynamic`), or a bench track.
    Scripted(u32),
    /// A vehicle: its MAVLink (sysid, compid), or a fleet number in the bench (as
    /// [`VehicleKey`] numbers it).
    Vehicle {
        /// MAVLink system id (or fleet number).
        vehicle: u16,
        /// MAVLink component id.
        component_id: u8,
    },
    /// ADS-B traffic by ICAO address.
    Traffic(u32),
}

/// A moving body's identity: its source and the generation of its track. A key whose track
/// restarted (a reboot, an expiry and return) is a different key, so state kept for the old
/// one is detectably stale, never silently another body's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BodyKey {
    /// Where it comes from.
    pub source: BodySource,
    /// The track's generation (0 for tracks that never restart).
    pub generation: u32,
}

/// The vehicle a tick is for: the MAVLink (sysid, compid) it is keyed by in the world store, and
/// its track's generation. Collision state is kept per (vehicle, component) and reset when the
/// generation changes (a reboot, or the track expired and came back).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VehicleKey {
    /// The vehicle's number: its MAVLink system id in a session, a fleet index in the bench.
    pub vehicle: u16,
    /// MAVLink component id (1 when not from MAVLink).
    pub component_id: u8,
    /// The track's generation.
    pub generation: u32,
}

impl VehicleKey {
    /// This vehicle as a moving body of other vehicles' ticks.
    pub const fn source(&self) -> BodySource {
        BodySource::Vehicle {
            vehicle: self.vehicle,
            component_id: self.component_id,
        }
    }

    /// This vehicle's key as a moving body.
    pub const fn as_body(&self) -> BodyKey {
        BodyKey {
            source: self.source(),
            generation: self.generation,
        }
    }

    /// Vehicle `vehicle`, component 1, generation 0.
    ///
    /// ```
    /// use savsim_core::collision::bodies::VehicleKey;
    /// let k = VehicleKey::new(7);
    /// assert_eq!((k.vehicle, k.component_id, k.generation), (7, 1, 0));
    /// ```
    pub const fn new(vehicle: u16) -> Self {
        Self {
            vehicle,
            component_id: 1,
            generation: 0,
        }
    }
}

/// An obstacle: static (index into `Scene::obstacles`) or moving (by its key).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ObstacleRef {
    /// A static obstacle.
    Static(u32),
    /// A moving body.
    Dynamic(BodyKey),
}

/// A rigid pose in the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyPose {
    /// Reference point, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Rotation from body FRD to ENU.
    pub enu_from_body: DQuat,
}

impl BodyPose {
    /// The pose of a track sample.
    pub fn of(sample: &TrackSample) -> Self {
        Self {
            position_enu_m: sample.position_enu_m,
            enu_from_body: sample.attitude.enu_from_frd,
        }
    }
}

/// Pose and velocity (ENU m/s; zero outside the track's time span) on a scripted track at `t`
/// seconds after the flight's start: linear between waypoints, held at the ends, nose along
/// the direction of travel. `w` is not empty (a scene's
/// and a manifest's tracks are checked for that when read).
pub fn waypoint_pose(w: &[crate::scene::Waypoint], t: f64) -> (BodyPose, DVec3) {
    let i = w.partition_point(|p| p.t_s <= t);
    let (a, b) = match i {
        0 => (&w[0], w.get(1).unwrap_or(&w[0])),
        i if i >= w.len() => (&w[w.len().saturating_sub(2)], &w[w.len() - 1]),
        i => (&w[i - 1], &w[i]),
    };
    let (pa, pb) = (DVec3::from(a.position_enu_m), DVec3::from(b.position_enu_m));
    let span = b.t_s - a.t_s;
    let velocity = if span > 0.0 {
        (pb - pa) / span
    } else {
        DVec3::ZERO
    };
    let u = if span > 0.0 {
        ((t - a.t_s) / span).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let moving = t > w[0].t_s && t < w[w.len() - 1].t_s;
    // FRD body: forward along the track, down towards -z (ENU).
    let heading = velocity.y.atan2(velocity.x);
    let enu_from_body =
        DQuat::from_rotation_z(heading) * DQuat::from_rotation_x(std::f64::consts::PI);
    (
        BodyPose {
            position_enu_m: pa.lerp(pb, u),
            enu_from_body,
        },
        if moving { velocity } else { DVec3::ZERO },
    )
}

/// A moving obstacle at this tick (another vehicle, ADS-B traffic, a scripted track).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicBody {
    /// Its identity across ticks.
    pub key: BodyKey,
    /// Id for events (`vehicle:2`, `icao:4840D6`, or the scene's id); shared, so that filling
    /// a tick's moving obstacles does not allocate.
    pub id: Arc<str>,
    /// Kind (threat class).
    pub kind: Kind,
    /// Threat T.
    pub threat: f64,
    /// Its model, an index into `Scene::geometries`.
    pub geometry_index: usize,
    /// Pose at the previous tick of the vehicle being checked.
    pub previous: BodyPose,
    /// Pose now.
    pub current: BodyPose,
    /// Speed, m/s.
    pub speed_mps: f64,
}

impl DynamicBody {
    /// Scripted track number `index` (a scene's, or an encounter's intruder) over the interval
    /// from `t_before_s` to `t_now_s`, seconds on the track's own clock.
    pub fn on_track(
        index: u32,
        id: Arc<str>,
        kind: Kind,
        threat: f64,
        geometry_index: usize,
        track: &[crate::scene::Waypoint],
        (t_before_s, t_now_s): (f64, f64),
    ) -> DynamicBody {
        let (previous, _) = waypoint_pose(track, t_before_s);
        let (current, velocity) = waypoint_pose(track, t_now_s);
        DynamicBody {
            key: BodyKey {
                source: BodySource::Scripted(index),
                generation: 0,
            },
            id,
            kind,
            threat,
            geometry_index,
            previous,
            current,
            speed_mps: velocity.length(),
        }
    }
}
/// The radius of the sphere about its origin that holds `geometry`, metres.
pub fn radius_m(geometry: &Geometry) -> f64 {
    f64::from(
        geometry
            .local_aabb
            .mins
            .abs()
            .max(geometry.local_aabb.maxs.abs())
            .length(),
    )
}

//! savsim's own threats, for the COLLISION feed: the closest point of approach of another
//! aircraft to the vehicle, both moving straight on at their present velocities.
//!
//! Pure; no I/O.

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{
    MavCollisionAction, MavCollisionSrc, MavCollisionThreatLevel, MavMessage, COLLISION_DATA,
};

use crate::feed::FeedConfig;

/// A predicted closest approach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Threat {
    /// Seconds from now to the closest approach (0 if it is now).
    pub time_to_cpa_s: f64,
    /// Horizontal distance then, metres.
    pub horizontal_m: f64,
    /// Vertical distance then, metres.
    pub vertical_m: f64,
    /// Within half the configured distances: high; otherwise low.
    pub high: bool,
}

/// The closest approach of `other` (position, velocity; ENU m, m/s) to `own`, if it comes
/// within the configured horizontal and vertical distances within the horizon.
///
/// ```
/// use glam::DVec3;
/// use savsim::feed::{threats::threat, FeedConfig};
/// // Head on at 10 m/s each, 200 m apart, 5 m above: closest in 10 s, 0 m across.
/// let t = threat(DVec3::ZERO, DVec3::X * 10.0, DVec3::new(200.0, 0.0, 5.0),
///                DVec3::X * -10.0, &FeedConfig::default()).unwrap();
/// assert!((t.time_to_cpa_s - 10.0).abs() < 1e-9 && t.horizontal_m < 1e-9);
/// assert!((t.vertical_m - 5.0).abs() < 1e-9 && t.high);
/// // Moving apart: no threat.
/// assert!(threat(DVec3::ZERO, DVec3::X * -10.0, DVec3::new(200.0, 0.0, 5.0),
///                DVec3::X * 10.0, &FeedConfig::default()).is_none());
/// ```
pub fn threat(
    own_enu_m: DVec3,
    own_velocity_enu_mps: DVec3,
    other_enu_m: DVec3,
    other_velocity_enu_mps: DVec3,
    cfg: &FeedConfig,
) -> Option<Threat> {
    let r = other_enu_m - own_enu_m;
    let v = other_velocity_enu_mps - own_velocity_enu_mps;
    let speed2 = v.length_squared();
    let t = if speed2 > 1e-12 {
        (-r.dot(v) / speed2).clamp(0.0, cfg.collision_horizon_s)
    } else {
        0.0
    };
    let at = r + v * t;
    let horizontal_m = at.truncate().length();
    let vertical_m = at.z.abs();
    let within = |h: f64, z: f64| horizontal_m <= h && vertical_m <= z;
    if !(t < cfg.collision_horizon_s
        && within(cfg.collision_horizontal_m, cfg.collision_vertical_m))
    {
        return None;
    }
    Some(Threat {
        time_to_cpa_s: t,
        horizontal_m,
        vertical_m,
        high: within(
            cfg.collision_horizontal_m * 0.5,
            cfg.collision_vertical_m * 0.5,
        ),
    })
}

/// The COLLISION message for aircraft `id` (its ICAO address).
pub fn collision(id: u32, t: &Threat) -> MavMessage {
    MavMessage::COLLISION(COLLISION_DATA {
        src: MavCollisionSrc::MAV_COLLISION_SRC_ADSB,
        id,
        action: MavCollisionAction::MAV_COLLISION_ACTION_REPORT,
        threat_level: if t.high {
            MavCollisionThreatLevel::MAV_COLLISION_THREAT_LEVEL_HIGH
        } else {
            MavCollisionThreatLevel::MAV_COLLISION_THREAT_LEVEL_LOW
        },
        time_to_minimum_delta: t.time_to_cpa_s as f32,
        altitude_minimum_delta: t.vertical_m as f32,
        horizontal_minimum_delta: t.horizontal_m as f32,
    })
}

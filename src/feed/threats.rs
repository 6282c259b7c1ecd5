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
    /// Comes within half the configured distances in the horizon: high; otherwise low.
    pub high: bool,
}

/// The closest approach of `other` (position, velocity; ENU m, m/s, in the vehicle's local
/// axes) to `own`, if at some moment within the horizon the two are within the configured
/// horizontal and vertical distances (already within them now counts, wherever the closest
/// approach is); the threat is high if they come within half of each.
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
/// // 100 m away, closing at 1 m/s: the closest approach is 100 s off, but it is inside
/// // (150 m) now; the closest within the 30 s horizon is at its end, and it is within half
/// // the distance (75 m) from 25 s: high.
/// let slow = threat(DVec3::ZERO, DVec3::ZERO, DVec3::new(100.0, 0.0, 0.0),
///                   DVec3::X * -1.0, &FeedConfig::default()).unwrap();
/// assert!((slow.time_to_cpa_s - 30.0).abs() < 1e-9 && slow.high);
/// // 140 m away, closing at 1 m/s: inside, never within 75 m in the horizon: low.
/// let far = threat(DVec3::ZERO, DVec3::ZERO, DVec3::new(140.0, 0.0, 0.0),
///                  DVec3::X * -1.0, &FeedConfig::default()).unwrap();
/// assert!(!far.high);
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
    let horizon_s = cfg.collision_horizon_s;
    let (h_m, z_m) = (cfg.collision_horizontal_m, cfg.collision_vertical_m);
    inside_within(r, v, h_m, z_m, horizon_s)?;
    let speed2 = v.length_squared();
    let t = if speed2 > 1e-12 {
        (-r.dot(v) / speed2).clamp(0.0, horizon_s)
    } else {
        0.0
    };
    let at = r + v * t;
    Some(Threat {
        time_to_cpa_s: t,
        horizontal_m: at.truncate().length(),
        vertical_m: at.z.abs(),
        high: inside_within(r, v, h_m * 0.5, z_m * 0.5, horizon_s).is_some(),
    })
}

/// The times in `[0, horizon_s]` when `r + v t` is within `h_m` horizontally and `z_m`
/// vertically, as an interval, if there are any.
fn inside_within(r: DVec3, v: DVec3, h_m: f64, z_m: f64, horizon_s: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0f64, horizon_s);
    // Vertical: |r.z + v.z t| <= z_m.
    if v.z.abs() < 1e-12 {
        if r.z.abs() > z_m {
            return None;
        }
    } else {
        let (a, b) = ((-z_m - r.z) / v.z, (z_m - r.z) / v.z);
        lo = lo.max(a.min(b));
        hi = hi.min(a.max(b));
    }
    // Horizontal: |r_h + v_h t|^2 <= h_m^2, a quadratic in t.
    let (rh, vh) = (r.truncate(), v.truncate());
    let (a, b, c) = (
        vh.length_squared(),
        2.0 * rh.dot(vh),
        rh.length_squared() - h_m * h_m,
    );
    if a < 1e-12 {
        if c > 0.0 {
            return None;
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        lo = lo.max((-b - root) / (2.0 * a));
        hi = hi.min((-b + root) / (2.0 * a));
    }
    (lo <= hi).then_some((lo, hi))
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

//! Events: what the collision core reports, one JSON object per line (`--events PATH`).
//! Documented field by field in docs/events.md.

use serde::Serialize;

use crate::collision::ColliderKind;

/// Something that happened to a vehicle at one tick.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Event {
    /// Receive/tlog clock of the tick, seconds (UNIX time for tlogs and live).
    pub t: f64,
    /// The vehicle's own clock at the tick, ms since boot.
    pub time_boot_ms: u32,
    /// The vehicle's MAVLink system id (in `savsim bench`, the fleet's vehicle number).
    pub vehicle: u16,
    /// The vehicle's MAVLink component id (1 in `savsim bench`).
    pub compid: u8,
    /// What happened.
    #[serde(flatten)]
    pub kind: EventKind,
}

/// The kinds of event, tagged by `kind` in JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EventKind {
    /// The vehicle touched an obstacle (the start of a contact).
    Collision {
        /// Obstacle id.
        obstacle: String,
        /// Obstacle kind.
        obstacle_kind: &'static str,
        /// Contact point, scene ENU metres.
        point_enu_m: [f64; 3],
        /// Contact normal (out of the obstacle), ENU.
        normal_enu: [f64; 3],
        /// When contact began, seconds on the same clock as `t`.
        time_of_impact: f64,
        /// True when found by sweeping between samples, false by a check at one sample.
        swept: bool,
    },
    /// An obstacle's collider changed.
    ColliderSwap {
        /// Obstacle id.
        obstacle: String,
        /// Collider before.
        from: ColliderKind,
        /// Collider after.
        to: ColliderKind,
        /// Threat coefficient at the change (0 when no ray saw it).
        beta: f64,
        /// Distance from the vehicle to the obstacle's box, metres.
        distance_m: f64,
        /// Why: `node` (paper: the vehicle's node gave it a box), `left` (paper: it left the
        /// node), `threat` (a ray saw beta above the threshold), `far` (beyond the far distance).
        reason: &'static str,
    },
    /// The vehicle came within the near-miss distance of an obstacle without touching it.
    NearMiss {
        /// Obstacle id.
        obstacle: String,
        /// Closest distance reached, metres.
        closest_m: f64,
        /// When it was closest, seconds.
        closest_t: f64,
    },
    /// The vehicle lost well clear of a moving body (the well-clear volume, `--well-clear`,
    /// violated between their reference points).
    WellClearLost {
        /// The moving body's id.
        track: String,
        /// When it was lost, seconds on the same clock as `t` (within the tick's interval).
        lost_t: f64,
        /// Horizontal separation then, metres.
        horizontal_m: f64,
        /// Vertical separation then (absolute), metres.
        vertical_m: f64,
    },
    /// The vehicle regained well clear of a moving body.
    WellClearRegained {
        /// The moving body's id.
        track: String,
        /// When it was regained, seconds on the same clock as `t`.
        regained_t: f64,
        /// How long well clear was lost, seconds.
        duration_s: f64,
    },
    /// The vehicle came nearer a moving body than the separation minimum (`--separation-m`,
    /// 3D between their reference points).
    SeparationLost {
        /// The moving body's id.
        track: String,
        /// When it was lost, seconds on the same clock as `t` (within the tick's interval).
        lost_t: f64,
        /// The separation minimum, metres.
        minimum_m: f64,
    },
    /// The vehicle was again at least the separation minimum from a moving body.
    SeparationRegained {
        /// The moving body's id.
        track: String,
        /// When it was regained, seconds on the same clock as `t`.
        regained_t: f64,
        /// How long separation was lost, seconds.
        duration_s: f64,
    },
    /// The vehicle was seen farther from its slot than the tolerance (`--slots`).
    LeftSlot {
        /// When, seconds on the same clock as `t` (the sample's).
        left_t: f64,
        /// How far from its slot, metres.
        deviation_m: f64,
        /// Where its slot was, scene ENU metres.
        slot_enu_m: [f64; 3],
    },
    /// The vehicle was seen within the tolerance of its slot again.
    BackInSlot {
        /// When, seconds on the same clock as `t`.
        back_t: f64,
        /// How long it was out, seconds.
        duration_s: f64,
        /// The farthest it was seen from its slot, metres.
        max_deviation_m: f64,
    },
    /// Telemetry stopped for longer than the gap limit: no sweep across the gap.
    TelemetryGap {
        /// Length of the gap, seconds.
        gap_s: f64,
        /// Distance the vehicle moved across it, metres.
        moved_m: f64,
    },
}

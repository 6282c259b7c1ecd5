//! What the world store is fed: a sender's identity and the decoded reports of the messages
//! savsim uses, in SI units. `ingest::decode` makes them from MAVLink frames (the only place
//! MAVLink units appear); the world store takes them and knows nothing of frames or sockets.

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavType};

use crate::geo::Geodetic;

/// A sender's (system id, component id): how savsim keys vehicles, never by endpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SenderId {
    /// MAVLink system id.
    pub system_id: u8,
    /// MAVLink component id.
    pub component_id: u8,
}

impl std::fmt::Display for SenderId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.system_id, self.component_id)
    }
}

/// A vehicle's position fix (GLOBAL_POSITION_INT) in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionReport {
    /// Vehicle clock, milliseconds since boot (wraps at 2^32).
    pub time_boot_ms: u32,
    /// WGS84 position; `alt_m` is metres above mean sea level.
    pub position: Geodetic,
    /// Height above home, metres.
    pub relative_alt_m: f64,
    /// Ground velocity in the vehicle's local North-East-Down frame, m/s.
    pub velocity_ned_mps: DVec3,
    /// Heading, degrees clockwise from north; `None` when the vehicle says unknown (65535).
    pub heading_deg: Option<f64>,
}

/// A vehicle's attitude (ATTITUDE) in SI units: body FRD relative to local NED.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeReport {
    /// Vehicle clock, milliseconds since boot (wraps at 2^32).
    pub time_boot_ms: u32,
    /// Roll, radians.
    pub roll_rad: f64,
    /// Pitch, radians.
    pub pitch_rad: f64,
    /// Yaw, radians clockwise from north.
    pub yaw_rad: f64,
    /// Body rates (roll, pitch, yaw), rad/s.
    pub body_rates_radps: DVec3,
}

/// Who a HEARTBEAT says its sender is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeartbeatReport {
    /// MAV_TYPE, or `None` if the value is not in the dialect.
    pub vehicle_type: Option<MavType>,
    /// MAV_AUTOPILOT, or `None` if the value is not in the dialect.
    pub autopilot: Option<MavAutopilot>,
}

impl HeartbeatReport {
    /// True for a vehicle's autopilot: a real MAV_AUTOPILOT (not INVALID) and a vehicle
    /// MAV_TYPE (not a GCS, companion computer, gimbal, camera, ADS-B receiver, ...). Only
    /// these are asked for streams, and only their sequence numbers count as the link's.
    ///
    /// ```
    /// use mavlink::dialects::ardupilotmega::{MavAutopilot, MavType};
    /// use savsim::world::report::HeartbeatReport;
    /// let copter = HeartbeatReport {
    ///     vehicle_type: Some(MavType::MAV_TYPE_QUADROTOR),
    ///     autopilot: Some(MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA),
    /// };
    /// let companion = HeartbeatReport {
    ///     vehicle_type: Some(MavType::MAV_TYPE_ONBOARD_CONTROLLER),
    ///     autopilot: Some(MavAutopilot::MAV_AUTOPILOT_INVALID),
    /// };
    /// assert!(copter.is_autopilot() && !companion.is_autopilot());
    /// ```
    pub fn is_autopilot(&self) -> bool {
        use MavType::*;
        let vehicle = matches!(
            self.vehicle_type,
            Some(
                MAV_TYPE_FIXED_WING
                    | MAV_TYPE_QUADROTOR
                    | MAV_TYPE_COAXIAL
                    | MAV_TYPE_HELICOPTER
                    | MAV_TYPE_AIRSHIP
                    | MAV_TYPE_FREE_BALLOON
                    | MAV_TYPE_ROCKET
                    | MAV_TYPE_GROUND_ROVER
                    | MAV_TYPE_SURFACE_BOAT
                    | MAV_TYPE_SUBMARINE
                    | MAV_TYPE_HEXAROTOR
                    | MAV_TYPE_OCTOROTOR
                    | MAV_TYPE_TRICOPTER
                    | MAV_TYPE_FLAPPING_WING
                    | MAV_TYPE_KITE
                    | MAV_TYPE_VTOL_TAILSITTER_DUOROTOR
                    | MAV_TYPE_VTOL_TAILSITTER_QUADROTOR
                    | MAV_TYPE_VTOL_TILTROTOR
                    | MAV_TYPE_VTOL_FIXEDROTOR
                    | MAV_TYPE_VTOL_TAILSITTER
                    | MAV_TYPE_VTOL_TILTWING
                    | MAV_TYPE_VTOL_RESERVED5
                    | MAV_TYPE_PARAFOIL
                    | MAV_TYPE_DODECAROTOR
                    | MAV_TYPE_DECAROTOR
                    | MAV_TYPE_GENERIC_MULTIROTOR
                    | MAV_TYPE_SPACECRAFT_ORBITER
                    | MAV_TYPE_GROUND_QUADRUPED
                    | MAV_TYPE_VTOL_GYRODYNE
            )
        );
        vehicle
            && self
                .autopilot
                .is_some_and(|a| a != MavAutopilot::MAV_AUTOPILOT_INVALID)
    }
}

/// An ADS-B traffic report (ADSB_VEHICLE) in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdsbReport {
    /// ICAO 24-bit address.
    pub icao_address: u32,
    /// WGS84 position; `alt_m` as reported (ADS-B altitude, metres).
    pub position: Geodetic,
    /// Course over ground, degrees clockwise from north.
    pub heading_deg: f64,
    /// Horizontal speed, m/s.
    pub horizontal_speed_mps: f64,
    /// Vertical speed, m/s, positive up.
    pub vertical_speed_mps: f64,
    /// ADSB_EMITTER_TYPE as its raw number (0 = no info).
    pub emitter_type: u8,
    /// Callsign, ASCII, NUL padded.
    pub callsign: [u8; 9],
}

/// A decoded message that savsim uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Report {
    /// GLOBAL_POSITION_INT.
    Position(PositionReport),
    /// ATTITUDE.
    Attitude(AttitudeReport),
    /// HEARTBEAT.
    Heartbeat(HeartbeatReport),
    /// ADSB_VEHICLE.
    Adsb(AdsbReport),
}

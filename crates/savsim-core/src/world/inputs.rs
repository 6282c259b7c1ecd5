//! What the world store is fed: a sender's identity and the decoded reports of the messages
//! savsim uses, in SI units. savsim's `codec::decode` makes them from MAVLink frames; the world
//! store takes them and knows nothing of frames or sockets.

use glam::DVec3;

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

/// Who a HEARTBEAT says its sender is: its MAV_TYPE and MAV_AUTOPILOT as the numbers sent
/// (a value newer than any dialect is kept as it came).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeartbeatReport {
    /// MAV_TYPE.
    pub mav_type: u8,
    /// MAV_AUTOPILOT.
    pub autopilot: u8,
}

impl HeartbeatReport {
    /// MAV_AUTOPILOT_INVALID: the sender is not a flight controller.
    pub const AUTOPILOT_INVALID: u8 = 8;
    /// MAV_AUTOPILOT_ARDUPILOTMEGA.
    pub const AUTOPILOT_ARDUPILOT: u8 = 3;
    /// MAV_AUTOPILOT_PX4.
    pub const AUTOPILOT_PX4: u8 = 12;

    /// The MAV_TYPEs that are not vehicles (minimal.xml): generic, antenna tracker, GCS,
    /// onboard controller, gimbal, ADS-B, camera, charging station, FLARM, servo, ODID,
    /// battery, parachute, log, OSD, IMU, GPS, winch, illuminator, gripper, radio.
    pub const PERIPHERAL_TYPES: [u8; 21] = [
        0, 5, 6, 18, 26, 27, 30, 31, 32, 33, 34, 36, 37, 38, 39, 40, 41, 42, 44, 48, 49,
    ];

    /// True for a vehicle's autopilot: a real MAV_AUTOPILOT (not INVALID) and a MAV_TYPE that
    /// is not a peripheral ([`Self::PERIPHERAL_TYPES`]). A MAV_TYPE newer than the list is a
    /// vehicle. Only these are asked for streams, and only their sequence numbers count as the
    /// link's.
    ///
    /// ```
    /// use savsim_core::world::inputs::HeartbeatReport;
    /// let copter = HeartbeatReport { mav_type: 2, autopilot: 3 }; // quadrotor, ArduPilot
    /// let companion = HeartbeatReport { mav_type: 18, autopilot: 8 }; // onboard, invalid
    /// let gcs = HeartbeatReport { mav_type: 6, autopilot: 0 };
    /// let newer = HeartbeatReport { mav_type: 77, autopilot: 12 }; // a type not yet listed
    /// assert!(copter.is_autopilot() && newer.is_autopilot());
    /// assert!(!companion.is_autopilot() && !gcs.is_autopilot());
    /// ```
    pub fn is_autopilot(&self) -> bool {
        self.autopilot != Self::AUTOPILOT_INVALID
            && !Self::PERIPHERAL_TYPES.contains(&self.mav_type)
    }
}

/// An ADS-B traffic report (ADSB_VEHICLE) in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdsbReport {
    /// ICAO 24-bit address.
    pub icao_address: u32,
    /// WGS84 position; `alt_m` as reported, metres above mean sea level (geometric, or
    /// barometric with QNH: see `pressure_altitude`).
    pub position: Geodetic,
    /// Course over ground, degrees clockwise from north.
    pub heading_deg: f64,
    /// Horizontal speed, m/s.
    pub horizontal_speed_mps: f64,
    /// Vertical speed, m/s, positive up.
    pub vertical_speed_mps: f64,
    /// True when the altitude is barometric (QNH), false when geometric (GNSS).
    pub pressure_altitude: bool,
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

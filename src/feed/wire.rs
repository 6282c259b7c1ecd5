//! The feed's messages: the only place its MAVLink units appear (centimetres, degE7, mm,
//! centidegrees). SI values in, `MavMessage`s out, as ArduPilot's AP_Proximity_MAV,
//! AP_RangeFinder_MAVLink and AP_ADSB_MAVLink, and PX4's CollisionPrevention read them.
//!
//! Pure; no I/O.

use mavlink::dialects::ardupilotmega::{
    AdsbAltitudeType, AdsbEmitterType, AdsbFlags, MavAutopilot, MavDistanceSensor, MavFrame,
    MavMessage, MavModeFlag, MavSensorOrientation, MavState, MavType, ADSB_VEHICLE_DATA,
    DISTANCE_SENSOR_DATA, HEARTBEAT_DATA, OBSTACLE_DISTANCE_DATA,
};
use num_traits::FromPrimitive;

use crate::feed::sectors::{BIN0_DEG, BINS, BIN_DEG};
use crate::geo::Geodetic;
use crate::scene::Kind;

/// A range sensor's limits, metres, as the wire carries them (whole centimetres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Nearest distance the sensor reports.
    pub min_m: f64,
    /// Farthest distance it reports; "nothing seen" is sent as one centimetre beyond.
    pub max_m: f64,
}

impl Range {
    fn min_cm(&self) -> u16 {
        cm(self.min_m)
    }

    fn max_cm(&self) -> u16 {
        // One below the largest u16: max + 1 must stay apart from UINT16_MAX ("unknown").
        cm(self.max_m).min(u16::MAX - 2)
    }

    /// A reading in centimetres: the distance (below the minimum: the minimum, the nearest a
    /// sensor can say), or max + 1 when nothing was seen within range.
    ///
    /// ```
    /// use savsim::feed::wire::Range;
    /// let r = Range { min_m: 0.2, max_m: 40.0 };
    /// assert_eq!(r.reading_cm(Some(12.344)), 1234);
    /// assert_eq!(r.reading_cm(Some(0.05)), 20);
    /// assert_eq!(r.reading_cm(Some(40.2)), 4001);
    /// assert_eq!(r.reading_cm(None), 4001);
    /// ```
    pub fn reading_cm(&self, distance_m: Option<f64>) -> u16 {
        match distance_m {
            Some(d) if d <= self.max_m => cm(d).clamp(self.min_cm(), self.max_cm()),
            _ => self.max_cm() + 1,
        }
    }
}

/// Metres to whole centimetres, rounded, saturating.
fn cm(m: f64) -> u16 {
    (m * 100.0).round().clamp(0.0, f64::from(u16::MAX)) as u16
}

/// One DISTANCE_SENSOR reading: `orientation` is MAV_SENSOR_ORIENTATION (0..7 the 45-degree
/// sectors clockwise from the nose, 24 up, 25 down).
pub fn distance_sensor(
    time_boot_ms: u32,
    range: Range,
    distance_m: Option<f64>,
    orientation: u8,
    sensor_type: u8,
    id: u8,
) -> MavMessage {
    MavMessage::DISTANCE_SENSOR(DISTANCE_SENSOR_DATA {
        time_boot_ms,
        min_distance: range.min_cm(),
        max_distance: range.max_cm(),
        current_distance: range.reading_cm(distance_m),
        mavtype: MavDistanceSensor::from_u8(sensor_type).unwrap_or_default(),
        id,
        orientation: MavSensorOrientation::from_u8(orientation).unwrap_or_default(),
        // 255: covariance unknown.
        covariance: u8::MAX,
        ..Default::default()
    })
}

/// OBSTACLE_DISTANCE: 72 bins of 5 degrees clockwise, in `MAV_FRAME_BODY_FRD`, bin 0 centred
/// 20 degrees left of the nose (`angle_offset` -20: see `sectors::BIN0_DEG`); `None` is
/// "nothing seen" (max + 1).
pub fn obstacle_distance(
    time_boot_ms: u32,
    range: Range,
    bins_m: &[Option<f64>; BINS],
    sensor_type: u8,
) -> MavMessage {
    let distances = bins_m.map(|d| range.reading_cm(d));
    obstacle_distance_cm(time_boot_ms, range, distances, sensor_type)
}

/// OBSTACLE_DISTANCE from modelled devices' bins: a return in centimetres, clear as max + 1,
/// no data as UINT16_MAX ("unknown"); otherwise as [`obstacle_distance`].
pub fn obstacle_distance_cells(
    time_boot_ms: u32,
    range: Range,
    bins: &[savsim_core::sensors::range::BeamReading; BINS],
    sensor_type: u8,
) -> MavMessage {
    use savsim_core::sensors::range::BeamReading;
    let distances = bins.map(|cell| match cell {
        BeamReading::Range(d) => range.reading_cm(Some(d)),
        BeamReading::Clear => range.reading_cm(None),
        BeamReading::NoData => u16::MAX,
    });
    obstacle_distance_cm(time_boot_ms, range, distances, sensor_type)
}

/// OBSTACLE_DISTANCE of bins already in centimetres.
fn obstacle_distance_cm(
    time_boot_ms: u32,
    range: Range,
    distances: [u16; BINS],
    sensor_type: u8,
) -> MavMessage {
    MavMessage::OBSTACLE_DISTANCE(OBSTACLE_DISTANCE_DATA {
        time_usec: u64::from(time_boot_ms) * 1000,
        distances,
        sensor_type: MavDistanceSensor::from_u8(sensor_type).unwrap_or_default(),
        max_distance: range.max_cm(),
        min_distance: range.min_cm(),
        increment: BIN_DEG as u8,
        increment_f: BIN_DEG as f32,
        angle_offset: BIN0_DEG as f32,
        frame: MavFrame::MAV_FRAME_BODY_FRD,
    })
}

/// An aircraft for ADSB_VEHICLE.
#[derive(Debug, Clone, PartialEq)]
pub struct Aircraft<'a> {
    /// ICAO address (24 bits).
    pub icao_address: u32,
    /// Callsign (up to 8 characters are sent).
    pub callsign: &'a str,
    /// Where, WGS84; the height is taken as above mean sea level, as MAVLink's positions are.
    pub position: Geodetic,
    /// Velocity in the local North-East-Down frame at its position, m/s.
    pub velocity_ned_mps: glam::DVec3,
    /// What it is.
    pub kind: Kind,
}

/// An aircraft as a person reads it: its address and the callsign ADSB_VEHICLE carries (its
/// first 8 characters).
///
/// ```
/// use savsim::feed::wire::{label, Aircraft};
/// let a = Aircraft {
///     icao_address: 0xF00001,
///     callsign: "SAVSIM-INTRUDER",
///     position: savsim::geo::Geodetic::new(0.0, 0.0, 0.0),
///     velocity_ned_mps: glam::DVec3::ZERO,
///     kind: savsim::scene::Kind::Dji,
/// };
/// assert_eq!(label(&a), "F00001 SAVSIM-I");
/// ```
pub fn label(a: &Aircraft<'_>) -> String {
    let callsign: Vec<u8> = a.callsign.bytes().take(8).collect();
    let callsign = String::from_utf8_lossy(&callsign);
    format!("{:06X} {}", a.icao_address & 0x00FF_FFFF, callsign.trim())
        .trim()
        .to_string()
}

/// ADSB_VEHICLE for `a`, reported `tslc_s` seconds after its last fix: every validity flag set
/// (as ArduPilot's own ADS-B simulator sends), marked simulated.
pub fn adsb_vehicle(a: &Aircraft<'_>, tslc_s: f64) -> MavMessage {
    let v = a.velocity_ned_mps;
    let horizontal = v.truncate().length();
    // Heading clockwise from north, [0, 360).
    let heading_deg = v.y.atan2(v.x).to_degrees().rem_euclid(360.0);
    let mut callsign = [0u8; 9];
    for (out, c) in callsign.iter_mut().zip(a.callsign.bytes().take(8)) {
        *out = c;
    }
    MavMessage::ADSB_VEHICLE(ADSB_VEHICLE_DATA {
        ICAO_address: a.icao_address & 0x00FF_FFFF,
        lat: (a.position.lat_deg * 1e7).round() as i32,
        lon: (a.position.lon_deg * 1e7).round() as i32,
        altitude_type: AdsbAltitudeType::ADSB_ALTITUDE_TYPE_GEOMETRIC,
        altitude: (a.position.alt_m * 1e3).round() as i32,
        heading: ((heading_deg * 100.0).round() as u32 % 36_000) as u16,
        hor_velocity: (horizontal * 100.0).round().clamp(0.0, 65_535.0) as u16,
        // Up positive.
        ver_velocity: (-v.z * 100.0).round().clamp(-32_768.0, 32_767.0) as i16,
        callsign: callsign.into(),
        emitter_type: emitter_type(a.kind),
        tslc: tslc_s.round().clamp(0.0, 255.0) as u8,
        flags: AdsbFlags::from_bits_truncate(0x1FF),
        squawk: 1200,
    })
}

/// The ADS-B emitter category of a kind of aircraft.
pub fn emitter_type(kind: Kind) -> AdsbEmitterType {
    match kind {
        Kind::A320 | Kind::B737 => AdsbEmitterType::ADSB_EMITTER_TYPE_LARGE,
        Kind::Dji => AdsbEmitterType::ADSB_EMITTER_TYPE_UAV,
        Kind::Airship | Kind::Balloon => AdsbEmitterType::ADSB_EMITTER_TYPE_LIGHTER_AIR,
        Kind::Building | Kind::Mountain | Kind::Tree => AdsbEmitterType::ADSB_EMITTER_TYPE_NO_INFO,
    }
}

/// The feed component's HEARTBEAT: an onboard sensor computer, no autopilot (so no GCS or
/// supervisor takes it for a vehicle).
pub fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

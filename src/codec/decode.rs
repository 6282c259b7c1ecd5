//! Decode: the only place where MAVLink units appear.
//!
//! Turns a valid [`RawFrame`] into a typed [`Report`] in SI units (degrees and metres for
//! positions, m/s, radians, seconds), or says why the values were rejected. Pure: no I/O, no
//! clocks, no allocation. Counting lives in [`crate::codec::stats`].

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavType, ADSB_VEHICLE_DATA, ATTITUDE_DATA, GLOBAL_POSITION_INT_DATA,
    HEARTBEAT_DATA,
};

pub use crate::world::inputs::{
    AdsbReport, AttitudeReport, HeartbeatReport, PositionReport, Report,
};
use mavlink::MessageData;

use crate::codec::frame::RawFrame;
use crate::geo::Geodetic;

/// MAVLink id of HEARTBEAT.
pub const ID_HEARTBEAT: u32 = HEARTBEAT_DATA::ID;
/// MAVLink id of ATTITUDE.
pub const ID_ATTITUDE: u32 = ATTITUDE_DATA::ID;
/// MAVLink id of GLOBAL_POSITION_INT.
pub const ID_GLOBAL_POSITION_INT: u32 = GLOBAL_POSITION_INT_DATA::ID;
/// MAVLink id of ADSB_VEHICLE.
pub const ID_ADSB_VEHICLE: u32 = ADSB_VEHICLE_DATA::ID;

/// Why a frame with a valid checksum still gave no report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rejection {
    /// lat = lon = 0: the autopilot's "no fix yet" sentinel.
    NoFix,
    /// Latitude outside [-90, 90] or longitude outside [-180, 180].
    LatLonOutOfRange,
    /// An attitude angle or rate that is NaN or infinite.
    NonFiniteAttitude,
    /// A field the dialect constrains (an enum) holds a value it does not define.
    InvalidField,
    /// An ADS-B report whose flags do not say its coordinates and altitude are valid.
    AdsbNoPosition,
}

impl Rejection {
    /// The stable snake_case name used in summaries.
    pub fn as_str(self) -> &'static str {
        match self {
            Rejection::NoFix => "no_fix",
            Rejection::LatLonOutOfRange => "lat_lon_out_of_range",
            Rejection::NonFiniteAttitude => "non_finite_attitude",
            Rejection::InvalidField => "invalid_field",
            Rejection::AdsbNoPosition => "adsb_no_position",
        }
    }
}

/// Decode a frame whose status is `Valid`. `Ok(None)` for messages savsim does not use.
///
/// ```
/// use savsim::codec::{decode::{decode, Report}, frame::{scan, Scan}};
/// let bytes = [0xfe, 9, 0, 1, 1, 0, 4, 0, 0, 0, 2, 3, 81, 3, 3, 0xe4, 0xe1];
/// let Scan::Frame(frame) = scan(&bytes) else { panic!() };
/// assert!(matches!(decode(&frame), Ok(Some(Report::Heartbeat(_)))));
/// ```
pub fn decode(frame: &RawFrame<'_>) -> Result<Option<Report>, Rejection> {
    let version = frame.version;
    let payload = frame.payload;
    match frame.message_id {
        ID_GLOBAL_POSITION_INT => {
            let m = GLOBAL_POSITION_INT_DATA::deser(version, payload)
                .map_err(|_| Rejection::InvalidField)?;
            position_from(&m).map(|p| Some(Report::Position(p)))
        }
        ID_ATTITUDE => {
            let m = ATTITUDE_DATA::deser(version, payload).map_err(|_| Rejection::InvalidField)?;
            attitude_from(&m).map(|a| Some(Report::Attitude(a)))
        }
        ID_HEARTBEAT => Ok(Some(Report::Heartbeat(heartbeat_from(payload)))),
        ID_ADSB_VEHICLE => {
            let m =
                ADSB_VEHICLE_DATA::deser(version, payload).map_err(|_| Rejection::InvalidField)?;
            adsb_from(&m).map(|a| Some(Report::Adsb(a)))
        }
        _ => Ok(None),
    }
}

fn geodetic_from_e7(lat_e7: i32, lon_e7: i32, alt_m: f64) -> Result<Geodetic, Rejection> {
    if lat_e7 == 0 && lon_e7 == 0 {
        return Err(Rejection::NoFix);
    }
    let position = Geodetic::new(f64::from(lat_e7) * 1e-7, f64::from(lon_e7) * 1e-7, alt_m);
    if !(-90.0..=90.0).contains(&position.lat_deg) || !(-180.0..=180.0).contains(&position.lon_deg)
    {
        return Err(Rejection::LatLonOutOfRange);
    }
    Ok(position)
}

fn position_from(m: &GLOBAL_POSITION_INT_DATA) -> Result<PositionReport, Rejection> {
    Ok(PositionReport {
        time_boot_ms: m.time_boot_ms,
        position: geodetic_from_e7(m.lat, m.lon, f64::from(m.alt) * 1e-3)?,
        relative_alt_m: f64::from(m.relative_alt) * 1e-3,
        velocity_ned_mps: DVec3::new(f64::from(m.vx), f64::from(m.vy), f64::from(m.vz)) * 0.01,
        heading_deg: (m.hdg != u16::MAX).then(|| f64::from(m.hdg) * 0.01),
    })
}

fn attitude_from(m: &ATTITUDE_DATA) -> Result<AttitudeReport, Rejection> {
    let values = [
        m.roll,
        m.pitch,
        m.yaw,
        m.rollspeed,
        m.pitchspeed,
        m.yawspeed,
    ];
    if values.iter().any(|v| !v.is_finite()) {
        return Err(Rejection::NonFiniteAttitude);
    }
    Ok(AttitudeReport {
        time_boot_ms: m.time_boot_ms,
        roll_rad: f64::from(m.roll),
        pitch_rad: f64::from(m.pitch),
        yaw_rad: f64::from(m.yaw),
        body_rates_radps: DVec3::new(
            f64::from(m.rollspeed),
            f64::from(m.pitchspeed),
            f64::from(m.yawspeed),
        ),
    })
}

/// A HEARTBEAT payload, decoded field by field so that a vehicle type newer than the dialect
/// still identifies a vehicle (the crate's `deser` rejects unknown enum values).
pub fn heartbeat_from(payload: &[u8]) -> HeartbeatReport {
    let byte = |i: usize| payload.get(i).copied().unwrap_or(0);
    HeartbeatReport {
        mav_type: byte(4),
        autopilot: byte(5),
    }
}

/// A HEARTBEAT's MAV_TYPE and MAV_AUTOPILOT by their dialect names (`MAV_TYPE_QUADROTOR`), or
/// as numbers where the dialect has none.
pub fn heartbeat_names(h: &HeartbeatReport) -> (String, String) {
    use num_traits::FromPrimitive;
    (
        MavType::from_u8(h.mav_type).map_or_else(|| h.mav_type.to_string(), |v| format!("{v:?}")),
        MavAutopilot::from_u8(h.autopilot)
            .map_or_else(|| h.autopilot.to_string(), |v| format!("{v:?}")),
    )
}

/// An ADS-B report, by its flags: no valid coordinates or altitude, no report (a receiver
/// relays Mode S replies with neither); heading and speed only when flagged valid (else the
/// aircraft is not extrapolated), the climb only with VERTICAL_VELOCITY_VALID. The altitude
/// type is kept: QNH barometric altitude is mean-sea-level altitude by its reference, with the
/// atmosphere's error in it, and is counted apart (`AdsbReport::pressure_altitude`).
fn adsb_from(m: &ADSB_VEHICLE_DATA) -> Result<AdsbReport, Rejection> {
    use mavlink::dialects::ardupilotmega::{AdsbAltitudeType, AdsbFlags};
    let flags = m.flags;
    if !flags.contains(AdsbFlags::ADSB_FLAGS_VALID_COORDS | AdsbFlags::ADSB_FLAGS_VALID_ALTITUDE) {
        return Err(Rejection::AdsbNoPosition);
    }
    let moving =
        flags.contains(AdsbFlags::ADSB_FLAGS_VALID_HEADING | AdsbFlags::ADSB_FLAGS_VALID_VELOCITY);
    let climbing = flags.contains(AdsbFlags::ADSB_FLAGS_VERTICAL_VELOCITY_VALID);
    Ok(AdsbReport {
        icao_address: m.ICAO_address,
        position: geodetic_from_e7(m.lat, m.lon, f64::from(m.altitude) * 1e-3)?,
        heading_deg: if moving {
            f64::from(m.heading) * 0.01
        } else {
            0.0
        },
        horizontal_speed_mps: if moving {
            f64::from(m.hor_velocity) * 0.01
        } else {
            0.0
        },
        vertical_speed_mps: if climbing {
            f64::from(m.ver_velocity) * 0.01
        } else {
            0.0
        },
        pressure_altitude: m.altitude_type == AdsbAltitudeType::ADSB_ALTITUDE_TYPE_PRESSURE_QNH,
        emitter_type: m.emitter_type as u8,
        callsign: m.callsign.into(),
    })
}

//! Autopilot logs to reports: a PX4 ULog or an ArduPilot DataFlash log read into the same
//! position, attitude and traffic reports a tlog's messages decode to, in time order, so that
//! a replay of either goes through the session exactly as a tlog does.
//!
//! Which topics or messages give the position and the attitude, and in which units, is decided
//! here (docs/replay-logs.md lists it); the readers ([`super::ulog`], [`super::dataflash`])
//! know only their file formats.

use glam::{DQuat, DVec3, EulerRot};

use crate::codec::decode::{AdsbReport, AttitudeReport, PositionReport, Report};
use crate::geo::{Geodetic, LocalTangentPlane};
use crate::logs::dataflash::{DataflashCounts, DataflashReader, Message};
use crate::logs::ulog::{Sample, UlogCounts, UlogError, UlogReader, MAGIC};
use crate::world::SenderId;

/// Which kind of log a file is, by its first bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LogKind {
    /// PX4 ULog.
    Ulog,
    /// ArduPilot DataFlash.
    Dataflash,
    /// Anything else: read as a tlog.
    Tlog,
}

impl LogKind {
    /// The kind of a file that starts with `head` (its first 16 bytes or fewer).
    ///
    /// ```
    /// use savsim::logs::flightlog::LogKind;
    /// assert_eq!(LogKind::of(b"ULog\x01\x12\x35\x01"), LogKind::Ulog);
    /// assert_eq!(LogKind::of(&[0xA3, 0x95, 0x80]), LogKind::Dataflash);
    /// assert_eq!(LogKind::of(&[0, 5, 0xFD]), LogKind::Tlog);
    /// ```
    pub fn of(head: &[u8]) -> Self {
        if head.starts_with(&MAGIC) {
            LogKind::Ulog
        } else if head.starts_with(&[0xA3, 0x95, 0x80]) {
            LogKind::Dataflash
        } else {
            LogKind::Tlog
        }
    }
}

/// One report at its time on the log's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timed {
    /// Microseconds on the log's clock (since the autopilot booted).
    pub t_us: u64,
    /// Who sent it: the vehicle, or the traffic's receiver.
    pub sender: SenderId,
    /// The report.
    pub report: Report,
}

/// What a log held and where its reports came from.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LogSummary {
    /// The topic or message the positions came from (`None`: the log has none).
    pub position_source: Option<&'static str>,
    /// The topic or message the attitudes came from.
    pub attitude_source: Option<&'static str>,
    /// Position samples taken.
    pub positions: u64,
    /// Position samples at lat = lon = 0 (no fix yet), left out.
    pub positions_without_fix: u64,
    /// Attitude samples taken.
    pub attitudes: u64,
    /// Traffic reports taken (ULog's transponder_report).
    pub traffic: u64,
    /// Estimator resets of the position (ULog's reset counters stepping).
    pub estimator_resets: u64,
    /// The ULog reader's counts (dropouts, corrupt messages).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ulog: Option<UlogCounts>,
    /// The DataFlash reader's counts (skipped bytes, unreadable messages).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dataflash: Option<DataflashCounts>,
}

/// A log's reports in time order, and what it held.
#[derive(Debug, Clone, Default)]
pub struct FlightLog {
    /// The reports, by time (stable: equal times keep the log's order).
    pub reports: Vec<Timed>,
    /// What it held.
    pub summary: LogSummary,
}

/// A position source's sample: where, and its time.
struct Fix {
    t_us: u64,
    position: Geodetic,
}

/// Positions to reports: velocity from the change since the previous fix (logs of different
/// versions carry no velocity in common), height above the first fix as the relative altitude
/// unless the log gives one.
#[derive(Default)]
struct Positions {
    previous: Option<(u64, Geodetic)>,
    first_alt_m: Option<f64>,
}

impl Positions {
    fn report(&mut self, fix: &Fix, relative_alt_m: Option<f64>) -> Report {
        let velocity_ned_mps = match self.previous {
            Some((t0, p0)) if fix.t_us > t0 => {
                let enu = LocalTangentPlane::new(p0).enu_m_from_geodetic(&fix.position);
                let dt_s = (fix.t_us - t0) as f64 * 1e-6;
                DVec3::new(enu.y, enu.x, -enu.z) / dt_s
            }
            _ => DVec3::ZERO,
        };
        self.previous = Some((fix.t_us, fix.position));
        let first = *self.first_alt_m.get_or_insert(fix.position.alt_m);
        Report::Position(PositionReport {
            time_boot_ms: (fix.t_us / 1000) as u32,
            position: fix.position,
            relative_alt_m: relative_alt_m.unwrap_or(fix.position.alt_m - first),
            velocity_ned_mps,
            heading_deg: None,
        })
    }
}

/// A fix at `lat_deg`, `lon_deg`, `alt_m`, or `None` (counted) at the no-fix sentinel 0, 0 or
/// where a value is not a number.
fn fix(t_us: u64, lat_deg: f64, lon_deg: f64, alt_m: f64, no_fix: &mut u64) -> Option<Fix> {
    if lat_deg == 0.0 && lon_deg == 0.0 {
        *no_fix += 1;
        return None;
    }
    let position = Geodetic::new(lat_deg, lon_deg, alt_m);
    (position.is_valid() && alt_m.is_finite()).then_some(Fix { t_us, position })
}

fn attitude(t_us: u64, roll_rad: f64, pitch_rad: f64, yaw_rad: f64) -> Option<Report> {
    [roll_rad, pitch_rad, yaw_rad]
        .iter()
        .all(|v| v.is_finite())
        .then_some(Report::Attitude(AttitudeReport {
            time_boot_ms: (t_us / 1000) as u32,
            roll_rad,
            pitch_rad,
            yaw_rad,
            body_rates_radps: DVec3::ZERO,
        }))
}

/// The reports of a log, each from the vehicle (traffic from its ADS-B receiver), sorted by
/// time, stably.
fn timed(reports: Vec<(u64, Report)>, vehicle: SenderId) -> Vec<Timed> {
    let mut timed: Vec<Timed> = reports
        .into_iter()
        .map(|(t_us, report)| Timed {
            t_us,
            sender: traffic_sender(&report, vehicle),
            report,
        })
        .collect();
    timed.sort_by_key(|r| r.t_us);
    timed
}

/// The vehicle's identity: its system id parameter (SYSID_THISMAV, MAV_SYS_ID) if the log
/// has one in 1..=255, else 1; component 1 (the autopilot).
fn vehicle(system_id: Option<f64>) -> SenderId {
    let system_id = system_id
        .filter(|v| (1.0..=255.0).contains(v))
        .map_or(1, |v| v as u8);
    SenderId {
        system_id,
        component_id: 1,
    }
}

/// ULog topics for the position, in the order preferred.
const ULOG_POSITION: [&str; 3] = [
    "vehicle_global_position",
    "vehicle_gps_position",
    "sensor_gps",
];

/// Every topic a ULog is read for: the positions', the attitude's and the traffic's.
const ULOG_TOPICS: [&str; 5] = [
    "vehicle_global_position",
    "vehicle_gps_position",
    "sensor_gps",
    "vehicle_attitude",
    "transponder_report",
];

/// A PX4 ULog's reports: positions from `vehicle_global_position` (else the GPS topic),
/// instance 0; attitudes from `vehicle_attitude` instance 0; traffic from
/// `transponder_report`.
pub fn read_ulog(data: &[u8]) -> Result<FlightLog, UlogError> {
    let position_topic = ulog_position_topic(data)?;
    let mut reader = UlogReader::new(data)?.only(&ULOG_TOPICS);
    let mut summary = LogSummary::default();
    let mut taken = Vec::new();
    let mut positions = Positions::default();
    let mut resets: Option<(f64, f64)> = None;
    while let Some(s) = reader.next_sample()? {
        let Some(t_us) = s.timestamp_us() else {
            continue;
        };
        let report = match s.topic {
            t if Some(t) == position_topic && s.instance == 0 => {
                count_resets(&s, &mut resets, &mut summary.estimator_resets);
                let Some(f) = ulog_fix(&s, t_us, &mut summary.positions_without_fix) else {
                    continue;
                };
                summary.positions += 1;
                positions.report(&f, None)
            }
            "vehicle_attitude" if s.instance == 0 => {
                let q = |i: &str| s.get(i);
                let (Some(w), Some(x), Some(y), Some(z)) =
                    (q("q[0]"), q("q[1]"), q("q[2]"), q("q[3]"))
                else {
                    continue;
                };
                let (yaw, pitch, roll) = DQuat::from_xyzw(x, y, z, w)
                    .normalize()
                    .to_euler(EulerRot::ZYX);
                let Some(a) = attitude(t_us, roll, pitch, yaw) else {
                    continue;
                };
                summary.attitudes += 1;
                a
            }
            "transponder_report" => {
                let Some(a) = ulog_traffic(&s) else { continue };
                summary.traffic += 1;
                a
            }
            _ => continue,
        };
        taken.push((t_us, report));
    }
    let sender = vehicle(reader.parameter("MAV_SYS_ID"));
    summary.position_source = position_topic;
    summary.attitude_source = (summary.attitudes > 0).then_some("vehicle_attitude");
    summary.ulog = Some(reader.counts());
    Ok(FlightLog {
        reports: timed(taken, sender),
        summary,
    })
}

/// Traffic is heard by the vehicle's receiver: a separate component, so that it is never
/// taken for the vehicle's own position.
fn traffic_sender(report: &Report, vehicle: SenderId) -> SenderId {
    match report {
        Report::Adsb(_) => SenderId {
            component_id: 156, // MAV_COMP_ID_ADSB
            ..vehicle
        },
        _ => vehicle,
    }
}

/// The first of [`ULOG_POSITION`] the log has samples of (a pass over its data).
fn ulog_position_topic(data: &[u8]) -> Result<Option<&'static str>, UlogError> {
    let mut reader = UlogReader::new(data)?.only(&ULOG_POSITION);
    let mut found = [false; ULOG_POSITION.len()];
    while let Some(s) = reader.next_sample()? {
        if let Some(i) = ULOG_POSITION.iter().position(|t| *t == s.topic) {
            found[i] |= s.instance == 0;
        }
    }
    Ok(ULOG_POSITION
        .iter()
        .zip(found)
        .find_map(|(t, f)| f.then_some(*t)))
}

/// A position sample in degrees and metres: `lat`/`lon`/`alt` in degrees and metres on
/// vehicle_global_position and GPS topics since PX4 v1.14 (`latitude_deg`...), in 1e-7 degrees
/// and millimetres on older GPS topics.
fn ulog_fix(s: &Sample<'_>, t_us: u64, no_fix: &mut u64) -> Option<Fix> {
    let (lat, lon, alt) = if s.topic == "vehicle_global_position" {
        (s.get("lat")?, s.get("lon")?, s.get("alt")?)
    } else if let Some(lat) = s.get("latitude_deg") {
        (lat, s.get("longitude_deg")?, s.get("altitude_msl_m")?)
    } else {
        (
            s.get("lat")? * 1e-7,
            s.get("lon")? * 1e-7,
            s.get("alt")? * 1e-3,
        )
    };
    fix(t_us, lat, lon, alt, no_fix)
}

/// Counts a step of the estimator's reset counters (horizontal or vertical).
fn count_resets(s: &Sample<'_>, last: &mut Option<(f64, f64)>, resets: &mut u64) {
    let now = (
        s.get("lat_lon_reset_counter").unwrap_or(0.0),
        s.get("alt_reset_counter").unwrap_or(0.0),
    );
    if let Some(before) = last.replace(now) {
        *resets += u64::from(now.0 != before.0) + u64::from(now.1 != before.1);
    }
}

/// A transponder_report with valid coordinates (flag 1) as traffic.
fn ulog_traffic(s: &Sample<'_>) -> Option<Report> {
    let flags = s.get("flags")? as u32;
    if flags & 1 == 0 {
        return None;
    }
    let position = Geodetic::new(s.get("lat")?, s.get("lon")?, s.get("altitude")?);
    if !position.is_valid() {
        return None;
    }
    let mut callsign = [0u8; 9];
    if let Some(text) = s.text("callsign", 9) {
        for (to, from) in callsign.iter_mut().zip(text.bytes()) {
            *to = from;
        }
    }
    Some(Report::Adsb(AdsbReport {
        icao_address: s.get("icao_address")? as u32,
        position,
        heading_deg: s.get("heading")?.to_degrees().rem_euclid(360.0),
        horizontal_speed_mps: s.get("hor_velocity")?,
        vertical_speed_mps: s.get("ver_velocity")?,
        pressure_altitude: s.get("altitude_type") == Some(0.0),
        emitter_type: s.get("emitter_type").unwrap_or(0.0) as u8,
        callsign,
    }))
}

/// DataFlash messages for the position, in the order preferred.
const DF_POSITION: [&str; 3] = ["POS", "AHR2", "GPS"];
/// DataFlash messages for the attitude, in the order preferred.
const DF_ATTITUDE: [&str; 2] = ["ATT", "AHR2"];

/// An ArduPilot DataFlash log's reports: positions from POS (else AHR2, else GPS instance 0),
/// attitudes from ATT (else AHR2), on the TimeUS clock (TimeMS in old logs).
pub fn read_dataflash(data: &[u8]) -> FlightLog {
    let (position, attitude_source, system_id) = dataflash_sources(data);
    let mut reader = DataflashReader::new(data);
    let mut summary = LogSummary::default();
    let mut reports = Vec::new();
    let mut positions = Positions::default();
    while let Some(m) = reader.next_message() {
        let Some(t_us) = df_time_us(&m) else { continue };
        if Some(m.name()) == position && df_gps_instance_ok(&m) {
            if let Some(f) = fix(
                t_us,
                m.get("Lat").unwrap_or(f64::NAN),
                m.get("Lng").unwrap_or(f64::NAN),
                m.get("Alt").unwrap_or(f64::NAN),
                &mut summary.positions_without_fix,
            ) {
                summary.positions += 1;
                reports.push((t_us, positions.report(&f, m.get("RelHomeAlt"))));
            }
        }
        if Some(m.name()) == attitude_source {
            let deg = |c| m.get(c).map_or(f64::NAN, f64::to_radians);
            if let Some(a) = attitude(t_us, deg("Roll"), deg("Pitch"), deg("Yaw")) {
                summary.attitudes += 1;
                reports.push((t_us, a));
            }
        }
        if m.name() == "ADSB" {
            if let Some(a) = df_traffic(&m) {
                summary.traffic += 1;
                reports.push((t_us, a));
            }
        }
    }
    let sender = vehicle(system_id);
    summary.position_source = position;
    summary.attitude_source = attitude_source;
    summary.dataflash = Some(reader.counts());
    FlightLog {
        reports: timed(reports, sender),
        summary,
    }
}

/// An `ADSB` message (what ArduPilot's ADS-B receiver heard, logged with `ADSB_LOG` 1 or 2)
/// as traffic. Its columns are ADSB_VEHICLE's fields as received (AP_ADSB::write_log): Lat
/// and Lng in 1e-7 degrees, Alt in millimetres (the log's FMTU says centimetres; ArduPilot
/// logs the MAVLink field, which is millimetres), Heading in centidegrees, Hor_vel and
/// Ver_vel in cm/s (up positive). The message has neither validity flags nor the altitude's
/// type: a position at 0, 0 is skipped as no fix, and the altitude is taken as geometric.
fn df_traffic(m: &Message<'_>) -> Option<Report> {
    let position = Geodetic::new(
        m.get("Lat")? * 1e-7,
        m.get("Lng")? * 1e-7,
        m.get("Alt")? * 1e-3,
    );
    if !position.is_valid() || (position.lat_deg == 0.0 && position.lon_deg == 0.0) {
        return None;
    }
    Some(Report::Adsb(AdsbReport {
        icao_address: m.get("ICAO_address")? as u32,
        position,
        heading_deg: (m.get("Heading")? * 0.01).rem_euclid(360.0),
        horizontal_speed_mps: m.get("Hor_vel")? * 0.01,
        vertical_speed_mps: m.get("Ver_vel")? * 0.01,
        pressure_altitude: false,
        emitter_type: 0,
        callsign: [0; 9],
    }))
}

/// GPS messages of newer logs carry an instance column `I`: only instance 0 is the vehicle's
/// position.
fn df_gps_instance_ok(m: &Message<'_>) -> bool {
    m.name() != "GPS" || m.get("I").is_none_or(|i| i == 0.0)
}

/// A message's time: TimeUS, or TimeMS in logs older than TimeUS.
fn df_time_us(m: &Message<'_>) -> Option<u64> {
    m.get("TimeUS")
        .or_else(|| m.get("TimeMS").map(|ms| ms * 1000.0))
        .filter(|t| t.is_finite() && *t >= 0.0)
        .map(|t| t as u64)
}

/// The position and attitude messages the log has (a pass over it), and SYSID_THISMAV.
fn dataflash_sources(data: &[u8]) -> (Option<&'static str>, Option<&'static str>, Option<f64>) {
    let mut reader = DataflashReader::new(data);
    let (mut has_position, mut has_attitude) = ([false; 3], [false; 2]);
    let mut system_id = None;
    while let Some(m) = reader.next_message() {
        if let Some(i) = DF_POSITION.iter().position(|n| *n == m.name()) {
            has_position[i] = true;
        }
        if let Some(i) = DF_ATTITUDE.iter().position(|n| *n == m.name()) {
            has_attitude[i] = true;
        }
        if m.name() == "PARM" && m.text("Name") == Some("SYSID_THISMAV") {
            system_id = m.get("Value");
        }
    }
    let first = |names: &[&'static str], has: &[bool]| {
        names.iter().zip(has).find_map(|(n, h)| h.then_some(*n))
    };
    (
        first(&DF_POSITION, &has_position),
        first(&DF_ATTITUDE, &has_attitude),
        system_id,
    )
}

//! The world-state store: every vehicle and traffic aircraft, in the scene's local ENU metres.
//!
//! Fed by decoded MAVLink reports (never by raw bytes), read by the collision pipeline as
//! `Copy` samples. Per track it keeps the latest state with both clocks (the vehicle's
//! `time_boot_ms` and the receive/tlog time), a short history for interpolation, and its age;
//! stale tracks expire. Vehicles are keyed by (sysid, compid), traffic by ICAO address. No I/O,
//! no tokio, no rerun.

use std::collections::{BTreeMap, VecDeque};

use glam::{DMat3, DQuat, DVec3, EulerRot};
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavType};

use crate::geo::{Geodetic, LocalTangentPlane};
pub mod report;

use report::{AdsbReport, AttitudeReport, PositionReport, Report, SenderId};

/// How the store ages and remembers tracks. Defaults in the field docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldConfig {
    /// A track not heard from for this long (seconds, receive/tlog clock) is dropped. Default 10.
    pub stale_after_s: f64,
    /// Samples of history kept per track for interpolation. Default 64.
    pub history_len: usize,
    /// A `time_boot_ms` that goes back by more than this (ms) means the vehicle rebooted.
    /// Default 5000.
    pub boot_reset_threshold_ms: u32,
    /// A vehicle's samples are timed by its own clock (`time_boot_ms`) mapped onto the receive
    /// clock; when the mapped time drifts further than this from arrival (seconds: a SITL
    /// speed-up, a clock that runs fast or slow), it is pulled back within it and counted.
    /// Default 2.
    pub max_clock_skew_s: f64,
}

impl Default for WorldConfig {
    fn default() -> Self {
        Self {
            stale_after_s: 10.0,
            history_len: 64,
            boot_reset_threshold_ms: 5_000,
            max_clock_skew_s: 2.0,
        }
    }
}

/// Orientation of a body: the rotation from its Forward-Right-Down axes to the scene's ENU axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attitude {
    /// Vehicle clock of the ATTITUDE message, ms (0 when derived from a heading).
    pub time_boot_ms: u32,
    /// Rotation taking body FRD vectors into scene ENU.
    pub enu_from_frd: DQuat,
    /// Body rates (roll, pitch, yaw), rad/s.
    pub body_rates_radps: DVec3,
}

impl Attitude {
    /// The attitude of a body at `position` with MAVLink roll, pitch, yaw (relative to the local
    /// NED frame there), expressed in `plane`'s ENU axes.
    ///
    /// ```
    /// use savsim::{geo::{Geodetic, LocalTangentPlane}, world::Attitude};
    /// use glam::DVec3;
    /// let origin = Geodetic::new(47.0, 8.0, 500.0);
    /// let plane = LocalTangentPlane::new(origin);
    /// // Yaw 90 degrees: nose east.
    /// let a = Attitude::from_euler_ned(&plane, &origin, 0.0, 0.0, std::f64::consts::FRAC_PI_2, 0);
    /// let forward = a.forward_enu();
    /// assert!((forward - DVec3::X).length() < 1e-9);
    /// ```
    pub fn from_euler_ned(
        plane: &LocalTangentPlane,
        position: &Geodetic,
        roll_rad: f64,
        pitch_rad: f64,
        yaw_rad: f64,
        time_boot_ms: u32,
    ) -> Self {
        let ned_from_frd = DQuat::from_euler(EulerRot::ZYX, yaw_rad, pitch_rad, roll_rad);
        let enu_from_ned = DMat3::from_cols(DVec3::Y, DVec3::X, DVec3::NEG_Z);
        let plane_from_local = plane.plane_enu_from_local_enu_at(position);
        let enu_from_frd =
            DQuat::from_mat3(&(plane_from_local * enu_from_ned * DMat3::from_quat(ned_from_frd)))
                .normalize();
        Self {
            time_boot_ms,
            enu_from_frd,
            body_rates_radps: DVec3::ZERO,
        }
    }

    /// The body's forward (x) axis in ENU.
    pub fn forward_enu(&self) -> DVec3 {
        self.enu_from_frd * DVec3::X
    }
}

/// One state of a vehicle or aircraft at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSample {
    /// When, seconds on the receive/tlog clock (UNIX time for tlogs and live). For a MAVLink
    /// vehicle this is its own clock (`time_boot_ms`) mapped onto the receive clock: intervals
    /// between its samples are the vehicle's, even when several arrive in one read.
    pub t_s: f64,
    /// Vehicle clock of the position, ms since boot (0 for ADS-B).
    pub time_boot_ms: u32,
    /// WGS84 position (alt AMSL).
    pub position: Geodetic,
    /// Position in the scene's ENU frame, metres from the origin.
    pub position_enu_m: DVec3,
    /// Velocity in the scene's ENU axes, m/s.
    pub velocity_enu_mps: DVec3,
    /// Orientation (the latest ATTITUDE, or one derived from the course for traffic).
    pub attitude: Attitude,
}

impl TrackSample {
    /// Linear interpolation of position and velocity, spherical of attitude; `u` in [0, 1].
    pub fn lerp(&self, next: &TrackSample, u: f64) -> TrackSample {
        let u = u.clamp(0.0, 1.0);
        TrackSample {
            t_s: self.t_s + (next.t_s - self.t_s) * u,
            time_boot_ms: if u < 0.5 {
                self.time_boot_ms
            } else {
                next.time_boot_ms
            },
            position: if u < 0.5 {
                self.position
            } else {
                next.position
            },
            position_enu_m: self.position_enu_m.lerp(next.position_enu_m, u),
            velocity_enu_mps: self.velocity_enu_mps.lerp(next.velocity_enu_mps, u),
            attitude: Attitude {
                time_boot_ms: next.attitude.time_boot_ms,
                enu_from_frd: self
                    .attitude
                    .enu_from_frd
                    .slerp(next.attitude.enu_from_frd, u),
                body_rates_radps: next.attitude.body_rates_radps,
            },
        }
    }
}

/// A track's history: latest samples in time order.
#[derive(Debug, Clone, Default)]
pub struct History {
    samples: VecDeque<TrackSample>,
}

impl History {
    fn push(&mut self, sample: TrackSample, capacity: usize) {
        if self.samples.len() == capacity.max(2) {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The newest sample.
    pub fn latest(&self) -> Option<&TrackSample> {
        self.samples.back()
    }

    /// The sample before the newest.
    pub fn previous(&self) -> Option<&TrackSample> {
        self.samples.len().checked_sub(2).map(|i| &self.samples[i])
    }

    /// The state at `t_s`: interpolated inside the history, held at its ends.
    pub fn at(&self, t_s: f64) -> Option<TrackSample> {
        let first = self.samples.front()?;
        if t_s <= first.t_s {
            return Some(*first);
        }
        let i = self.samples.partition_point(|s| s.t_s <= t_s);
        if i >= self.samples.len() {
            return self.samples.back().copied();
        }
        let (a, b) = (&self.samples[i - 1], &self.samples[i]);
        let span = b.t_s - a.t_s;
        Some(if span > 0.0 {
            a.lerp(b, (t_s - a.t_s) / span)
        } else {
            *b
        })
    }

    /// The state at `t_s`, extrapolated along the newest velocity (at most `max_ahead_s`) when
    /// `t_s` is past the newest sample: traffic reports slower than the vehicle's ticks.
    pub fn predict(&self, t_s: f64, max_ahead_s: f64) -> Option<TrackSample> {
        let latest = self.samples.back()?;
        if t_s <= latest.t_s {
            return self.at(t_s);
        }
        let ahead_s = (t_s - latest.t_s).min(max_ahead_s);
        Some(TrackSample {
            t_s,
            position_enu_m: latest.position_enu_m + latest.velocity_enu_mps * ahead_s,
            ..*latest
        })
    }

    /// Number of samples held.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True when no sample is held.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    fn clear(&mut self) {
        self.samples.clear();
    }
}

/// A MAVLink vehicle (a sender of GLOBAL_POSITION_INT).
#[derive(Debug, Clone)]
pub struct VehicleTrack {
    /// Its id as a moving obstacle to other vehicles (`vehicle:7`).
    pub label: std::sync::Arc<str>,
    /// Generation of the track: new at creation and at every reboot, so collision state kept
    /// for an earlier life of the same (sysid, compid) is detectably stale.
    pub generation: u32,
    /// Who it is.
    pub id: SenderId,
    /// MAV_TYPE from its HEARTBEAT, if one came.
    pub vehicle_type: Option<MavType>,
    /// MAV_AUTOPILOT from its HEARTBEAT, if one came.
    pub autopilot: Option<MavAutopilot>,
    /// The latest ATTITUDE, converted; positions take it until the next one.
    pub latest_attitude: Option<Attitude>,
    /// Position history.
    pub history: History,
    /// Receive/tlog time of the last message of any kind, seconds.
    pub last_heard_t_s: f64,
    /// Times its `time_boot_ms` went back (reboots).
    pub boot_resets: u64,
    /// Positions accepted.
    pub positions: u64,
}

/// An ADS-B aircraft.
#[derive(Debug, Clone)]
pub struct TrafficTrack {
    /// Its id as a moving obstacle (`icao:4840D6`).
    pub label: std::sync::Arc<str>,
    /// Generation of the track: new each time it is created (after an expiry too).
    pub generation: u32,
    /// ICAO 24-bit address.
    pub icao_address: u32,
    /// Callsign as sent (trimmed ASCII).
    pub callsign: String,
    /// ADSB_EMITTER_TYPE number.
    pub emitter_type: u8,
    /// Position history.
    pub history: History,
    /// Receive/tlog time of its last report, seconds.
    pub last_heard_t_s: f64,
}

/// What a report changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WorldUpdate {
    /// A vehicle has a new position sample.
    VehicleMoved(SenderId),
    /// A traffic aircraft has a new position sample.
    TrafficMoved(u32),
    /// Something else changed (attitude, identity).
    Other,
}

/// All tracks, in the scene's frame.
#[derive(Debug, Clone)]
pub struct WorldStore {
    plane: LocalTangentPlane,
    config: WorldConfig,
    /// MAVLink vehicles by (sysid, compid).
    pub vehicles: BTreeMap<SenderId, VehicleTrack>,
    /// ADS-B traffic by ICAO address.
    pub traffic: BTreeMap<u32, TrafficTrack>,
    /// Tracks dropped as stale so far.
    pub expired: u64,
    /// Every vehicle ever seen, kept after its track expires (for summaries).
    pub seen: BTreeMap<SenderId, VehicleSeen>,
    /// The next track generation handed out.
    next_generation: u32,
}

/// What the store saw of one vehicle over a whole run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct VehicleSeen {
    /// Positions accepted.
    pub positions: u64,
    /// Reboots detected from `time_boot_ms` going back.
    pub boot_resets: u64,
    /// Times its track expired and came back.
    pub returns: u64,
    /// Times its clock, mapped onto the receive clock, drifted beyond `max_clock_skew_s` and
    /// was pulled back.
    pub clock_reanchors: u64,
}

impl WorldStore {
    /// An empty store whose ENU frame is the tangent plane at `origin`.
    pub fn new(origin: Geodetic, config: WorldConfig) -> Self {
        Self {
            plane: LocalTangentPlane::new(origin),
            config,
            vehicles: BTreeMap::new(),
            traffic: BTreeMap::new(),
            expired: 0,
            seen: BTreeMap::new(),
            next_generation: 1,
        }
    }

    /// The scene's tangent plane.
    pub fn plane(&self) -> &LocalTangentPlane {
        &self.plane
    }

    /// Apply one decoded report from `sender`, received at `t_s`.
    ///
    /// ```
    /// use savsim::{geo::Geodetic, world::{WorldStore, WorldConfig, WorldUpdate}};
    /// use savsim::world::report::{PositionReport, Report, SenderId};
    /// let origin = Geodetic::new(-35.363261, 149.165230, 584.0);
    /// let mut world = WorldStore::new(origin, WorldConfig::default());
    /// let sender = SenderId { system_id: 1, component_id: 1 };
    /// let report = Report::Position(PositionReport {
    ///     time_boot_ms: 1000, position: Geodetic::new(-35.363261, 149.165230, 634.0),
    ///     relative_alt_m: 50.0, velocity_ned_mps: glam::DVec3::ZERO, heading_deg: None });
    /// assert_eq!(world.apply(10.0, sender, &report), WorldUpdate::VehicleMoved(sender));
    /// let up_m = world.vehicles[&sender].history.latest().unwrap().position_enu_m.z;
    /// assert!((up_m - 50.0).abs() < 1e-6);
    /// ```
    pub fn apply(&mut self, t_s: f64, sender: SenderId, report: &Report) -> WorldUpdate {
        match report {
            Report::Position(p) => {
                self.apply_position(t_s, sender, p);
                WorldUpdate::VehicleMoved(sender)
            }
            Report::Attitude(a) => {
                self.apply_attitude(t_s, sender, a);
                WorldUpdate::Other
            }
            Report::Heartbeat(h) => {
                if let Some(track) = self.vehicles.get_mut(&sender) {
                    track.vehicle_type = h.vehicle_type;
                    track.autopilot = h.autopilot;
                    track.last_heard_t_s = t_s;
                }
                WorldUpdate::Other
            }
            Report::Adsb(a) => {
                self.apply_adsb(t_s, a);
                WorldUpdate::TrafficMoved(a.icao_address)
            }
        }
    }

    fn vehicle(&mut self, sender: SenderId, t_s: f64) -> &mut VehicleTrack {
        let seen = &mut self.seen;
        let next = &mut self.next_generation;
        self.vehicles.entry(sender).or_insert_with(|| {
            if let Some(before) = seen.get_mut(&sender) {
                before.returns += 1;
            }
            let generation = *next;
            *next = next.wrapping_add(1);
            VehicleTrack {
                id: sender,
                generation,
                label: format!("vehicle:{}", sender.system_id).into(),
                vehicle_type: None,
                autopilot: None,
                latest_attitude: None,
                history: History::default(),
                last_heard_t_s: t_s,
                boot_resets: 0,
                positions: 0,
            }
        })
    }

    fn apply_attitude(&mut self, t_s: f64, sender: SenderId, a: &AttitudeReport) {
        // Attitude is relative to the NED frame where the vehicle is: use its last position.
        let Some(track) = self.vehicles.get(&sender) else {
            // No position yet: remember the attitude at the origin's axes.
            let plane = self.plane;
            let origin = plane.origin();
            let attitude = attitude_of(&plane, &origin, a);
            let track = self.vehicle(sender, t_s);
            track.latest_attitude = Some(attitude);
            track.last_heard_t_s = t_s;
            return;
        };
        let position = track
            .history
            .latest()
            .map_or(self.plane.origin(), |s| s.position);
        let attitude = attitude_of(&self.plane, &position, a);
        let track = self.vehicle(sender, t_s);
        track.latest_attitude = Some(attitude);
        track.last_heard_t_s = t_s;
    }

    fn apply_position(&mut self, receive_t_s: f64, sender: SenderId, p: &PositionReport) {
        let plane = self.plane;
        let capacity = self.config.history_len;
        let reset_ms = self.config.boot_reset_threshold_ms;
        let skew_s = self.config.max_clock_skew_s;
        let generation = self.next_generation;
        let track = self.vehicle(sender, receive_t_s);
        let rebooted = track.history.latest().is_some_and(|last| {
            last.time_boot_ms > p.time_boot_ms
                && last.time_boot_ms - p.time_boot_ms > reset_ms
                && !is_u32_wrap(last.time_boot_ms, p.time_boot_ms)
        });
        let mut took_generation = false;
        if rebooted {
            track.boot_resets += 1;
            track.history.clear();
            track.generation = generation;
            took_generation = true;
        }
        let (t_s, reanchored) = match track.history.latest() {
            Some(last) => vehicle_time_s(last, p.time_boot_ms, receive_t_s, skew_s),
            None => (receive_t_s, false),
        };
        let velocity_enu_mps = plane.enu_vector_from_ned_at(&p.position, p.velocity_ned_mps);
        let attitude = track.latest_attitude.unwrap_or_else(|| {
            let yaw_rad = p
                .heading_deg
                .map_or_else(|| course_rad(p.velocity_ned_mps), f64::to_radians);
            Attitude::from_euler_ned(&plane, &p.position, 0.0, 0.0, yaw_rad, 0)
        });
        let sample = TrackSample {
            t_s,
            time_boot_ms: p.time_boot_ms,
            position: p.position,
            position_enu_m: plane.enu_m_from_geodetic(&p.position),
            velocity_enu_mps,
            attitude,
        };
        track.history.push(sample, capacity);
        track.positions += 1;
        track.last_heard_t_s = track.last_heard_t_s.max(receive_t_s);
        if took_generation {
            self.next_generation = self.next_generation.wrapping_add(1);
        }
        let seen = self.seen.entry(sender).or_default();
        seen.positions += 1;
        seen.boot_resets += u64::from(rebooted);
        seen.clock_reanchors += u64::from(reanchored);
    }

    fn apply_adsb(&mut self, t_s: f64, a: &AdsbReport) {
        let plane = self.plane;
        let capacity = self.config.history_len;
        let (sin_h, cos_h) = a.heading_deg.to_radians().sin_cos();
        let velocity_ned_mps = DVec3::new(
            a.horizontal_speed_mps * cos_h,
            a.horizontal_speed_mps * sin_h,
            -a.vertical_speed_mps,
        );
        let sample = TrackSample {
            t_s,
            time_boot_ms: 0,
            position: a.position,
            position_enu_m: plane.enu_m_from_geodetic(&a.position),
            velocity_enu_mps: plane.enu_vector_from_ned_at(&a.position, velocity_ned_mps),
            attitude: Attitude::from_euler_ned(
                &plane,
                &a.position,
                0.0,
                0.0,
                a.heading_deg.to_radians(),
                0,
            ),
        };
        let next = &mut self.next_generation;
        let track = self.traffic.entry(a.icao_address).or_insert_with(|| {
            let generation = *next;
            *next = next.wrapping_add(1);
            TrafficTrack {
                generation,
                icao_address: a.icao_address,
                label: format!("icao:{:06X}", a.icao_address).into(),
                callsign: String::from_utf8_lossy(&a.callsign)
                    .trim_matches(|c: char| c == '\0' || c.is_whitespace())
                    .to_owned(),
                emitter_type: a.emitter_type,
                history: History::default(),
                last_heard_t_s: t_s,
            }
        });
        track.history.push(sample, capacity);
        track.last_heard_t_s = t_s;
    }

    /// Drop tracks not heard from since `now_t_s - stale_after_s`. Returns how many went.
    pub fn expire(&mut self, now_t_s: f64) -> usize {
        let horizon = now_t_s - self.config.stale_after_s;
        let before = self.vehicles.len() + self.traffic.len();
        self.vehicles.retain(|_, v| v.last_heard_t_s >= horizon);
        self.traffic.retain(|_, t| t.last_heard_t_s >= horizon);
        let gone = before - self.vehicles.len() - self.traffic.len();
        self.expired += gone as u64;
        gone
    }

    /// Seconds since a vehicle was last heard from, at `now_t_s`.
    pub fn vehicle_age_s(&self, sender: SenderId, now_t_s: f64) -> Option<f64> {
        self.vehicles
            .get(&sender)
            .map(|v| (now_t_s - v.last_heard_t_s).max(0.0))
    }
}

fn attitude_of(plane: &LocalTangentPlane, position: &Geodetic, a: &AttitudeReport) -> Attitude {
    Attitude {
        body_rates_radps: a.body_rates_radps,
        ..Attitude::from_euler_ned(
            plane,
            position,
            a.roll_rad,
            a.pitch_rad,
            a.yaw_rad,
            a.time_boot_ms,
        )
    }
}

/// Course over ground from a NED velocity, radians clockwise from north (0 when still).
fn course_rad(velocity_ned_mps: DVec3) -> f64 {
    if velocity_ned_mps.x == 0.0 && velocity_ned_mps.y == 0.0 {
        0.0
    } else {
        velocity_ned_mps.y.atan2(velocity_ned_mps.x)
    }
}

/// The time of a vehicle's sample stamped `time_boot_ms`, following `last` (same boot): the
/// last sample's time plus the vehicle's own interval, kept within `skew_s` of the arrival
/// time `receive_t_s` (true when it had to be pulled back) and never before `last`. A sample
/// older than `last` (reordered) is held at `last`'s time.
///
/// ```
/// # use savsim::world::{vehicle_time_s, TrackSample, Attitude};
/// # use savsim::geo::Geodetic;
/// # use glam::{DQuat, DVec3};
/// # let last = TrackSample { t_s: 100.0, time_boot_ms: 5_000, position: Geodetic::new(0.0, 0.0, 0.0),
/// #     position_enu_m: DVec3::ZERO, velocity_enu_mps: DVec3::ZERO,
/// #     attitude: Attitude { time_boot_ms: 0, enu_from_frd: DQuat::IDENTITY, body_rates_radps: DVec3::ZERO } };
/// // Two samples 100 ms apart on the vehicle's clock that arrived in one read.
/// assert_eq!(vehicle_time_s(&last, 5_100, 100.0, 2.0), (100.1, false));
/// // A vehicle clock running far ahead of arrival (SITL speed-up) is pulled back.
/// assert_eq!(vehicle_time_s(&last, 9_000, 100.5, 2.0), (102.5, true));
/// ```
pub fn vehicle_time_s(
    last: &TrackSample,
    time_boot_ms: u32,
    receive_t_s: f64,
    skew_s: f64,
) -> (f64, bool) {
    // Signed difference across the u32 wrap.
    let dt_s = f64::from(time_boot_ms.wrapping_sub(last.time_boot_ms) as i32) / 1000.0;
    if dt_s <= 0.0 {
        return (last.t_s, false);
    }
    let mapped = last.t_s + dt_s;
    let lo = receive_t_s - skew_s;
    let hi = receive_t_s + skew_s;
    if (lo..=hi).contains(&mapped) {
        return (mapped, false);
    }
    // Pulled back within the skew, but still after the last sample (by at least 1 ms, or
    // the whole interval if that is smaller), so that an interval is never empty.
    let floor = last.t_s + dt_s.min(1e-3);
    (mapped.clamp(lo, hi).max(floor), true)
}

/// True when `later` follows `earlier` across the u32 wrap (about 49.7 days of uptime).
fn is_u32_wrap(earlier: u32, later: u32) -> bool {
    earlier > u32::MAX - 60_000 && later < 60_000
}

//! The world-state store: every vehicle and traffic aircraft, in the scene's local ENU metres.
//!
//! Fed by decoded MAVLink reports (never by raw bytes), read by the collision pipeline as
//! `Copy` samples. Per track it keeps the latest state with both clocks (the vehicle's
//! `time_boot_ms` and the receive/tlog time), a short history for interpolation, and its age;
//! stale tracks expire. Vehicles are keyed by (sysid, compid), traffic by ICAO address. No I/O,
//! no tokio, no rerun.

use std::collections::BTreeMap;

use glam::DVec3;

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::scene::Aabb64;
pub mod clock;
pub mod index;
pub mod inputs;
pub mod samples;
pub mod timeline;
pub mod tracks;

use index::{TrackIndex, TrackKey};
pub use inputs::SenderId;
use inputs::{AdsbReport, AttitudeReport, PositionReport, Report};
pub use samples::{Attitude, History, TrackSample};
pub use tracks::{TrafficTrack, VehicleTrack};

/// How far past a track's newest sample [`History::predict`] carries it, seconds: traffic
/// reports slower than the vehicles it is traffic to.
pub const PREDICT_MAX_S: f64 = 5.0;

/// How the store ages and remembers tracks. Defaults in the field docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldConfig {
    /// A track not heard from for this long (seconds, receive/tlog clock) is dropped. Default 10.
    pub stale_after_s: f64,
    /// Samples of history kept per track for interpolation. Default 64.
    pub history_len: usize,
    /// Vehicles' samples keep their own clock's time ([`clock::ClockMap::own_rate`]) instead
    /// of being mapped onto the receive clock at the rate they arrive. Default false; `savsim
    /// study` sets it (traffic on the vehicle's clock). With several vehicles, their clocks
    /// share one timeline, the reference's ([`timeline`]).
    pub vehicle_clock: bool,
    /// On the vehicle's clock, the system id whose clock is the timeline: other vehicles'
    /// positions before its pace is known (its first positions over
    /// [`timeline::RATE_SPAN_S`] of its clock) are not applied
    /// ([`VehicleSeen::before_timeline`]). `None` (the default): the first vehicle heard.
    pub timeline_system_id: Option<u8>,
}

impl Default for WorldConfig {
    fn default() -> Self {
        Self {
            stale_after_s: 10.0,
            history_len: 64,
            vehicle_clock: false,
            timeline_system_id: None,
        }
    }
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
    vehicles: BTreeMap<SenderId, VehicleTrack>,
    /// ADS-B traffic by ICAO address.
    traffic: BTreeMap<u32, TrafficTrack>,
    /// Tracks dropped as stale so far.
    pub expired: u64,
    /// Every vehicle ever seen, kept after its track expires (for summaries).
    pub seen: BTreeMap<SenderId, VehicleSeen>,
    /// The next track generation handed out.
    next_generation: u32,
    /// Which tracks may be near a region ([`WorldStore::tracks_near`]).
    index: TrackIndex,
    /// On the vehicle's clock: the reference vehicle and its clock ([`timeline`]).
    timeline: (Option<SenderId>, timeline::Timeline),
}

/// A track found by [`WorldStore::tracks_near`].
#[derive(Debug, Clone, Copy)]
pub enum Track<'a> {
    /// A MAVLink vehicle.
    Vehicle(&'a VehicleTrack),
    /// An ADS-B aircraft.
    Traffic(&'a TrafficTrack),
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
    /// Samples whose time on the vehicle's clock, mapped onto the receive clock, came out more
    /// than 50 ms after they arrived and were pulled back to their arrival (the clock's rate
    /// changed faster than the map followed).
    pub clock_reanchors: u64,
    /// Positions older than the newest (a reordered message), not applied.
    pub reordered: u64,
    /// Seconds of the vehicle's clock per receive second, as last fitted (its speedup).
    pub clock_speedup: f64,
    /// On the vehicle's clock with several vehicles: the largest drift of this vehicle's
    /// clock from the timeline's (the reference's), seconds, either way (0 for the reference):
    /// the largest median of [`timeline::SKEW_WINDOW`] readings in a row.
    pub clock_skew_s: f64,
    /// Positions that came before the timeline's reference vehicle's pace was known, not
    /// applied.
    pub before_timeline: u64,
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
            index: TrackIndex::default(),
            timeline: (None, timeline::Timeline::default()),
        }
    }

    /// Call `visit` with every track whose predicted position ([`History::predict`]) at some
    /// time from `since_t_s` on may lie in `region`: all of them, and perhaps others. Through
    /// the index, rebuilt first when it is stale at `now_t_s`; a scan of every track when
    /// `since_t_s` is older than the index looks back ([`index::LOOKBACK_S`]). The vehicles
    /// come first, by (system id, component id), then the traffic by ICAO address.
    ///
    /// ```
    /// use savsim_core::{geo::Geodetic, scene::Aabb64, world::{Track, WorldStore, WorldConfig}};
    /// use savsim_core::world::inputs::{PositionReport, Report, SenderId};
    /// let origin = Geodetic::new(-35.363261, 149.165230, 584.0);
    /// let mut world = WorldStore::new(origin, WorldConfig::default());
    /// for (id, east_m) in [(1u8, 0.0), (2, 5000.0)] {
    ///     let position = world.plane().geodetic_from_enu_m(glam::DVec3::new(east_m, 0.0, 50.0));
    ///     let report = Report::Position(PositionReport { time_boot_ms: 1000, position,
    ///         relative_alt_m: 50.0, velocity_ned_mps: glam::DVec3::ZERO, heading_deg: None });
    ///     world.apply(10.0, SenderId { system_id: id, component_id: 1 }, &report);
    /// }
    /// let mut found = Vec::new();
    /// let region = Aabb64::around(glam::DVec3::ZERO, glam::DVec3::splat(100.0));
    /// world.tracks_near(&region, 10.0, 10.0, |t| if let Track::Vehicle(v) = t {
    ///     found.push(v.id.system_id)
    /// });
    /// assert_eq!(found, [1]);
    /// ```
    pub fn tracks_near(
        &mut self,
        region: &Aabb64,
        since_t_s: f64,
        now_t_s: f64,
        mut visit: impl FnMut(Track<'_>),
    ) {
        let count = self.vehicles.len() + self.traffic.len();
        if self.index.stale(now_t_s, count) {
            let vehicles = self
                .vehicles
                .iter()
                .map(|(k, v)| (TrackKey::Vehicle(*k), &v.history));
            let traffic = self
                .traffic
                .iter()
                .map(|(k, t)| (TrackKey::Traffic(*k), &t.history));
            self.index.build(now_t_s, vehicles.chain(traffic));
        }
        if !self.index.covers(since_t_s) {
            self.index.scans += 1;
            self.vehicles
                .values()
                .for_each(|v| visit(Track::Vehicle(v)));
            self.traffic.values().for_each(|t| visit(Track::Traffic(t)));
            return;
        }
        let (vehicles, traffic) = (&self.vehicles, &self.traffic);
        self.index.near(region, |key| match key {
            TrackKey::Vehicle(s) => {
                if let Some(v) = vehicles.get(&s) {
                    visit(Track::Vehicle(v));
                }
            }
            TrackKey::Traffic(icao) => {
                if let Some(t) = traffic.get(&icao) {
                    visit(Track::Traffic(t));
                }
            }
        });
    }

    /// The fastest speed of any track's newest sample, m/s, over at least the tracks
    /// [`WorldStore::tracks_near`] last looked at (a bound for how far they reach).
    pub fn max_speed_mps(&self) -> f64 {
        self.index.max_speed_mps()
    }

    /// The index's builds and full scans so far.
    pub fn index_counts(&self) -> (u64, u64) {
        (self.index.builds, self.index.scans)
    }

    /// The vehicle `id`'s track, while it has one.
    pub fn vehicle(&self, id: &SenderId) -> Option<&VehicleTrack> {
        self.vehicles.get(id)
    }

    /// Every vehicle's track, by (sysid, compid).
    pub fn vehicles(&self) -> impl ExactSizeIterator<Item = (&SenderId, &VehicleTrack)> {
        self.vehicles.iter()
    }

    /// The ADS-B aircraft `icao_address`'s track, while it has one.
    pub fn aircraft(&self, icao_address: u32) -> Option<&TrafficTrack> {
        self.traffic.get(&icao_address)
    }

    /// Every ADS-B aircraft's track, by ICAO address.
    pub fn traffic(&self) -> impl ExactSizeIterator<Item = (&u32, &TrafficTrack)> {
        self.traffic.iter()
    }

    /// The vehicle with MAVLink system id `system_id` (its lowest component id, if several).
    pub fn vehicle_of_system(&self, system_id: u8) -> Option<&VehicleTrack> {
        let from = SenderId {
            system_id,
            component_id: 0,
        };
        self.vehicles
            .range(from..)
            .next()
            .map(|(_, v)| v)
            .filter(|v| v.id.system_id == system_id)
    }

    /// The scene's tangent plane.
    pub fn plane(&self) -> &LocalTangentPlane {
        &self.plane
    }

    /// Apply one decoded report from `sender`, received at `t_s`.
    ///
    /// ```
    /// use savsim_core::{geo::Geodetic, world::{WorldStore, WorldConfig, WorldUpdate}};
    /// use savsim_core::world::inputs::{PositionReport, Report, SenderId};
    /// let origin = Geodetic::new(-35.363261, 149.165230, 584.0);
    /// let mut world = WorldStore::new(origin, WorldConfig::default());
    /// let sender = SenderId { system_id: 1, component_id: 1 };
    /// let report = Report::Position(PositionReport {
    ///     time_boot_ms: 1000, position: Geodetic::new(-35.363261, 149.165230, 634.0),
    ///     relative_alt_m: 50.0, velocity_ned_mps: glam::DVec3::ZERO, heading_deg: None });
    /// assert_eq!(world.apply(10.0, sender, &report), WorldUpdate::VehicleMoved(sender));
    /// let up_m = world.vehicle(&sender).unwrap().history.latest().unwrap().position_enu_m.z;
    /// assert!((up_m - 50.0).abs() < 1e-6);
    /// ```
    pub fn apply(&mut self, t_s: f64, sender: SenderId, report: &Report) -> WorldUpdate {
        match report {
            Report::Position(p) => {
                if self.apply_position(t_s, sender, p) {
                    WorldUpdate::VehicleMoved(sender)
                } else {
                    WorldUpdate::Other
                }
            }
            Report::Attitude(a) => {
                self.apply_attitude(t_s, sender, a);
                WorldUpdate::Other
            }
            Report::Heartbeat(h) => {
                if let Some(track) = self.vehicles.get_mut(&sender) {
                    track.heartbeat = Some(*h);
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

    fn vehicle_mut(&mut self, sender: SenderId, t_s: f64) -> &mut VehicleTrack {
        let seen = &mut self.seen;
        let next = &mut self.next_generation;
        let own_rate = self.config.vehicle_clock;
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
                heartbeat: None,
                latest_attitude: None,
                history: History::default(),
                last_heard_t_s: t_s,
                boot_resets: 0,
                clock: if own_rate {
                    clock::ClockMap::own_rate()
                } else {
                    clock::ClockMap::new(1.0)
                },
                positions: 0,
                skew: timeline::SkewWindow::default(),
                recent: timeline::RecentClock::default(),
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
            let track = self.vehicle_mut(sender, t_s);
            track.latest_attitude = Some(attitude);
            track.last_heard_t_s = t_s;
            return;
        };
        let position = track
            .history
            .latest()
            .map_or(self.plane.origin(), |s| s.position);
        let attitude = attitude_of(&self.plane, &position, a);
        let track = self.vehicle_mut(sender, t_s);
        track.latest_attitude = Some(attitude);
        track.last_heard_t_s = t_s;
    }

    /// Take a position; false when it was not applied (older than the newest: reordered).
    fn apply_position(&mut self, receive_t_s: f64, sender: SenderId, p: &PositionReport) -> bool {
        let on_timeline = self.config.vehicle_clock;
        let is_reference = on_timeline && self.is_reference(sender);
        if on_timeline && !is_reference && self.timeline.1.rate().is_none() {
            // The reference is not heard yet, or not long enough to know its pace.
            self.seen.entry(sender).or_default().before_timeline += 1;
            return false;
        }
        let placed_by_timeline = on_timeline && !is_reference;
        let timeline = self.timeline.1;
        let plane = self.plane;
        let capacity = self.config.history_len;
        let generation = self.next_generation;
        let track = self.vehicle_mut(sender, receive_t_s);
        if placed_by_timeline && track.clock.is_own_rate() {
            // Placed by when its positions were sent: its clock fitted to the receive clock.
            track.clock = clock::ClockMap::new(timeline.rate().unwrap_or(1.0));
        }
        let step = track
            .history
            .latest()
            .map(|last| clock::step(last.time_boot_ms, p.time_boot_ms));
        track.last_heard_t_s = track.last_heard_t_s.max(receive_t_s);
        if step == Some(clock::ClockStep::Reordered) {
            self.seen.entry(sender).or_default().reordered += 1;
            return false;
        }
        let rebooted = step == Some(clock::ClockStep::Restart);
        if rebooted {
            // A new life: its samples start a new track, swept from its second sample on.
            track.boot_resets += 1;
            track.history.clear();
            track.generation = generation;
            track.skew.restart();
            track.recent.clear();
            track.clock = if track.clock.is_own_rate() {
                clock::ClockMap::own_rate()
            } else {
                clock::ClockMap::new(track.clock.rate())
            };
        }
        if let Some(now_s) = timeline.at(receive_t_s).filter(|_| is_reference) {
            // The reference's clock after a reboot goes on where the timeline is.
            track.clock.anchor(p.time_boot_ms, now_s);
        }
        let (mapped_s, reanchored) = track.clock.map(p.time_boot_ms, receive_t_s);
        let t_s = if placed_by_timeline {
            track.on_timeline(p.time_boot_ms, receive_t_s, &timeline, mapped_s)
        } else {
            mapped_s
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
        let speedup = track.clock.speedup();
        let skew_s = track.skew.largest_s;
        let reference_rate = track.clock.fitted_rate();
        self.index
            .moved(TrackKey::Vehicle(sender), &self.vehicles[&sender].history);
        if rebooted {
            self.next_generation = self.next_generation.wrapping_add(1);
        }
        let seen = self.seen.entry(sender).or_default();
        seen.positions += 1;
        seen.boot_resets += u64::from(rebooted);
        seen.clock_reanchors += u64::from(reanchored);
        seen.clock_speedup = speedup;
        seen.clock_skew_s = seen.clock_skew_s.max(skew_s);
        if is_reference {
            self.timeline
                .1
                .reference_at(t_s, receive_t_s, reference_rate);
        }
        true
    }

    /// Whether `sender` is (or now becomes) the timeline's reference vehicle.
    fn is_reference(&mut self, sender: SenderId) -> bool {
        match self.timeline.0 {
            Some(reference) => reference == sender,
            None => {
                let named = self.config.timeline_system_id;
                let becomes = named.is_none_or(|id| id == sender.system_id);
                if becomes {
                    self.timeline.0 = Some(sender);
                }
                becomes
            }
        }
    }

    /// The timeline's reference vehicle, once heard (on the vehicle's clock).
    pub fn timeline_reference(&self) -> Option<SenderId> {
        self.timeline.0
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
                pressure_altitude: a.pressure_altitude,
            }
        });
        track.history.push(sample, capacity);
        track.last_heard_t_s = t_s;
        track.pressure_altitude = a.pressure_altitude;
        self.index
            .moved(TrackKey::Traffic(a.icao_address), &track.history);
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    /// A track that turns and speeds up, sampled unevenly (two samples at one instant too).
    fn history() -> History {
        let mut h = History::default();
        for (k, t_s) in [0.0, 0.1, 0.25, 0.25, 0.3, 0.72].into_iter().enumerate() {
            let k = k as f64;
            let attitude = Attitude {
                time_boot_ms: 0,
                enu_from_frd: DQuat::from_rotation_z(0.3 * k),
                body_rates_radps: DVec3::ZERO,
            };
            h.push(
                TrackSample {
                    t_s,
                    time_boot_ms: (t_s * 1000.0) as u32,
                    position: Geodetic::new(0.0, 0.0, 0.0),
                    position_enu_m: DVec3::new(3.0 * k * k, -2.0 * k, 0.5 * k),
                    velocity_enu_mps: DVec3::new(6.0 * k, -2.0, 0.1 * k),
                    attitude,
                },
                64,
            );
        }
        h
    }

    #[test]
    fn predict_motion_is_predicts_position_and_velocity_bit_for_bit() {
        let h = history();
        for i in -20..120 {
            let t_s = f64::from(i) * 0.0137;
            let full = h.predict(t_s, 0.5).unwrap();
            let motion = h.predict_motion(t_s, 0.5).unwrap();
            assert_eq!(
                motion,
                (full.position_enu_m, full.velocity_enu_mps),
                "at {t_s}"
            );
        }
        assert_eq!(History::default().predict_motion(1.0, 0.5), None);
    }
}

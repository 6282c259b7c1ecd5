//! The closed-loop feed (docs/closed-loop.md): savsim as the vehicle's virtual range sensors
//! and traffic source. Per vehicle, paced on the vehicle's own clock (`time_boot_ms`), the
//! sensing layer casts exact rays into the scene ([`crate::collision::fan`]) and the feed turns
//! them into what the autopilot's avoidance reads: DISTANCE_SENSOR sectors (ArduPilot's
//! proximity), a downward DISTANCE_SENSOR (rangefinder), OBSTACLE_DISTANCE (PX4, ArduPilot),
//! ADSB_VEHICLE for the scene's other aircraft and vehicles, and COLLISION for savsim's own
//! threats.
//!
//! Pure and synchronous: samples in, messages out ([`FeedMessage`]); the live session sends
//! them to the link each vehicle is on, replay writes them to a tlog.
//!
//! With `--sensors` other than `ideal`, what is sent is what the modelled devices measured
//! ([`devices`]); `ideal` is the exact feed described above, bit for bit.
//!
//! - [`devices`]: the feed from modelled devices (their rays, rates, latencies and errors),
//!   with `picture` (the bins they fill, and the messages made from them) and `tracks` (the
//!   reports of other aircraft as they arrive, and what the vehicle was told).
//! - [`sectors`]: which way each reading looks (levelled, clockwise from the nose).
//! - [`wire`]: the MAVLink messages and their units.
//! - [`threats`]: closest approach of the other aircraft, for COLLISION.

pub mod devices;
mod picture;
pub mod sectors;
pub mod threats;
mod tracks;
pub mod wire;

use std::collections::BTreeMap;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::MavMessage;
use serde::Serialize;

use crate::geo::LocalTangentPlane;
use crate::ingest::stats::SenderId;
use crate::pipeline::{BodySource, DynamicBody, MovingBodies, Pipeline, Rays, VehicleKey};
use crate::scene::{DynamicSource, Scene};
use crate::world::clock::{self, ClockStep};
use crate::world::report::Report;
use crate::world::TrackSample;
use sectors::{Levelled, BINS, SECTORS};
pub use tracks::Told;
use wire::Range;

/// MAV_SENSOR_ORIENTATION of the upward reading.
pub const ORIENTATION_UP: u8 = 24;
/// MAV_SENSOR_ORIENTATION of the downward reading (the rangefinder).
pub const ORIENTATION_DOWN: u8 = 25;

/// What the feed sends.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FeedKinds {
    /// DISTANCE_SENSOR per horizontal sector (and up): ArduPilot's MAVLink proximity.
    pub proximity: bool,
    /// DISTANCE_SENSOR down: ArduPilot's MAVLink rangefinder, PX4's distance sensor.
    pub rangefinder: bool,
    /// OBSTACLE_DISTANCE, 72 bins: PX4's collision prevention, ArduPilot's proximity.
    pub obstacle_distance: bool,
    /// ADSB_VEHICLE for the other aircraft: ArduPilot's and PX4's traffic avoidance.
    pub adsb: bool,
    /// COLLISION for savsim's own threats.
    pub collision: bool,
}

impl FeedKinds {
    /// Parse `proximity,rangefinder,obstacle-distance,adsb,collision` (any subset).
    ///
    /// ```
    /// use savsim::feed::FeedKinds;
    /// let k = FeedKinds::parse("proximity,adsb").unwrap();
    /// assert!(k.proximity && k.adsb && !k.rangefinder);
    /// assert!(FeedKinds::parse("proximity,obstacle-distance").is_err());
    /// assert!(FeedKinds::parse("lidar").is_err());
    /// ```
    pub fn parse(list: &str) -> Result<Self, FeedError> {
        let mut k = FeedKinds::default();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "proximity" => k.proximity = true,
                "rangefinder" => k.rangefinder = true,
                "obstacle-distance" => k.obstacle_distance = true,
                "adsb" => k.adsb = true,
                "collision" => k.collision = true,
                other => return Err(FeedError::Unknown(other.into())),
            }
        }
        if k.proximity && k.obstacle_distance {
            // ArduPilot's MAVLink proximity keeps one picture: each message clears the other's.
            return Err(FeedError::ProximityAndObstacleDistance);
        }
        Ok(k)
    }

    /// True when anything is sent.
    pub fn any(&self) -> bool {
        self.proximity || self.rangefinder || self.obstacle_distance || self.adsb || self.collision
    }

    /// True when the horizontal bins are cast.
    fn needs_bins(&self) -> bool {
        self.proximity || self.obstacle_distance
    }
}

/// How the feed behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedConfig {
    /// What is sent.
    pub kinds: FeedKinds,
    /// Frames per second of the vehicle's clock (the autopilot's timeouts run on it).
    pub hz: f64,
    /// The range sensors' limits.
    pub range: Range,
    /// The proximity orientations sent: 0..7 (sectors), 24 (up).
    pub orientations: Vec<u8>,
    /// MAV_DISTANCE_SENSOR type of every reading (0 laser).
    pub sensor_type: u8,
    /// ADSB_VEHICLE reports per aircraft per second (vehicle's clock).
    pub adsb_hz: f64,
    /// Aircraft farther than this from the vehicle are not reported as ADS-B, metres. Default
    /// 2000, ArduCopter's ADSB_LIST_RADIUS (ArduPlane's is 10000).
    pub adsb_radius_m: f64,
    /// COLLISION: report aircraft whose closest approach comes within this horizontally,
    /// metres...
    pub collision_horizontal_m: f64,
    /// ... and this vertically, metres...
    pub collision_vertical_m: f64,
    /// ... within this many seconds.
    pub collision_horizon_s: f64,
    /// The vehicle's sensors: `ideal` (the exact feed) or modelled devices.
    pub sensors: savsim_core::sensors::suite::Suite,
    /// The seed of the devices' errors.
    pub sensor_seed: u64,
}

impl Default for FeedConfig {
    fn default() -> Self {
        Self {
            kinds: FeedKinds::default(),
            hz: 20.0,
            range: Range {
                min_m: 0.2,
                max_m: 40.0,
            },
            orientations: (0..SECTORS as u8).chain([ORIENTATION_UP]).collect(),
            sensor_type: 0,
            adsb_hz: 2.0,
            adsb_radius_m: 2000.0,
            collision_horizontal_m: 150.0,
            collision_vertical_m: 30.0,
            collision_horizon_s: 30.0,
            sensors: savsim_core::sensors::suite::Suite::Ideal,
            sensor_seed: 0,
        }
    }
}

impl FeedConfig {
    /// Check the settings; the error names what is wrong.
    pub fn validate(&self) -> Result<(), FeedError> {
        use savsim_core::bounds::{positive, within};
        positive("--feed-hz", self.hz, 1000.0)?;
        positive("the ADS-B rate", self.adsb_hz, 100.0)?;
        within("--feed-adsb-radius-m", self.adsb_radius_m, 0.0, 1e6)?;
        let Range { min_m, max_m } = self.range;
        if !(min_m.is_finite() && max_m.is_finite() && 0.0 <= min_m && min_m < max_m) {
            return Err(FeedError::RangeOrder { min_m, max_m });
        }
        if max_m > 650.0 {
            return Err(FeedError::RangeTooLong { max_m });
        }
        if let Some(&o) = self
            .orientations
            .iter()
            .find(|&&o| !(o < SECTORS as u8 || o == ORIENTATION_UP))
        {
            return Err(FeedError::Orientation(o));
        }
        Ok(())
    }
}

/// The sensors a run's feed sends from: those `list` names (`ideal`, presets with settings,
/// files of `[[sensor]]` tables, read within `crate::files`' bound), else the scene's
/// `[[sensor]]` tables, else `ideal`.
pub fn sensors_for(
    list: Option<&str>,
    scene: Option<&Scene>,
) -> crate::error::Result<savsim_core::sensors::suite::Suite> {
    use savsim_core::sensors::suite::Suite;
    let usage = |e: savsim_core::sensors::suite::SuiteError| {
        crate::error::Error::Usage(format!("--sensors: {e}"))
    };
    match (list, scene) {
        (Some(list), _) => Suite::parse(list, |path| {
            crate::files::read_text(std::path::Path::new(path), 1 << 20).map_err(|e| e.to_string())
        })
        .map_err(usage),
        (None, Some(scene)) if !scene.sensors.is_empty() => {
            Suite::from_specs(&scene.sensors).map_err(usage)
        }
        _ => Ok(Suite::Ideal),
    }
}

/// Feed settings that are not valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeedError {
    /// A rate or a radius out of range.
    #[error(transparent)]
    OutOfRange(#[from] savsim_core::bounds::OutOfRange),
    /// A range sensor's limits in the wrong order.
    #[error("the feed's range must be 0 <= min < max, not {min_m} .. {max_m} m")]
    RangeOrder {
        /// Its minimum, metres.
        min_m: f64,
        /// Its maximum, metres.
        max_m: f64,
    },
    /// A maximum range DISTANCE_SENSOR cannot carry.
    #[error("the feed's max range {max_m} m does not fit DISTANCE_SENSOR's centimetres")]
    RangeTooLong {
        /// The maximum, metres.
        max_m: f64,
    },
    /// A proximity orientation that is not one.
    #[error("proximity orientation {0}: 0..7 (45-degree sectors) or 24 (up); 25 (down) is `rangefinder`")]
    Orientation(u8),
    /// A feed that is not one.
    #[error("unknown feed `{0}` (proximity, rangefinder, obstacle-distance, adsb, collision)")]
    Unknown(String),
    /// Two feeds that cannot go together.
    #[error("`proximity` and `obstacle-distance` feed the same ArduPilot proximity backend and clear each other's picture: choose one")]
    ProximityAndObstacleDistance,
}

/// A message for a vehicle: who it is for, the vehicle's clock it was stamped with, and what.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedMessage {
    /// The vehicle (its MAVLink system and component).
    pub to: SenderId,
    /// The receive clock of the sample it was cast from, seconds (for a tlog).
    pub t_s: f64,
    /// The message.
    pub message: MavMessage,
}

/// What the feed did for one vehicle, for the summary.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct FeedCounts {
    /// Frames cast.
    pub frames: u64,
    /// Messages made.
    pub messages: u64,
    /// Intervals between frames longer than twice the period (the autopilot's picture aged).
    pub gaps: u64,
    /// Longest interval between frames, vehicle's clock, ms.
    pub max_interval_ms: u32,
    /// Vehicle's clock from the first frame to the last, ms (frames / span is the rate).
    pub span_ms: u64,
    /// Restarts of the vehicle's clock (a reboot): pacing started again.
    pub restarts: u64,
}

#[derive(Debug, Clone, Default)]
struct VehicleFeed {
    next_due_ms: Option<u32>,
    last_stamp_ms: Option<u32>,
    next_adsb_ms: Option<u32>,
    counts: FeedCounts,
    /// Its modelled devices' state (with `--sensors` other than `ideal`).
    devices: devices::VehicleDevices,
}

/// One range reading of the last frame, for the viewer: which way it looked and what it said.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Its direction (a sector's or bin's centre line, up, or body down), ENU unit vector.
    pub dir_enu: DVec3,
    /// What was sent, metres (`None`: nothing seen within range).
    pub distance_m: Option<f64>,
}

/// The feed's per-vehicle pacing and its scratch buffers.
#[derive(Debug, Clone)]
pub struct Feed {
    /// Settings.
    pub config: FeedConfig,
    /// ADSB_VEHICLE reports of the feed's own aircraft that came back (a vehicle re-streams
    /// the traffic it was told about): never applied to the world.
    pub adsb_echoes: u64,
    vehicles: BTreeMap<SenderId, VehicleFeed>,
    dirs: [DVec3; BINS],
    bins: [Option<f64>; BINS],
    readings: Vec<Reading>,
    /// The modelled devices, unless the sensors are `ideal`.
    devices: Option<devices::Devices>,
}

/// One feed frame's inputs: the scene, the vehicle and its sample, the moving bodies around it.
pub struct FrameInput<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its tangent plane (ENU <-> WGS84).
    pub plane: &'a LocalTangentPlane,
    /// The vehicle's MAVLink identity.
    pub sender: SenderId,
    /// The vehicle as a collision body.
    pub key: VehicleKey,
    /// Its newest sample.
    pub current: &'a TrackSample,
    /// The moving bodies at this sample (the vehicle's own is skipped).
    pub dynamic: &'a MovingBodies,
}

impl Feed {
    /// A feed with no vehicles yet.
    pub fn new(config: FeedConfig) -> Self {
        let devices = match &config.sensors {
            savsim_core::sensors::suite::Suite::Ideal => None,
            savsim_core::sensors::suite::Suite::Devices(d) => Some(devices::Devices::new(
                d.clone(),
                config.sensor_seed,
                config.kinds.adsb,
            )),
        };
        Self {
            config,
            adsb_echoes: 0,
            vehicles: BTreeMap::new(),
            dirs: [DVec3::ZERO; BINS],
            bins: [None; BINS],
            readings: Vec::new(),
            devices,
        }
    }

    /// What each vehicle was told of each aircraft by its modelled devices (empty with
    /// `ideal` sensors): the aircraft by its ICAO address.
    pub fn told(&self) -> impl Iterator<Item = (SenderId, u64, Told)> + '_ {
        self.vehicles
            .iter()
            .flat_map(|(id, v)| v.devices.told.iter().map(move |(k, t)| (*id, *k, *t)))
    }

    /// True (and counted) for an ADS-B report of an aircraft this feed sends as ADS-B: the
    /// vehicle or its router handing savsim's own traffic back, under the vehicle's identity
    /// (PX4 relays every ADS-B report it receives; ArduPilot with ADSB_TYPE > 0 can). Applied,
    /// it would become a second body at the aircraft's place.
    pub fn is_echo(&mut self, report: &Report) -> bool {
        let echo = matches!(report, Report::Adsb(a)
            if self.config.kinds.adsb && is_feed_icao(a.icao_address));
        self.adsb_echoes += u64::from(echo);
        echo
    }

    /// Each vehicle's counts.
    pub fn counts(&self) -> impl Iterator<Item = (SenderId, FeedCounts)> + '_ {
        self.vehicles.iter().map(|(id, v)| (*id, v.counts))
    }

    /// The range readings of the frame the last [`Feed::on_sample`] cast (empty when it cast
    /// none): what the viewer draws.
    pub fn readings(&self) -> &[Reading] {
        &self.readings
    }

    /// True when a frame is due for `sender` at its sample stamped `time_boot_ms`: one per
    /// period of the vehicle's clock (a quarter period early at most, for jitter), never two
    /// to catch up. Wrap-safe; a restart of the vehicle's clock ([`clock::step`]) starts the
    /// pacing again.
    fn due(&mut self, sender: SenderId, time_boot_ms: u32) -> bool {
        let period_ms = (1000.0 / self.config.hz).round().max(1.0) as u32;
        let v = self.vehicles.entry(sender).or_default();
        if v.last_stamp_ms
            .is_some_and(|last| clock::step(last, time_boot_ms) == ClockStep::Restart)
        {
            v.next_due_ms = None;
            v.last_stamp_ms = None;
            v.next_adsb_ms = None;
            v.counts.restarts += 1;
            devices::Devices::restart(&mut v.devices);
        }
        let early_ms = period_ms / 4;
        match v.next_due_ms {
            Some(next) if !at_or_after(time_boot_ms.wrapping_add(early_ms), next) => false,
            Some(next) => {
                let after = next.wrapping_add(period_ms);
                // Behind (a telemetry gap): one frame now, the next a period later.
                v.next_due_ms = Some(if at_or_after(time_boot_ms, after) {
                    time_boot_ms.wrapping_add(period_ms)
                } else {
                    after
                });
                true
            }
            None => {
                v.next_due_ms = Some(time_boot_ms.wrapping_add(period_ms));
                true
            }
        }
    }

    /// The frame's stamp: the sample's, always advancing (ArduPilot groups readings by it);
    /// counts the interval since the last frame.
    fn stamp(&mut self, sender: SenderId, time_boot_ms: u32) -> u32 {
        let gap_ms = 2000.0 / self.config.hz;
        let v = self.vehicles.entry(sender).or_default();
        let stamp = match v.last_stamp_ms {
            Some(last) if !at_or_after(time_boot_ms, last.wrapping_add(1)) => last.wrapping_add(1),
            _ => time_boot_ms,
        };
        if let Some(last) = v.last_stamp_ms {
            let interval = stamp.wrapping_sub(last);
            v.counts.max_interval_ms = v.counts.max_interval_ms.max(interval);
            v.counts.span_ms += u64::from(interval);
            if f64::from(interval) > gap_ms {
                v.counts.gaps += 1;
            }
        }
        v.last_stamp_ms = Some(stamp);
        v.counts.frames += 1;
        stamp
    }

    /// After a collision tick: if a frame is due for this vehicle, cast it and push its
    /// messages to `out`.
    pub fn on_sample(
        &mut self,
        pipeline: &mut Pipeline,
        input: &FrameInput<'_>,
        out: &mut Vec<FeedMessage>,
    ) {
        self.readings.clear();
        if self.devices.is_some() && self.config.kinds.any() {
            self.on_sample_devices(pipeline, input, out);
            return;
        }
        if !self.config.kinds.any() || !self.due(input.sender, input.current.time_boot_ms) {
            return;
        }
        let first = out.len();
        let stamp = self.stamp(input.sender, input.current.time_boot_ms);
        let mut frame = Frame {
            input,
            stamp,
            up_enu: input.plane.up_at(&input.current.position),
            out,
        };
        let kinds = self.config.kinds;
        if kinds.needs_bins() || kinds.rangefinder {
            self.range_readings(pipeline, &mut frame);
        }
        if kinds.adsb {
            self.adsb(&mut frame);
        }
        if kinds.collision {
            self.collisions(&mut frame);
        }
        let made = (frame.out.len() - first) as u64;
        self.vehicles
            .entry(input.sender)
            .or_default()
            .counts
            .messages += made;
    }

    /// [`Feed::on_sample`] with modelled devices: they read at every sample whose instant
    /// came (and send the reports that arrived); the range picture goes out at the feed's
    /// pace.
    fn on_sample_devices(
        &mut self,
        pipeline: &mut Pipeline,
        input: &FrameInput<'_>,
        out: &mut Vec<FeedMessage>,
    ) {
        let time_boot_ms = input.current.time_boot_ms;
        let due = self.due(input.sender, time_boot_ms);
        let first = out.len();
        let stamp = if due {
            self.stamp(input.sender, time_boot_ms)
        } else {
            time_boot_ms
        };
        let mut frame = Frame {
            input,
            stamp,
            up_enu: input.plane.up_at(&input.current.position),
            out,
        };
        let Some(devices) = self.devices.as_mut() else {
            return;
        };
        let v = self.vehicles.entry(input.sender).or_default();
        let picture = devices.on_sample(&mut v.devices, pipeline, &mut frame);
        let kinds = self.config.kinds;
        if due && (kinds.needs_bins() || kinds.rangefinder) {
            picture::send_picture(&picture, devices.range, &self.config, &mut frame);
            self.readings.extend(picture::readings_of(&picture, &frame));
        }
        if due && kinds.collision {
            self.collisions(&mut frame);
        }
        let made = (frame.out.len() - first) as u64;
        self.vehicles
            .entry(input.sender)
            .or_default()
            .counts
            .messages += made;
    }

    /// The range sensors: proximity sectors and up, OBSTACLE_DISTANCE, the rangefinder.
    fn range_readings(&mut self, pipeline: &mut Pipeline, f: &mut Frame<'_, '_>) {
        let cfg = &self.config;
        let kinds = cfg.kinds;
        let attitude = &f.input.current.attitude;
        let down_enu = (attitude.enu_from_frd * DVec3::Z).normalize_or(-f.up_enu);
        let levelled = Levelled::new(attitude.forward_enu(), down_enu, f.up_enu);
        let mut caster = Caster {
            pipeline,
            input: f.input,
            max_m: cfg.range.max_m,
        };
        if let (true, Some(levelled)) = (kinds.needs_bins(), levelled) {
            levelled.bin_directions(&mut self.dirs);
            caster.cast(&self.dirs, &mut self.bins);
        }
        let readings = &mut self.readings;
        if let (true, Some(levelled)) = (kinds.proximity, levelled) {
            for (id, &o) in cfg.orientations.iter().enumerate() {
                let (dir_enu, distance_m) = if o == ORIENTATION_UP {
                    (f.up_enu, caster.one(f.up_enu))
                } else {
                    let centre = levelled.direction(f64::from(o) * 45.0);
                    (
                        centre,
                        sectors::sector_from_bins(&self.bins, usize::from(o)),
                    )
                };
                readings.push(Reading {
                    dir_enu,
                    distance_m,
                });
                let m = wire::distance_sensor(
                    f.stamp,
                    cfg.range,
                    distance_m,
                    o,
                    cfg.sensor_type,
                    id as u8,
                );
                f.push(m);
            }
        }
        if let (true, Some(_)) = (kinds.obstacle_distance, levelled) {
            readings.extend(
                self.dirs
                    .iter()
                    .zip(&self.bins)
                    .map(|(&dir_enu, &distance_m)| Reading {
                        dir_enu,
                        distance_m,
                    }),
            );
            f.push(wire::obstacle_distance(
                f.stamp,
                cfg.range,
                &self.bins,
                cfg.sensor_type,
            ));
        }
        if kinds.rangefinder {
            let mut distance_m = caster.one(down_enu);
            if !caster.pipeline.has_terrain() {
                // No terrain: the ground is the ellipsoid's surface at the origin's height.
                let ground = f.input.plane.distance_to_height_m(
                    f.input.current.position_enu_m,
                    down_enu,
                    cfg.range.max_m,
                    f.input.plane.origin().alt_m,
                );
                distance_m = nearest(distance_m, ground);
            }
            readings.push(Reading {
                dir_enu: down_enu,
                distance_m,
            });
            let id = cfg.orientations.len() as u8;
            f.push(wire::distance_sensor(
                f.stamp,
                cfg.range,
                distance_m,
                ORIENTATION_DOWN,
                cfg.sensor_type,
                id,
            ));
        }
    }

    /// ADSB_VEHICLE for each aircraft within the ADS-B radius, at the ADS-B rate.
    fn adsb(&mut self, f: &mut Frame<'_, '_>) {
        let cfg = &self.config;
        let v = self.vehicles.entry(f.input.sender).or_default();
        if v.next_adsb_ms
            .is_some_and(|next| !at_or_after(f.stamp, next))
        {
            return;
        }
        let period_ms = (1000.0 / cfg.adsb_hz).round().max(1.0) as u32;
        v.next_adsb_ms = Some(f.stamp.wrapping_add(period_ms));
        let own = f.input.current.position_enu_m;
        for (aircraft, body) in aircraft(f.input) {
            if (body.current.position_enu_m - own).length() <= cfg.adsb_radius_m {
                f.push(wire::adsb_vehicle(&aircraft, 0.0));
            }
        }
    }

    /// COLLISION for each aircraft whose straight-on course enters the threat volume.
    fn collisions(&mut self, f: &mut Frame<'_, '_>) {
        let current = f.input.current;
        let to_local = f
            .input
            .plane
            .plane_enu_from_local_enu_at(&current.position)
            .transpose();
        for (aircraft, body) in aircraft(f.input) {
            // In the local ENU axes at the vehicle: "horizontal" and "vertical" are its own.
            let threat = threats::threat(
                DVec3::ZERO,
                to_local * current.velocity_enu_mps,
                to_local * (body.current.position_enu_m - current.position_enu_m),
                to_local * body_velocity(body),
                &self.config,
            );
            if let Some(threat) = threat {
                f.push(threats::collision(aircraft.icao_address, &threat));
            }
        }
    }
}

/// True when the stamp `a` is at or after `b` on a wrapping u32 clock (within 24.8 days).
fn at_or_after(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) >= 0
}

/// One frame being made: its inputs, stamp, the local vertical and where its messages go.
struct Frame<'i, 'o> {
    input: &'i FrameInput<'i>,
    stamp: u32,
    /// The local vertical at the vehicle, scene ENU.
    up_enu: DVec3,
    out: &'o mut Vec<FeedMessage>,
}

impl Frame<'_, '_> {
    fn push(&mut self, message: MavMessage) {
        self.out.push(FeedMessage {
            to: self.input.sender,
            t_s: self.input.current.t_s,
            message,
        });
    }
}

/// Exact rays from the vehicle into the scene and the other moving bodies.
struct Caster<'p, 'i> {
    pipeline: &'p mut Pipeline,
    input: &'i FrameInput<'i>,
    max_m: f64,
}

impl Caster<'_, '_> {
    fn cast(&mut self, dirs: &[DVec3], out: &mut [Option<f64>]) {
        let rays = Rays {
            origin_enu_m: self.input.current.position_enu_m,
            dirs_enu: dirs,
            max_m: self.max_m,
        };
        let own = self.input.key.source();
        self.pipeline
            .cast_exact_rays(self.input.scene, own, self.input.dynamic, rays, out);
    }

    fn one(&mut self, dir: DVec3) -> Option<f64> {
        let mut hit = [None];
        self.cast(&[dir], &mut hit);
        hit[0]
    }
}

fn nearest(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// A moving body's velocity, ENU m/s: its speed along its motion in this interval (along its
/// nose when it did not move).
fn body_velocity(d: &DynamicBody) -> DVec3 {
    let moved = d.current.position_enu_m - d.previous.position_enu_m;
    let along = moved
        .try_normalize()
        .unwrap_or_else(|| d.current.enu_from_body * DVec3::X);
    along * d.speed_mps
}

/// The ICAO addresses the feed gives the aircraft it sends: `0xF0xxxx` the scene's track
/// `xxxx`, `0xF1SSCC` MAVLink vehicle SS/CC. While `--feed adsb` is on, a real transponder
/// with such an address would be taken for an echo (docs/closed-loop.md, limits).
const TRACK_ICAO: u32 = 0xF0_0000;
const VEHICLE_ICAO: u32 = 0xF1_0000;

/// Whether `icao` is one the feed gives an aircraft.
fn is_feed_icao(icao: u32) -> bool {
    matches!(icao & 0xFF_0000, TRACK_ICAO | VEHICLE_ICAO)
}

/// Whether a moving body carries a transponder: a scene track as its `[[dynamic]]` says
/// (default yes), every MAVLink vehicle.
fn has_transponder(input: &FrameInput<'_>, body: &DynamicBody) -> bool {
    match body.key.source {
        BodySource::Scripted(i) => input
            .scene
            .dynamic
            .get(i as usize)
            .is_none_or(|d| d.transponder),
        _ => true,
    }
}

/// The aircraft a vehicle is told about: the scene's scripted tracks and declared vehicles, and
/// every other MAVLink vehicle savsim mirrors; not ADS-B traffic (the vehicle's own receiver
/// or its GCS already has it) and never the vehicle itself.
fn aircraft<'a>(
    input: &'a FrameInput<'a>,
) -> impl Iterator<Item = (wire::Aircraft<'a>, &'a DynamicBody)> + 'a {
    input.dynamic.as_slice().iter().filter_map(move |d| {
        let icao_address = match d.key.source {
            BodySource::Scripted(i) => match input.scene.dynamic.get(i as usize)?.source {
                DynamicSource::Icao(_) => return None,
                DynamicSource::Waypoints(_) | DynamicSource::SystemId(_) => {
                    TRACK_ICAO | (i & 0xFFFF)
                }
            },
            BodySource::Vehicle {
                vehicle,
                component_id,
            } => {
                if (vehicle, component_id) == (input.key.vehicle, input.key.component_id) {
                    return None;
                }
                VEHICLE_ICAO | (u32::from(vehicle & 0xFF) << 8) | u32::from(component_id)
            }
            BodySource::Traffic(_) => return None,
        };
        let position = input.plane.geodetic_from_enu_m(d.current.position_enu_m);
        Some((
            wire::Aircraft {
                icao_address,
                callsign: &d.id,
                position,
                velocity_ned_mps: input.plane.ned_vector_at(&position, body_velocity(d)),
                kind: d.kind,
            },
            d,
        ))
    })
}

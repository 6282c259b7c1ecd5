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

mod aircraft;
pub mod capture;
mod cast;
mod config;
pub mod devices;
mod ideal;
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
use crate::pipeline::{MovingBodies, Pipeline, VehicleKey};
use crate::scene::Scene;
use crate::world::clock::{self, ClockStep};
use crate::world::inputs::Report;
use crate::world::SenderId;
use crate::world::TrackSample;
use aircraft::is_feed_icao;
pub use config::{sensors_for, FeedConfig, FeedError, FeedKinds};
use sectors::BINS;
pub use tracks::Told;

/// MAV_SENSOR_ORIENTATION of the upward reading.
pub const ORIENTATION_UP: u8 = 24;
/// MAV_SENSOR_ORIENTATION of the downward reading (the rangefinder).
pub const ORIENTATION_DOWN: u8 = 25;

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

/// One ADS-B report the feed sent, for the viewer: the aircraft's address, a label (the address
/// and its callsign) and where the report put it (scene ENU metres, its errors included).
#[derive(Debug, Clone, PartialEq)]
pub struct AdsbSent {
    /// ICAO address (24 bits).
    pub icao_address: u32,
    /// The address and the callsign, as a person reads them.
    pub label: String,
    /// Where the report put the aircraft, scene ENU metres.
    pub position_enu_m: DVec3,
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
    adsb_sent: Vec<AdsbSent>,
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
            adsb_sent: Vec::new(),
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

    /// Keep each image device's and lidar's readings whole ([`Feed::captures`]): for the
    /// viewer; off by default (a reading is then only what the autopilot is sent).
    pub fn keep_captures(&mut self, on: bool) {
        if let Some(d) = self.devices.as_mut() {
            d.keep_captures = on;
        }
    }

    /// The range devices' readings made whole at the last [`Feed::on_sample`], when kept.
    pub fn captures(&self) -> &[std::sync::Arc<capture::Capture>] {
        self.devices.as_ref().map_or(&[], |d| &d.captures)
    }

    /// The ADS-B reports the last [`Feed::on_sample`] sent: what the viewer draws.
    pub fn adsb_sent(&self) -> &[AdsbSent] {
        &self.adsb_sent
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
    /// messages to `out`. Modelled devices read at every sample whose instant came (and send
    /// the reports that arrived); the range picture goes out at the feed's pace.
    pub fn on_sample(
        &mut self,
        pipeline: &mut Pipeline,
        input: &FrameInput<'_>,
        out: &mut Vec<FeedMessage>,
    ) {
        self.readings.clear();
        self.adsb_sent.clear();
        if !self.config.kinds.any() {
            return;
        }
        let modelled = self.devices.is_some();
        let time_boot_ms = input.current.time_boot_ms;
        let due = self.due(input.sender, time_boot_ms);
        if !due && !modelled {
            return;
        }
        let stamp = if due {
            self.stamp(input.sender, time_boot_ms)
        } else {
            time_boot_ms
        };
        let first = out.len();
        let mut adsb_sent = std::mem::take(&mut self.adsb_sent);
        let mut frame = Frame {
            input,
            stamp,
            up_enu: input.plane.up_at(&input.current.position),
            adsb_radius_m: self.config.adsb_radius_m,
            out,
            adsb_sent: &mut adsb_sent,
        };
        if modelled {
            self.cast_modelled(pipeline, due, &mut frame);
        } else {
            self.cast_ideal(pipeline, &mut frame);
        }
        let made = (frame.out.len() - first) as u64;
        self.adsb_sent = adsb_sent;
        self.vehicles
            .entry(input.sender)
            .or_default()
            .counts
            .messages += made;
    }

    /// The exact feed's frame: the levelled ring, ADS-B and COLLISION, as asked.
    fn cast_ideal(&mut self, pipeline: &mut Pipeline, frame: &mut Frame<'_, '_>) {
        let kinds = self.config.kinds;
        if kinds.needs_bins() || kinds.rangefinder {
            self.range_readings(pipeline, frame);
        }
        if kinds.adsb {
            self.adsb(frame);
        }
        if kinds.collision {
            self.collisions(frame);
        }
    }

    /// The modelled devices at this sample; when the feed's frame is `due`, their range
    /// picture and COLLISION.
    fn cast_modelled(&mut self, pipeline: &mut Pipeline, due: bool, frame: &mut Frame<'_, '_>) {
        let Some(devices) = self.devices.as_mut() else {
            return;
        };
        let v = self.vehicles.entry(frame.input.sender).or_default();
        let picture = devices.on_sample(&mut v.devices, pipeline, frame);
        let kinds = self.config.kinds;
        if due && (kinds.needs_bins() || kinds.rangefinder) {
            picture::send_picture(&picture, devices.range, &self.config, frame);
            self.readings.extend(picture::readings_of(&picture, frame));
        }
        if due && kinds.collision {
            self.collisions(frame);
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
    /// Aircraft sent as ADS-B farther than this from the vehicle are not sent, metres.
    adsb_radius_m: f64,
    out: &'o mut Vec<FeedMessage>,
    /// The ADS-B reports sent, for the viewer.
    adsb_sent: &'o mut Vec<AdsbSent>,
}

impl Frame<'_, '_> {
    /// The one rule of `--feed-adsb-radius-m`, for the exact feed and modelled devices alike:
    /// an aircraft is sent as ADS-B only where it is sent at (its truth, or a device's report
    /// of it) within the radius of the vehicle's position at this frame.
    fn within_adsb_radius(&self, position_enu_m: DVec3) -> bool {
        (position_enu_m - self.input.current.position_enu_m).length() <= self.adsb_radius_m
    }

    /// Send `aircraft` as ADSB_VEHICLE, `tslc_s` after its fix, and keep where it was put.
    fn push_adsb(&mut self, aircraft: &wire::Aircraft<'_>, tslc_s: f64) {
        self.push(wire::adsb_vehicle(aircraft, tslc_s));
        self.adsb_sent.push(AdsbSent {
            icao_address: aircraft.icao_address & 0x00FF_FFFF,
            label: wire::label(aircraft),
            position_enu_m: self.input.plane.enu_m_from_geodetic(&aircraft.position),
        });
    }

    fn push(&mut self, message: MavMessage) {
        self.out.push(FeedMessage {
            to: self.input.sender,
            t_s: self.input.current.t_s,
            message,
        });
    }
}

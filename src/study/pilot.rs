//! The study's pilot: a ground station on the autopilot's second serial port (ArduCopter
//! SITL's SERIAL1, TCP) that arms the vehicle and flies a row's plan, and hears what the
//! autopilot does (modes, COLLISION, STATUSTEXT, its version).
//!
//! Every decision is taken on the vehicle's own clock: the pilot acts at each
//! GLOBAL_POSITION_INT the vehicle sends (asked at [`POSITION_HZ`] of its clock), so a row
//! flies the same at any speedup. Targets are velocities (GUIDED's velocity targets are what
//! ArduCopter's proximity avoidance acts on, docs/closed-loop.md), re-sent at every position.

use std::io::Write;
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavFrame, MavMessage, MavModeFlag, MavParamType, MavState, MavType,
    PositionTargetTypemask, COMMAND_LONG_DATA, HEARTBEAT_DATA, MANUAL_CONTROL_DATA,
    PARAM_REQUEST_READ_DATA, PARAM_SET_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::ingest::outbox::Outbox;
use crate::ingest::stats::SenderId;
use crate::study::plan::Leg;

/// Positions asked for on the pilot's link, Hz of the vehicle's clock.
pub const POSITION_HZ: f64 = 20.0;
/// The pilot's identity: a ground station's system, a component no common GCS uses
/// (MAV_COMP_ID_USER1).
pub const PILOT: SenderId = SenderId {
    system_id: 254,
    component_id: 25,
};
/// A goto is done within this distance of its point, metres.
pub const GOTO_DONE_M: f64 = 1.0;
/// A takeoff is done within this height of its target, metres.
pub const TAKEOFF_DONE_M: f64 = 1.0;

/// ArduCopter's flight modes (custom_mode) that a study reads.
pub mod mode {
    /// GUIDED.
    pub const GUIDED: u32 = 4;
    /// LAND.
    pub const LAND: u32 = 9;
    /// AVOID_ADSB.
    pub const AVOID_ADSB: u32 = 19;
}

/// One position of the vehicle, as the pilot heard it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    /// The vehicle's clock, ms.
    pub time_boot_ms: u32,
    /// Scene ENU, metres.
    pub enu_m: DVec3,
    /// Velocity, scene ENU m/s.
    pub velocity_enu_mps: DVec3,
    /// Heading, degrees clockwise from north (`None` when the autopilot does not know it).
    pub heading_deg: Option<f64>,
    /// The row's clock at this position, seconds: the vehicle's own from its boot, or the
    /// row's first vehicle's ([`RowClock`]).
    pub row_s: f64,
}

/// Another vehicle's clock as a pilot hears it: the clock the second and further vehicles of
/// a row time their `until` legs by (its last position's time carried on at its speedup).
#[derive(Debug, Clone)]
pub struct RowClock {
    /// What the first vehicle's pilot heard.
    pub reference: std::sync::Arc<std::sync::Mutex<Heard>>,
    /// Its speedup (asked of its SITL).
    pub speedup: f64,
}

impl RowClock {
    /// The first vehicle's clock now, seconds from its boot; `None` before its first position.
    pub fn now_s(&self) -> Option<f64> {
        let heard = self.reference.lock().ok()?;
        let at = heard.position_at?;
        let now = Instant::now();
        Some(crate::study::pace::carried(
            heard.time_boot_ms,
            at,
            now,
            self.speedup,
        ))
    }
}

/// What the autopilot said, and its positions sampled.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Heard {
    /// Its positions in the scene's frame (ENU, m) with its clock (ms), one each
    /// [`TRACK_PERIOD_MS`] of its clock: the first [`TRACK_POINTS_KEPT`].
    pub track: Vec<(u32, DVec3)>,
    /// Its last position, with its clock (ms).
    pub last_fix: Option<(u32, DVec3)>,
    /// Armed at its last heartbeat.
    pub armed: bool,
    /// Its mode at its last heartbeat (custom_mode).
    pub mode: Option<u32>,
    /// Every mode it entered, in order, with its clock then (ms; of the last position).
    pub modes: Vec<(u32, u32)>,
    /// COLLISION messages it sent.
    pub collision_messages: u64,
    /// Its clock (ms) at the first COLLISION message.
    pub first_collision_ms: Option<u32>,
    /// The last [`RECENT_TEXTS`] STATUSTEXTs: its clock (ms), severity, text (what an error
    /// message quotes).
    pub recent_texts: std::collections::VecDeque<(u32, u8, String)>,
    /// Its STATUSTEXTs about avoidance (avoid, ADS-B, proximity, obstacle, fence), in order,
    /// repeats of the one before left out: the first [`AVOIDANCE_TEXTS_KEPT`].
    pub avoidance_texts: Vec<String>,
    /// Avoidance STATUSTEXTs past those, counted.
    pub avoidance_texts_not_kept: u64,
    /// The last avoidance STATUSTEXT heard, kept or not (a repeat of it is left out).
    last_avoidance_text: String,
    /// AUTOPILOT_VERSION: `major.minor.patch (git hash)`.
    pub version: Option<String>,
    /// Its clock at the last position, ms.
    pub time_boot_ms: u32,
    /// When the last position came (wall clock).
    pub position_at: Option<Instant>,
    /// Its clock (ms) in its last message that carries it (a position, with or without a
    /// fix, or an attitude), and when that came (wall clock).
    pub clock: Option<(u32, Instant)>,
    /// PARAM_VALUE: the last value and type heard of each parameter, by name (one entry a
    /// name: as many as the autopilot has parameters).
    pub params: std::collections::HashMap<String, (f32, u8)>,
}

/// The vehicle's clock between two points of [`Heard::track`], ms.
pub const TRACK_PERIOD_MS: u32 = 500;
/// The most points [`Heard::track`] keeps (two hours at [`TRACK_PERIOD_MS`]).
pub const TRACK_POINTS_KEPT: usize = 14_400;

/// How many of the last STATUSTEXTs [`Heard`] keeps.
pub const RECENT_TEXTS: usize = 20;
/// How many avoidance STATUSTEXTs [`Heard`] keeps (the rest are counted).
pub const AVOIDANCE_TEXTS_KEPT: usize = 100;

/// Whether a STATUSTEXT is about avoidance: avoid, ADS-B, proximity, obstacle or fence.
fn about_avoidance(text: &str) -> bool {
    let t = text.to_ascii_lowercase();
    ["avoid", "adsb", "proximity", "obstacle", "fence"]
        .iter()
        .any(|w| t.contains(w))
}

/// What the reader thread passes on.
pub enum News {
    /// A position.
    Fix(Fix),
    /// Anything else that changed [`Heard`].
    Other,
}

/// Why the pilot stopped short of its plan.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PilotError {
    /// The autopilot's port never answered.
    #[error("the autopilot's port {port} never answered within {waited_s:.0} s: {why}")]
    NoPort {
        /// The TCP port.
        port: u16,
        /// Wall seconds waited.
        waited_s: f64,
        /// The last connection error.
        why: String,
    },
    /// The autopilot sent nothing for too long (it hung or died).
    #[error("the autopilot sent no position for {silent_s:.0} s of wall time")]
    Silent {
        /// Wall seconds of silence.
        silent_s: f64,
    },
    /// It would not arm.
    #[error("the autopilot did not arm within {waited_s:.0} s of its clock; it said: {texts}")]
    NoArm {
        /// Vehicle seconds waited.
        waited_s: f64,
        /// Its last messages.
        texts: String,
    },
    /// Writing to its port failed.
    #[error("sending to the autopilot failed: {0}")]
    Send(String),
    /// A parameter could not be set.
    #[error("parameter {name}: {why}")]
    Param {
        /// Its name.
        name: String,
        /// Why.
        why: String,
    },
}

/// How the pilot reaches the autopilot: a TCP connection (ArduCopter SITL's SERIAL1) or a UDP
/// socket and the autopilot's address (PX4's onboard link).
enum Wire {
    Tcp(TcpStream),
    Udp(UdpSocket, SocketAddr),
}

/// The pilot's side of the link: the writer; the reader thread feeds `fixes`.
pub struct Pilot {
    wire: Wire,
    outbox: Outbox,
    target: SenderId,
    /// Positions (and other news) from the reader thread.
    news: Receiver<News>,
    /// What the autopilot said.
    pub heard: std::sync::Arc<std::sync::Mutex<Heard>>,
    /// The last position.
    pub fix: Option<Fix>,
    last_heartbeat_ms: Option<u32>,
    /// How long the autopilot may be silent before the row is an error (wall clock).
    pub silence_limit: Duration,
    /// The row's clock when it is not this vehicle's own ([`Fix::row_s`]).
    pub row_clock: Option<RowClock>,
    /// The row's clock less the vehicle's at the last position, seconds (0 on its own).
    pub row_offset_s: f64,
    /// An ArduCopter's speedup kept to another vehicle's clock (`SIM_SPEEDUP`).
    pub pace: Option<crate::study::pace::Pace>,
}

impl Pilot {
    /// Connect to the autopilot `target` on TCP `port` of 127.0.0.1, retrying for `within`
    /// (SITL opens its ports a moment after it starts); positions are mapped into `plane`.
    pub fn connect(
        port: u16,
        target: SenderId,
        plane: LocalTangentPlane,
        within: Duration,
    ) -> Result<Pilot, PilotError> {
        let started = Instant::now();
        let stream = loop {
            match TcpStream::connect(("127.0.0.1", port)) {
                Ok(s) => break s,
                Err(e) if started.elapsed() >= within => {
                    return Err(PilotError::NoPort {
                        port,
                        waited_s: within.as_secs_f64(),
                        why: e.to_string(),
                    })
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let _ = stream.set_nodelay(true);
        let reader = stream
            .try_clone()
            .map_err(|e| PilotError::Send(e.to_string()))?;
        Self::with_reader(Wire::Tcp(stream), target, move |into, tx| {
            let mut reader = mavlink::MavlinkReader::new(reader);
            loop {
                match reader.read_any_message::<MavMessage>() {
                    Ok((h, m)) => {
                        if !pass_on(h, m, target, &plane, into, tx) {
                            return;
                        }
                    }
                    Err(mavlink::error::MessageReadError::Io(_)) => return,
                    Err(_) => {}
                }
            }
        })
    }

    /// The pilot on UDP: bound to 127.0.0.1:`bind_port` (retried for five seconds), sending
    /// to 127.0.0.1:`to_port` (PX4's onboard link sends to the one and listens on the other).
    pub fn udp(
        bind_port: u16,
        to_port: u16,
        target: SenderId,
        plane: LocalTangentPlane,
    ) -> Result<Pilot, PilotError> {
        let started = Instant::now();
        let socket = loop {
            match bind_reusable(bind_port) {
                Ok(s) => break s,
                Err(e) if started.elapsed() > Duration::from_secs(5) => {
                    return Err(PilotError::NoPort {
                        port: bind_port,
                        waited_s: 5.0,
                        why: e.to_string(),
                    })
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let err = |e: std::io::Error| PilotError::Send(e.to_string());
        socket
            .set_read_timeout(Some(Duration::from_millis(200)))
            .map_err(err)?;
        let reader = socket.try_clone().map_err(err)?;
        let to = SocketAddr::from(([127, 0, 0, 1], to_port));
        Self::with_reader(Wire::Udp(socket, to), target, move |into, tx| {
            let mut buffer = [0u8; 4096];
            loop {
                // Nobody holds the pilot any more: stop reading (and free the port).
                if std::sync::Arc::strong_count(into) == 1 {
                    return;
                }
                let n = match reader.recv(&mut buffer) {
                    Ok(n) => n,
                    Err(e) if is_timeout(&e) => continue,
                    Err(_) => return,
                };
                let mut datagram = mavlink::MavlinkReader::new(&buffer[..n]);
                while let Ok((h, m)) = datagram.read_any_message::<MavMessage>() {
                    if !pass_on(h, m, target, &plane, into, tx) {
                        return;
                    }
                }
            }
        })
    }

    /// A pilot writing to `wire`, its reader thread running `read`.
    fn with_reader(
        wire: Wire,
        target: SenderId,
        read: impl FnOnce(&Shared, &std::sync::mpsc::SyncSender<News>) + Send + 'static,
    ) -> Result<Pilot, PilotError> {
        let heard = std::sync::Arc::new(std::sync::Mutex::new(Heard::default()));
        // Bounded: a pilot that falls behind holds the reader back (TCP then holds SITL's).
        let (tx, news) = std::sync::mpsc::sync_channel(1024);
        let into = heard.clone();
        std::thread::Builder::new()
            .name("savsim-pilot".into())
            .spawn(move || read(&into, &tx))
            .map_err(|e| PilotError::Send(e.to_string()))?;
        Ok(Pilot {
            wire,
            outbox: Outbox::new(PILOT),
            target,
            news,
            heard,
            fix: None,
            last_heartbeat_ms: None,
            silence_limit: Duration::from_secs(30),
            row_clock: None,
            row_offset_s: 0.0,
            pace: None,
        })
    }

    /// The autopilot's mode and whether it is armed, at its last heartbeat.
    pub fn state(&self) -> (Option<u32>, bool) {
        self.heard
            .lock()
            .map(|h| (h.mode, h.armed))
            .unwrap_or((None, false))
    }

    /// A copy of what the autopilot said.
    pub fn heard(&self) -> Heard {
        self.heard.lock().map(|h| h.clone()).unwrap_or_default()
    }

    /// Send `message` to the autopilot.
    pub fn send(&mut self, message: &MavMessage) -> Result<(), PilotError> {
        let bytes = self.outbox.encode(message);
        let sent = match &mut self.wire {
            Wire::Tcp(stream) => stream.write_all(&bytes),
            Wire::Udp(socket, to) => socket.send_to(&bytes, *to).map(|_| ()),
        };
        sent.map_err(|e| PilotError::Send(e.to_string()))
    }

    /// COMMAND_LONG `command` with `p` to the autopilot.
    pub fn command(&mut self, command: MavCmd, p: [f32; 7]) -> Result<(), PilotError> {
        self.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: p[0],
            param2: p[1],
            param3: p[2],
            param4: p[3],
            param5: p[4],
            param6: p[5],
            param7: p[6],
            command,
            target_system: self.target.system_id,
            target_component: self.target.component_id,
            confirmation: 0,
        }))
    }

    /// Wait for the next position, answering with a heartbeat once a second of the vehicle's
    /// clock; an error when the autopilot sends nothing for `silence_limit` of wall time.
    /// `Ok(None)`: `stop` was set.
    pub fn next_fix(&mut self, stop: &dyn Fn() -> bool) -> Result<Option<Fix>, PilotError> {
        let mut started = Instant::now();
        let mut asked = started;
        loop {
            if stop() {
                return Ok(None);
            }
            match self.news.recv_timeout(Duration::from_millis(50)) {
                Ok(News::Fix(mut fix)) => {
                    if let Some(clock) = &self.row_clock {
                        // Before the row's first vehicle is heard its clock is at its start.
                        fix.row_s = clock.now_s().unwrap_or(0.0);
                        self.row_offset_s = fix.row_s - f64::from(fix.time_boot_ms) / 1000.0;
                    }
                    self.fix = Some(fix);
                    self.heartbeat_due(fix.time_boot_ms)?;
                    self.keep_pace()?;
                    return Ok(Some(fix));
                }
                // Anything heard: not silent (before its GPS fix it sends no position).
                Ok(News::Other) => {
                    started = Instant::now();
                    self.keep_pace()?;
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(PilotError::Silent {
                        silent_s: started.elapsed().as_secs_f64(),
                    })
                }
            }
            if started.elapsed() > self.silence_limit {
                return Err(PilotError::Silent {
                    silent_s: started.elapsed().as_secs_f64(),
                });
            }
            if self.fix.is_none() && asked.elapsed() > Duration::from_secs(1) {
                // Before the first position: keep asking for them, once a wall second.
                asked = Instant::now();
                self.ask_positions()?;
            }
        }
    }

    /// Ask for positions at [`POSITION_HZ`] and for AUTOPILOT_VERSION; send a heartbeat.
    pub fn ask_positions(&mut self) -> Result<(), PilotError> {
        self.heartbeat()?;
        let interval_us = (1e6 / POSITION_HZ) as f32;
        self.command(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [33.0, interval_us, 0.0, 0.0, 0.0, 0.0, 0.0],
        )?;
        self.command(
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        )
    }

    /// Ask SITL for the speedup the pace calls for, if one is due.
    fn keep_pace(&mut self) -> Result<(), PilotError> {
        let Some(pace) = self.pace.as_mut() else {
            return Ok(());
        };
        let own = self.heard.lock().ok().and_then(|h| h.clock);
        let Some(speedup) = own.and_then(|own| pace.at(own, Instant::now())) else {
            return Ok(());
        };
        let (target_system, target_component) = (self.target.system_id, self.target.component_id);
        self.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: speedup as f32,
            target_system,
            target_component,
            param_id: "SIM_SPEEDUP".into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }))
    }

    fn heartbeat_due(&mut self, now_ms: u32) -> Result<(), PilotError> {
        let due = self
            .last_heartbeat_ms
            .is_none_or(|last| now_ms.wrapping_sub(last) >= 1000);
        if due {
            self.last_heartbeat_ms = Some(now_ms);
            self.heartbeat()?;
        }
        Ok(())
    }

    fn heartbeat(&mut self) -> Result<(), PilotError> {
        self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_GCS,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }))
    }

    /// A velocity target, scene ENU m/s (GUIDED; re-sent at every position: ArduCopter drops a
    /// velocity target after 3 s).
    pub fn velocity(&mut self, enu_mps: DVec3) -> Result<(), PilotError> {
        // Velocities only: position, acceleration, yaw and yaw rate ignored.
        let velocity_only = 0b0000_1101_1100_0111;
        self.send(&MavMessage::SET_POSITION_TARGET_LOCAL_NED(
            SET_POSITION_TARGET_LOCAL_NED_DATA {
                time_boot_ms: 0,
                x: 0.0,
                y: 0.0,
                z: 0.0,
                vx: enu_mps.y as f32,
                vy: enu_mps.x as f32,
                vz: -enu_mps.z as f32,
                afx: 0.0,
                afy: 0.0,
                afz: 0.0,
                yaw: 0.0,
                yaw_rate: 0.0,
                type_mask: PositionTargetTypemask::from_bits_truncate(velocity_only),
                target_system: self.target.system_id,
                target_component: self.target.component_id,
                coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            },
        ))
    }
}

impl Pilot {
    /// PX4's parameter `name` as last heard: its value (as PX4 encodes it: an integer's bits in
    /// the float) and MAV_PARAM_TYPE.
    fn param_heard(&self, name: &str) -> Option<(f32, u8)> {
        let heard = self.heard.lock().ok()?;
        heard.params.get(name).copied()
    }

    /// Forget what was heard of parameter `name`, then send `set` (PARAM_SET: its value on the
    /// wire and type) or, without it, PARAM_REQUEST_READ: the next PARAM_VALUE of `name` heard
    /// is the answer, never an older one.
    fn ask_param(
        &mut self,
        name: &str,
        set: Option<(f32, MavParamType)>,
    ) -> Result<(), PilotError> {
        if let Ok(mut heard) = self.heard.lock() {
            heard.params.remove(name);
        }
        let (target_system, target_component) = (self.target.system_id, self.target.component_id);
        self.send(&match set {
            Some((param_value, param_type)) => MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value,
                target_system,
                target_component,
                param_id: name.into(),
                param_type,
            }),
            None => MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: -1,
                target_system,
                target_component,
                param_id: name.into(),
            }),
        })
    }

    /// Ask for parameter `name` and wait (on the vehicle's clock, at most `within_s`) for its
    /// value and type.
    pub fn read_param(
        &mut self,
        name: &str,
        within_s: f64,
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<(f32, u8)>, PilotError> {
        let asked_ms = self.fix.map_or(0, |f| f.time_boot_ms);
        self.ask_param(name, None)?;
        while let Some(fix) = self.next_fix(stop)? {
            if let Some(v) = self.param_heard(name) {
                return Ok(Some(v));
            }
            if f64::from(fix.time_boot_ms.wrapping_sub(asked_ms)) / 1000.0 > within_s {
                return Ok(None);
            }
        }
        Ok(None)
    }

    /// Set PX4 parameter `name` to `value` in its own type (read first; an integer's bits travel
    /// in the float, as PX4 encodes them) and wait for PX4 to echo it. An error when PX4 does
    /// not know the parameter or does not take the value.
    pub fn set_param(
        &mut self,
        name: &str,
        value: f64,
        stop: &dyn Fn() -> bool,
    ) -> Result<(), PilotError> {
        let refused = |why: &str| PilotError::Param {
            name: name.to_owned(),
            why: why.to_owned(),
        };
        let Some((_, kind)) = self.read_param(name, 5.0, stop)? else {
            return Err(refused("PX4 did not answer for it (no such parameter?)"));
        };
        let (wire, param_type) = param_on_wire(value, kind);
        for _ in 0..3 {
            self.ask_param(name, Some((wire, param_type)))?;
            let Some((now, _)) = self.read_param(name, 2.0, stop)? else {
                continue;
            };
            if now.to_bits() == wire.to_bits() {
                return Ok(());
            }
        }
        Err(refused(&format!("PX4 did not take {value}")))
    }

    /// Set parameter `name` (its type read first) before the autopilot sends positions,
    /// waiting on the wall clock (at most `within` for each answer): for set-up before the
    /// row's flight, e.g. PX4 SIH's home altitude.
    pub fn set_param_before_flight(
        &mut self,
        name: &str,
        value: f64,
        within: Duration,
    ) -> Result<(), PilotError> {
        let refused = |why: String| PilotError::Param {
            name: name.to_owned(),
            why,
        };
        let ask = |pilot: &mut Pilot, set: Option<(f32, MavParamType)>| {
            pilot.ask_param(name, set)?;
            let started = Instant::now();
            while started.elapsed() < within {
                if let Some(v) = pilot.param_heard(name) {
                    return Ok(Some(v));
                }
                let _ = pilot.news.recv_timeout(Duration::from_millis(50));
            }
            Ok::<_, PilotError>(None)
        };
        let mut answer = None;
        for _ in 0..20 {
            answer = ask(self, None)?;
            if answer.is_some() {
                break;
            }
        }
        let Some((_, kind)) = answer else {
            return Err(refused("the autopilot did not answer for it".into()));
        };
        let (wire, param_type) = param_on_wire(value, kind);
        match ask(self, Some((wire, param_type)))? {
            Some((now, _)) if now.to_bits() == wire.to_bits() => Ok(()),
            _ => Err(refused(format!("the autopilot did not take {value}"))),
        }
    }

    /// MANUAL_CONTROL: pitch (`forward`), roll (`right`) and throttle (`up`), each -1..1
    /// (throttle centred at 0), no yaw; PX4's joystick input (COM_RC_IN_MODE).
    pub fn sticks(&mut self, forward: f64, right: f64, up: f64) -> Result<(), PilotError> {
        let axis = |v: f64| (v.clamp(-1.0, 1.0) * 1000.0).round() as i16;
        self.send(&MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA {
            x: axis(forward),
            y: axis(right),
            z: ((up.clamp(-1.0, 1.0) + 1.0) * 500.0).round() as i16,
            r: 0,
            buttons: 0,
            target: self.target.system_id,
            ..MANUAL_CONTROL_DATA::default()
        }))
    }
}

/// `value` as PARAM_SET carries it for a parameter of MAV_PARAM_TYPE `kind`: an INT32's bits
/// in the float (PX4 encodes parameters bytewise), anything else as a REAL32.
fn param_on_wire(value: f64, kind: u8) -> (f32, MavParamType) {
    if kind == MavParamType::MAV_PARAM_TYPE_INT32 as u8 {
        (
            f32::from_bits(value.round() as i32 as u32),
            MavParamType::MAV_PARAM_TYPE_INT32,
        )
    } else {
        (value as f32, MavParamType::MAV_PARAM_TYPE_REAL32)
    }
}

/// The stick (-1..1) that makes PX4's Position mode ask for `fraction` (-1..1) of its
/// maximum, through its deadzone `dz` (MPC_HOLD_DZ) and expo `e` (MPC_XY_MAN_EXPO):
/// PX4 maps a stick `s` to `expo(deadzone(s))`, `deadzone(s) = (|s| - dz) / (1 - dz)`,
/// `expo(u) = (1 - e) u + e u^3`; this inverts it (Newton on the cubic).
///
/// ```
/// use savsim::study::pilot::stick_for;
/// let s = stick_for(0.5, 0.1, 0.6);
/// let u = (s - 0.1) / 0.9;
/// assert!(((1.0 - 0.6) * u + 0.6 * u * u * u - 0.5).abs() < 1e-9);
/// assert_eq!(stick_for(0.0, 0.1, 0.6), 0.0);
/// ```
pub fn stick_for(fraction: f64, dz: f64, e: f64) -> f64 {
    let f = fraction.clamp(-1.0, 1.0);
    if f == 0.0 {
        return 0.0;
    }
    let target = f.abs();
    let mut u = target;
    for _ in 0..50 {
        let value = (1.0 - e) * u + e * u * u * u - target;
        let slope = (1.0 - e) + 3.0 * e * u * u;
        if slope.abs() < 1e-12 {
            break;
        }
        u = (u - value / slope).clamp(0.0, 1.0);
    }
    f.signum() * (u * (1.0 - dz) + dz).min(1.0)
}

/// The velocity a `goto` commands from `at` towards `to` at `speed_mps`, slowing within two
/// seconds of the point (at most half the distance per second), scene ENU m/s.
///
/// ```
/// use glam::DVec3;
/// let v = savsim::study::pilot::goto_velocity(DVec3::ZERO, DVec3::new(100.0, 0.0, 0.0), 5.0);
/// assert_eq!(v, DVec3::new(5.0, 0.0, 0.0));
/// let near = savsim::study::pilot::goto_velocity(DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0), 5.0);
/// assert_eq!(near, DVec3::new(1.0, 0.0, 0.0));
/// ```
pub fn goto_velocity(at: DVec3, to: DVec3, speed_mps: f64) -> DVec3 {
    let away = to - at;
    let distance = away.length();
    if distance < 1e-6 {
        return DVec3::ZERO;
    }
    away / distance * speed_mps.min(0.5 * distance)
}

/// Whether `leg` is done at `fix`, given where and when it began (a takeoff's height is
/// above where it began: home).
pub fn leg_done(leg: &Leg, fix: &Fix, began: &Fix, armed: bool) -> bool {
    let elapsed_s = f64::from(fix.time_boot_ms.wrapping_sub(began.time_boot_ms)) / 1000.0;
    match *leg {
        Leg::Takeoff { up_m } => fix.enu_m.z - began.enu_m.z >= up_m - TAKEOFF_DONE_M,
        Leg::Goto { enu_m, .. } => fix.enu_m.distance(DVec3::from(enu_m)) <= GOTO_DONE_M,
        Leg::Velocity { seconds, .. } | Leg::Hold { seconds } => elapsed_s >= seconds,
        Leg::Until { t_s } => fix.row_s >= t_s,
        Leg::Land => !armed && elapsed_s > 1.0,
    }
}

/// A UDP socket on 127.0.0.1:`port` with SO_REUSEADDR, so that a row's pilot can bind the
/// port the last row's pilot had while that one's reader thread lets go of it.
fn bind_reusable(port: u16) -> std::io::Result<UdpSocket> {
    let address = SocketAddr::from(([127, 0, 0, 1], port));
    let socket = socket2::Socket::new(
        socket2::Domain::IPV4,
        socket2::Type::DGRAM,
        Some(socket2::Protocol::UDP),
    )?;
    socket.set_reuse_address(true)?;
    socket.bind(&address.into())?;
    Ok(socket.into())
}

/// What the pilot and its reader thread share.
type Shared = std::sync::Arc<std::sync::Mutex<Heard>>;

fn is_timeout(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
    )
}

/// One message from the autopilot's link: from `target` into `heard`, positions (in `plane`)
/// also to `tx`. False when the pilot is gone.
fn pass_on(
    header: mavlink::MavHeader,
    message: MavMessage,
    target: SenderId,
    plane: &LocalTangentPlane,
    heard: &std::sync::Mutex<Heard>,
    tx: &std::sync::mpsc::SyncSender<News>,
) -> bool {
    if header.system_id != u32::from(target.system_id) {
        return true;
    }
    let clock_ms = match &message {
        MavMessage::GLOBAL_POSITION_INT(p) => Some(p.time_boot_ms),
        MavMessage::ATTITUDE(a) => Some(a.time_boot_ms),
        _ => None,
    };
    if let Some(ms) = clock_ms.filter(|_| header.component_id == target.component_id) {
        if let Ok(mut h) = heard.lock() {
            h.clock = Some((ms, Instant::now()));
        }
    }
    let news = match message {
        // ArduPilot sends 0, 0 until its EKF has an origin: no position yet.
        MavMessage::GLOBAL_POSITION_INT(p)
            if header.component_id == target.component_id && (p.lat, p.lon) != (0, 0) =>
        {
            let at = Geodetic::new(
                f64::from(p.lat) * 1e-7,
                f64::from(p.lon) * 1e-7,
                f64::from(p.alt) * 1e-3,
            );
            let ned = DVec3::new(f64::from(p.vx), f64::from(p.vy), f64::from(p.vz)) * 0.01;
            let enu_m = plane.enu_m_from_geodetic(&at);
            if let Ok(mut h) = heard.lock() {
                h.time_boot_ms = p.time_boot_ms;
                h.position_at = Some(Instant::now());
                h.take_position(p.time_boot_ms, enu_m);
            }
            News::Fix(Fix {
                time_boot_ms: p.time_boot_ms,
                enu_m,
                velocity_enu_mps: DVec3::new(ned.y, ned.x, -ned.z),
                heading_deg: (p.hdg != u16::MAX).then(|| f64::from(p.hdg) / 100.0),
                row_s: f64::from(p.time_boot_ms) / 1000.0,
            })
        }
        other => {
            if let Ok(mut h) = heard.lock() {
                hear(&mut h, header.component_id == target.component_id, other);
            }
            News::Other
        }
    };
    tx.send(news).is_ok()
}

impl Heard {
    /// Take a position at `ms` of the vehicle's clock: the last, and into the track when
    /// [`TRACK_PERIOD_MS`] have passed since its last point.
    pub fn take_position(&mut self, ms: u32, enu_m: DVec3) {
        self.last_fix = Some((ms, enu_m));
        let due = self
            .track
            .last()
            .is_none_or(|(t, _)| ms >= t.saturating_add(TRACK_PERIOD_MS));
        if due && self.track.len() < TRACK_POINTS_KEPT {
            self.track.push((ms, enu_m));
        }
    }

    /// The track and the last position as waypoints in the text an intruder's track is
    /// given in (`t_s e_m n_m u_m; ...`, seconds of the vehicle's clock, decimetres); `None`
    /// when no position was heard.
    ///
    /// ```
    /// use glam::DVec3;
    /// let mut heard = savsim::study::pilot::Heard::default();
    /// assert_eq!(heard.track_text(), None);
    /// for (ms, e) in [(1000, 0.0), (1200, 1.0), (1500, 2.5), (1700, 3.0)] {
    ///     heard.take_position(ms, DVec3::new(e, 10.0, 20.0));
    /// }
    /// assert_eq!(heard.track_text().unwrap(), "1.000 0.0 10.0 20.0; 1.500 2.5 10.0 20.0; 1.700 3.0 10.0 20.0");
    /// ```
    pub fn track_text(&self) -> Option<String> {
        self.track_text_shifted(0.0)
    }

    /// [`Heard::track_text`] with `offset_s` added to every time (onto the row's clock).
    pub fn track_text_shifted(&self, offset_s: f64) -> Option<String> {
        let last = self.last_fix?;
        let mut points = self.track.clone();
        if points.last().is_none_or(|(t, _)| *t < last.0) {
            points.push(last);
        }
        let one = |(ms, p): &(u32, DVec3)| {
            format!(
                "{:.3} {:.1} {:.1} {:.1}",
                f64::from(*ms) / 1000.0 + offset_s,
                p.x,
                p.y,
                p.z
            )
        };
        Some(points.iter().map(one).collect::<Vec<_>>().join("; "))
    }
}

/// Take one message other than a position into `heard`.
fn hear(heard: &mut Heard, from_autopilot: bool, message: MavMessage) {
    let now = heard.time_boot_ms;
    match message {
        MavMessage::HEARTBEAT(hb) if from_autopilot => {
            heard.armed = hb
                .base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
            if heard.mode != Some(hb.custom_mode) {
                heard.mode = Some(hb.custom_mode);
                heard.modes.push((now, hb.custom_mode));
            }
        }
        MavMessage::COLLISION(_) => {
            heard.collision_messages += 1;
            heard.first_collision_ms.get_or_insert(now);
        }
        MavMessage::STATUSTEXT(t) => {
            let text = t
                .text
                .to_str()
                .unwrap_or("?")
                .trim_end_matches('\0')
                .to_owned();
            if about_avoidance(&text) && heard.last_avoidance_text != text {
                if heard.avoidance_texts.len() < AVOIDANCE_TEXTS_KEPT {
                    heard.avoidance_texts.push(text.clone());
                } else {
                    heard.avoidance_texts_not_kept += 1;
                }
                heard.last_avoidance_text.clone_from(&text);
            }
            if heard.recent_texts.len() == RECENT_TEXTS {
                heard.recent_texts.pop_front();
            }
            heard.recent_texts.push_back((now, t.severity as u8, text));
        }
        MavMessage::PARAM_VALUE(v) => {
            let name = v.param_id.to_str().unwrap_or("").trim_end_matches('\0');
            heard
                .params
                .insert(name.to_owned(), (v.param_value, v.param_type as u8));
        }
        MavMessage::AUTOPILOT_VERSION(v) => {
            let s = v.flight_sw_version;
            let hash: String = v
                .flight_custom_version
                .iter()
                .take_while(|b| **b != 0)
                .map(|b| char::from(*b))
                .collect();
            heard.version = Some(format!(
                "{}.{}.{} ({hash})",
                s >> 24,
                (s >> 16) & 0xff,
                (s >> 8) & 0xff
            ));
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{MavSeverity, STATUSTEXT_DATA};

    fn text(t: &str) -> MavMessage {
        let mut data = STATUSTEXT_DATA {
            severity: MavSeverity::MAV_SEVERITY_INFO,
            ..STATUSTEXT_DATA::default()
        };
        data.text = t.into();
        MavMessage::STATUSTEXT(data)
    }

    /// What the pilot keeps of an autopilot that talks without end: the last texts for error
    /// messages, the first avoidance texts and a count of the rest; nothing grows with time.
    #[test]
    fn texts_heard_for_ever_are_kept_bounded_and_the_rest_counted() {
        let mut heard = Heard::default();
        for k in 0..5000 {
            heard.time_boot_ms = k;
            hear(&mut heard, true, text(&format!("ADSB: avoiding {k}")));
            hear(&mut heard, true, text("ADSB: avoiding the same"));
            hear(&mut heard, true, text("ADSB: avoiding the same"));
            hear(&mut heard, true, text(&format!("battery {k}")));
        }
        assert_eq!(heard.avoidance_texts.len(), AVOIDANCE_TEXTS_KEPT);
        assert_eq!(heard.avoidance_texts[0], "ADSB: avoiding 0");
        assert_eq!(heard.avoidance_texts[1], "ADSB: avoiding the same");
        // Each round adds two avoidance texts (the repeat of the same one is left out).
        assert_eq!(
            heard.avoidance_texts_not_kept,
            2 * 5000 - AVOIDANCE_TEXTS_KEPT as u64
        );
        assert_eq!(heard.recent_texts.len(), RECENT_TEXTS);
        assert_eq!(heard.recent_texts.back().unwrap().2, "battery 4999");
    }
}

//! The study's pilot: a ground station on the autopilot's second serial port (ArduCopter
//! SITL's SERIAL1, TCP) that arms the vehicle and flies a row's plan, and hears what the
//! autopilot does (modes, COLLISION, STATUSTEXT, its version).
//!
//! - here: the link (connect, send, commands, positions, velocity targets and sticks) and the
//!   reader thread;
//! - [`lockstep`]: the pilot in savsim's lockstep loop (no socket: the loop hands it what
//!   the autopilot said and sends what it queues);
//! - [`heard`]: what the reader thread keeps of what the autopilot said, and the row's clock;
//! - [`params`]: reading and setting parameters;
//! - [`fly`]: the plan, leg by leg; [`pace`]: an ArduCopter's speedup kept to another clock.
//!
//! Every decision is taken on the vehicle's own clock: the pilot acts at each
//! GLOBAL_POSITION_INT the vehicle sends (asked at [`POSITION_HZ`] of its clock), so a row
//! flies the same at any speedup. Targets are velocities (GUIDED's velocity targets are what
//! ArduCopter's proximity avoidance acts on, docs/closed-loop.md), re-sent at every position.

pub mod fly;
pub mod heard;
mod lockstep;
pub mod pace;
mod params;

use std::io::Write;
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{
    MavCmd, MavFrame, MavMessage, MavParamType, PositionTargetTypemask, COMMAND_LONG_DATA,
    MANUAL_CONTROL_DATA, PARAM_SET_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};

use crate::codec::outbox::{gcs_heartbeat, Outbox};
use crate::geo::{Geodetic, LocalTangentPlane};
use crate::world::SenderId;
use heard::{hear, Fix, Heard, News, RowClock};

/// Positions asked for on the pilot's link, Hz of the vehicle's clock.
pub const POSITION_HZ: f64 = 20.0;
/// The pilot's identity: a ground station's system, a component no common GCS uses
/// (MAV_COMP_ID_USER1).
pub const PILOT: SenderId = SenderId {
    system_id: 254,
    component_id: 25,
};

/// ArduCopter's flight modes (custom_mode) that a study reads.
pub mod mode {
    /// GUIDED.
    pub const GUIDED: u32 = 4;
    /// LAND.
    pub const LAND: u32 = 9;
    /// AVOID_ADSB.
    pub const AVOID_ADSB: u32 = 19;
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
    /// In lockstep: frames queued for savsim's physics loop to send while the autopilot waits.
    Queue(std::sync::Arc<std::sync::Mutex<Vec<Vec<u8>>>>),
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
    pub pace: Option<crate::study::pilot::pace::Pace>,
    /// In lockstep: the turn-taking with savsim's physics loop, and the news taken so far.
    gate: Option<(std::sync::Arc<crate::lockstep::gate::Gate>, u64)>,
    /// In lockstep: when positions were last asked for (the row's clock, ms).
    asked_ms: Option<u32>,
    /// With a companion: the plan's velocity goes here for the companion's frames instead of
    /// to the autopilot (the companion flies; the pilot arms, takes off and lands).
    pub companion_intent: Option<std::sync::Arc<std::sync::Mutex<Option<DVec3>>>>,
}

impl Drop for Pilot {
    fn drop(&mut self) {
        if let Some((gate, _)) = &self.gate {
            gate.close();
        }
    }
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
                        if pass_on(h, m, target, &plane, into, tx) == Passed::Gone {
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
                    if pass_on(h, m, target, &plane, into, tx) == Passed::Gone {
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
        Ok(Pilot::new(wire, target, news, heard, None))
    }

    /// A pilot writing to `wire` for `target`, its news from `news`, what it heard in `heard`;
    /// `gate` in lockstep.
    fn new(
        wire: Wire,
        target: SenderId,
        news: Receiver<News>,
        heard: Shared,
        gate: Option<std::sync::Arc<crate::lockstep::gate::Gate>>,
    ) -> Pilot {
        Pilot {
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
            gate: gate.map(|g| (g, 0)),
            asked_ms: None,
            companion_intent: None,
        }
    }

    /// Whether it flies in lockstep ([`Pilot::lockstep`]).
    pub fn in_lockstep(&self) -> bool {
        self.gate.is_some()
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
            Wire::Queue(queue) => {
                if let Ok(mut q) = queue.lock() {
                    q.push(bytes);
                }
                Ok(())
            }
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
            match self.recv_news(Duration::from_millis(50)) {
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
                // Lockstep: positions asked for on the row's clock, once a second until one
                // comes.
                Ok(News::Tick(ms)) => {
                    started = Instant::now();
                    if self.fix.is_none()
                        && self.asked_ms.is_none_or(|a| ms.wrapping_sub(a) >= 1000)
                    {
                        self.asked_ms = Some(ms);
                        self.ask_positions()?;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                // The link is gone: the end of the row if it was stopped, else silence.
                Err(RecvTimeoutError::Disconnected) if stop() => return Ok(None),
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
            if self.gate.is_none() && self.fix.is_none() && asked.elapsed() > Duration::from_secs(1)
            {
                // Before the first position: keep asking for them, once a wall second.
                asked = Instant::now();
                self.ask_positions()?;
            }
        }
    }

    /// The next news within `wait`. In lockstep, the physics loop is told first when none is
    /// waiting, so that it moves the autopilot's clock on only once the pilot has acted on
    /// everything it was handed.
    fn recv_news(&mut self, wait: Duration) -> Result<News, RecvTimeoutError> {
        if let Some((gate, consumed)) = &mut self.gate {
            match self.news.try_recv() {
                Ok(news) => {
                    *consumed += 1;
                    return Ok(news);
                }
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    return Err(RecvTimeoutError::Disconnected)
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => gate.idle(*consumed),
            }
        }
        let news = self.news.recv_timeout(wait)?;
        if let Some((_, consumed)) = &mut self.gate {
            *consumed += 1;
        }
        Ok(news)
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
        self.send(&gcs_heartbeat())
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

/// What [`pass_on`] did with a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Passed {
    /// Not from the target: ignored.
    Ignored,
    /// Kept, and news of it sent.
    Sent,
    /// The pilot is gone.
    Gone,
}

/// One message from the autopilot's link: from `target` into `heard`, positions (in `plane`)
/// also to `tx`.
fn pass_on(
    header: mavlink::MavHeader,
    message: MavMessage,
    target: SenderId,
    plane: &LocalTangentPlane,
    heard: &std::sync::Mutex<Heard>,
    tx: &std::sync::mpsc::SyncSender<News>,
) -> Passed {
    if header.system_id != u32::from(target.system_id) {
        return Passed::Ignored;
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
    match tx.send(news) {
        Ok(()) => Passed::Sent,
        Err(_) => Passed::Gone,
    }
}

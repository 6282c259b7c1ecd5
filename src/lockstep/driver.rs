//! savsim's physics loop: every autopilot of a run waits for savsim's clock. At each step it
//! takes every autopilot's servo packet, hands what each said to the session and to its pilot,
//! waits for the pilots to act, moves every vehicle one step with its outputs, gives the world
//! the truth, sends the feed and the pilots' commands, and only then answers each autopilot
//! with its new state. What any autopilot receives therefore depends on the clock alone.

use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{MavCmd, MavMessage, COMMAND_LONG_DATA};
use savsim_core::dynamics::StepError;

use super::backend::{Backend, Outputs};
use super::estimates::EstimateErrors;
use super::port::{MavPort, PortError};
use super::surroundings::SceneSurroundings;
use super::vehicle::SimVehicle;
use crate::codec::frame::{scan, Scan};
use crate::codec::outbox::{gcs_heartbeat, Outbox};
use crate::companion::protocol::State;
use crate::companion::slot::{Slot, SlotError};
use crate::geo::LocalTangentPlane;
use crate::pipeline::{BodySource, CollisionConfig, Mode, Pipeline};
use crate::scene::Scene;
use crate::session::Session;
use crate::world::SenderId;

/// savsim's identity as the ground station of its session's ports (as `live`'s).
const GCS: SenderId = SenderId {
    system_id: 245,
    component_id: 190,
};

/// How a lockstep run steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopConfig {
    /// The physics step, microseconds.
    pub step_us: u64,
    /// The world is given the truth (and the feed is cast) every this many microseconds.
    pub truth_every_us: u64,
    /// Run no faster than this many times real time (None: as fast as the autopilots go).
    pub real_time: Option<f64>,
    /// An autopilot that sends no servo packet for this long (wall time) has hung or died.
    pub silence: Duration,
    /// End at this time of the clock, microseconds (None: when stopped).
    pub end_us: Option<u64>,
    /// End at the first collision the session reports.
    pub stop_on_collision: bool,
    /// End when the first vehicle's pilot has finished (at the step it finished on, so that
    /// the end too depends on the clock alone).
    pub end_with_first_pilot: bool,
}

/// Why a lockstep run ended short.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// An autopilot's physics port.
    #[error("{vehicle}: {source}")]
    Port {
        /// The vehicle.
        vehicle: SenderId,
        /// What happened.
        source: PortError,
    },
    /// A vehicle's dynamics refused a step.
    #[error("{vehicle}: dynamics: {source}")]
    Step {
        /// The vehicle.
        vehicle: SenderId,
        /// Why.
        source: StepError,
    },
    /// A pilot did not act on its news.
    #[error("{vehicle}: {source}")]
    Pilot {
        /// The vehicle.
        vehicle: SenderId,
        /// Why.
        source: super::gate::Stuck,
    },
    /// The session.
    #[error("{0}")]
    Session(#[from] crate::error::Error),
    /// Its companion.
    #[error("{vehicle}: {source}")]
    Companion {
        /// The vehicle.
        vehicle: SenderId,
        /// What happened.
        source: SlotError,
    },
    /// A MAVLink port.
    #[error("{vehicle}: MAVLink port: {source}")]
    Mav {
        /// The vehicle.
        vehicle: SenderId,
        /// What the system said.
        source: std::io::Error,
    },
}

/// Whoever acts on what an autopilot says on one of its ports (a study's pilot), in turn with
/// the loop: handed what the autopilot sent, it acts, and the loop waits for it to settle
/// before the autopilot's clock moves on.
pub trait Actor: Send {
    /// One datagram the autopilot sent.
    fn take(&mut self, datagram: &[u8]);
    /// A second of the clock passed (at `time_ms`).
    fn tick(&mut self, time_ms: u32);
    /// Wait, at most `limit`, until it has acted on everything it was handed.
    fn settle(&mut self, limit: Duration) -> Result<(), super::gate::Stuck>;
    /// What it sent since the last call, in order.
    fn outgoing(&mut self) -> Vec<Vec<u8>>;
    /// Whether it has finished (it acts no more).
    fn finished(&self) -> bool;
}

/// One autopilot in the loop.
pub struct Lockstepped {
    /// The vehicle savsim flies for it.
    pub vehicle: SimVehicle,
    /// Its protocol (its physics port).
    pub backend: Box<dyn Backend>,
    /// Its SERIAL0 (the session's port: its estimate in, the feed out).
    pub serial0: MavPort,
    /// Its pilot's port and the pilot, when a pilot flies it.
    pub pilot: Option<(MavPort, Box<dyn Actor>)>,
    /// Its estimate against the truth.
    pub estimates: EstimateErrors,
    /// Its companion (a user's planner), when the row has one.
    pub companion: Option<Slot>,
    outputs: Outputs,
    asked: bool,
    gcs: Outbox,
}

impl Lockstepped {
    /// `vehicle` flown for the autopilot behind `backend`, its SERIAL0 on `serial0`.
    pub fn new(vehicle: SimVehicle, backend: Box<dyn Backend>, serial0: MavPort) -> Self {
        Lockstepped {
            vehicle,
            backend,
            serial0,
            pilot: None,
            estimates: EstimateErrors::default(),
            companion: None,
            outputs: Outputs::default(),
            asked: false,
            gcs: Outbox::new(GCS),
        }
    }

    /// Wait for the autopilot's outputs for the step.
    fn take_outputs(&mut self, silence: Duration) -> Result<(), PortError> {
        self.outputs = self.backend.take_outputs(&self.vehicle, silence)?;
        Ok(())
    }
}

/// Where a lockstep run's wall time went.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LoopTimes {
    /// Steps taken.
    pub steps: u64,
    /// Waiting for the autopilots' servo packets: their own work and the sockets' round
    /// trip, seconds.
    pub autopilots_s: f64,
    /// Waiting for the pilots to act, seconds.
    pub pilots_s: f64,
    /// Waiting for the companions' answers (their planners' work and the sockets), seconds.
    pub companions_s: f64,
    /// savsim's own work: the dynamics, the world, the collision layers, the feed, the
    /// replies, seconds.
    pub savsim_s: f64,
    /// Sleeping to keep a pace ([`LoopConfig::real_time`]), seconds.
    pub paced_s: f64,
}

/// How a lockstep run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// Its clock reached the end.
    Time,
    /// The caller stopped it.
    Stopped,
    /// A vehicle collided ([`LoopConfig::stop_on_collision`]).
    Collision,
    /// The first vehicle's pilot finished ([`LoopConfig::end_with_first_pilot`]).
    PilotDone,
}

/// Run `vehicles` over `scene` in lockstep through `session` until the end of `config`'s
/// clock or `stop` (asked once a step). The clock's time reached, microseconds, and how it
/// ended; each vehicle is left as it was at the end.
pub fn run(
    vehicles: &mut [Lockstepped],
    scene: &Scene,
    session: &mut Session,
    config: &LoopConfig,
    stop: &dyn Fn(u64) -> bool,
) -> Result<(u64, Ended), LoopError> {
    let mut times = LoopTimes::default();
    run_timed(vehicles, scene, session, config, stop, &mut times)
}

/// [`run`], adding where the wall time went to `times`.
pub fn run_timed(
    vehicles: &mut [Lockstepped],
    scene: &Scene,
    session: &mut Session,
    config: &LoopConfig,
    stop: &dyn Fn(u64) -> bool,
    times: &mut LoopTimes,
) -> Result<(u64, Ended), LoopError> {
    let plane = LocalTangentPlane::new(scene.origin);
    // One pipeline of exact shapes per vehicle for its rays.
    let mut pipelines: Vec<Pipeline> = vehicles
        .iter()
        .map(|_| {
            Pipeline::new(
                scene,
                CollisionConfig {
                    mode: Mode::Exact,
                    ..CollisionConfig::default()
                },
            )
        })
        .collect();
    let mut feed = Outbox::new(crate::live::FEED_FROM);
    let (mut time_us, started) = (0u64, Instant::now());
    loop {
        if config.end_us.is_some_and(|end| time_us >= end) {
            return Ok((time_us, Ended::Time));
        }
        if stop(time_us) {
            return Ok((time_us, Ended::Stopped));
        }
        let collided = session
            .pipeline()
            .is_some_and(|p| p.totals().collisions > 0);
        if config.stop_on_collision && collided {
            return Ok((time_us, Ended::Collision));
        }
        let waited = Instant::now();
        for v in vehicles.iter_mut() {
            let vehicle = v.vehicle.id;
            v.take_outputs(config.silence)
                .map_err(|source| LoopError::Port { vehicle, source })?;
        }
        let heard = Instant::now();
        times.autopilots_s += (heard - waited).as_secs_f64();
        times.steps += 1;
        let t_s = time_us as f64 / 1e6;
        for v in vehicles.iter_mut() {
            hear(v, session, t_s, time_us)?;
        }
        for (id, estimate) in session.drain_estimates() {
            if let Some(v) = vehicles.iter_mut().find(|v| v.vehicle.id == id) {
                let enu = plane.enu_m_from_geodetic(&estimate.position);
                v.estimates.estimate(estimate.time_boot_ms, enu);
            }
        }
        let pilots = Instant::now();
        for v in vehicles.iter_mut() {
            pilots_act(v, config)?;
        }
        let acted = Instant::now();
        times.pilots_s += (acted - pilots).as_secs_f64();
        let first_done = vehicles
            .first()
            .and_then(|v| v.pilot.as_ref())
            .is_some_and(|(_, actor)| actor.finished());
        if config.end_with_first_pilot && first_done {
            return Ok((time_us, Ended::PilotDone));
        }
        time_us += config.step_us;
        for (v, pipeline) in vehicles.iter_mut().zip(&mut pipelines) {
            advance(v, scene, pipeline, config.step_us)?;
            v.estimates.truth(time_us, v.vehicle.position_enu_m());
        }
        if time_us.is_multiple_of(config.truth_every_us) {
            tell_world(vehicles, session, &plane, time_us, &mut feed)?;
        }
        let asking = Instant::now();
        companions(vehicles, session, time_us)?;
        let companions_s = asking.elapsed().as_secs_f64();
        times.companions_s += companions_s;
        for v in vehicles.iter_mut() {
            let vehicle = v.vehicle.id;
            v.backend
                .send_state(time_us, &v.vehicle)
                .map_err(|source| LoopError::Port { vehicle, source })?;
        }
        let replied = Instant::now();
        times.savsim_s += ((pilots - heard) + (replied - acted)).as_secs_f64() - companions_s;
        if let Some(speed) = config.real_time {
            let due = Duration::from_secs_f64(time_us as f64 / 1e6 / speed);
            if let Some(wait) = due.checked_sub(started.elapsed()) {
                std::thread::sleep(wait);
                times.paced_s += wait.as_secs_f64();
            }
        }
    }
}

/// Each companion: what its vehicle's devices made and was sent, handed over; at its
/// instants, its frame and commands (the loop waits for them); its commands that are due, sent
/// on the vehicle's SERIAL0.
fn companions(
    vehicles: &mut [Lockstepped],
    session: &mut Session,
    time_us: u64,
) -> Result<(), LoopError> {
    if vehicles.iter().all(|v| v.companion.is_none()) {
        return Ok(());
    }
    let inputs = session.drain_companion_inputs();
    for v in vehicles.iter_mut() {
        let vehicle = v.vehicle.id;
        let Some(slot) = v.companion.as_mut() else {
            continue;
        };
        slot.collect(&inputs.captures, &inputs.traffic);
        let body = &v.vehicle.body;
        let [roll, pitch, yaw] = body.euler_rad();
        let velocity = body.velocity_ned_mps;
        let truth = State {
            position_enu_m: v.vehicle.position_enu_m(),
            velocity_enu_mps: glam::DVec3::new(velocity.y, velocity.x, -velocity.z),
            attitude_deg: [
                roll.to_degrees(),
                pitch.to_degrees(),
                yaw.to_degrees().rem_euclid(360.0),
            ],
        };
        let estimate = v.estimates.last().map(|(ms, enu)| {
            let age_s = time_us as f64 / 1e6 - f64::from(ms) / 1000.0;
            (enu, age_s.max(0.0))
        });
        slot.at(time_us, truth, estimate)
            .map_err(|source| LoopError::Companion { vehicle, source })?;
        for bytes in slot.due(time_us) {
            v.serial0
                .send(&bytes)
                .map_err(|source| LoopError::Mav { vehicle, source })?;
        }
    }
    Ok(())
}

/// What `v`'s autopilot sent since the last step: SERIAL0's frames to the session (its
/// positions kept as its estimate), the pilot's port to the pilot; a second of the clock told
/// to the pilot.
fn hear(
    v: &mut Lockstepped,
    session: &mut Session,
    t_s: f64,
    time_us: u64,
) -> Result<(), LoopError> {
    let vehicle = v.vehicle.id;
    let mav = |source| LoopError::Mav { vehicle, source };
    let mut result = Ok(());
    v.serial0
        .drain(|datagram| {
            let mut bytes = datagram;
            loop {
                match scan(bytes) {
                    Scan::Frame(frame) => {
                        if result.is_ok() {
                            result = session.on_frame(t_s, &frame);
                        }
                        bytes = &bytes[frame.len..];
                    }
                    Scan::Garbage(n) => bytes = &bytes[n..],
                    Scan::Incomplete => break,
                }
            }
        })
        .map_err(mav)?;
    result?;
    if let Some((port, actor)) = &mut v.pilot {
        port.drain(|datagram| actor.take(datagram)).map_err(mav)?;
        if time_us.is_multiple_of(1_000_000) {
            actor.tick((time_us / 1000) as u32);
        }
    }
    Ok(())
}

/// Wait for `v`'s pilot to act on what it was handed, and send what it sent.
fn pilots_act(v: &mut Lockstepped, config: &LoopConfig) -> Result<(), LoopError> {
    let vehicle = v.vehicle.id;
    let Some((port, actor)) = &mut v.pilot else {
        return Ok(());
    };
    actor
        .settle(config.silence)
        .map_err(|source| LoopError::Pilot { vehicle, source })?;
    for bytes in actor.outgoing() {
        port.send(&bytes)
            .map_err(|source| LoopError::Mav { vehicle, source })?;
    }
    Ok(())
}

/// One step of `v`'s dynamics among the scene's obstacles.
fn advance(
    v: &mut Lockstepped,
    scene: &Scene,
    pipeline: &mut Pipeline,
    step_us: u64,
) -> Result<(), LoopError> {
    let id = v.vehicle.id;
    let own = BodySource::Vehicle {
        vehicle: u16::from(id.system_id),
        component_id: id.component_id,
    };
    let surroundings = SceneSurroundings::new(scene, pipeline, v.vehicle.home_enu_m, own);
    let outputs = v.outputs;
    v.vehicle
        .advance(
            &outputs.values,
            outputs.armed,
            &surroundings,
            step_us as f64 / 1e6,
        )
        .map_err(|source| LoopError::Step {
            vehicle: id,
            source,
        })
}

/// Give the world every vehicle's truth at `time_us`, and send the feed it casts; once a
/// second, savsim's heartbeats, and its request for each autopilot's position (its estimate).
fn tell_world(
    vehicles: &mut [Lockstepped],
    session: &mut Session,
    plane: &LocalTangentPlane,
    time_us: u64,
    feed: &mut Outbox,
) -> Result<(), LoopError> {
    let (t_s, time_ms) = (time_us as f64 / 1e6, (time_us / 1000) as u32);
    for v in vehicles.iter() {
        for report in v.vehicle.reports(plane, time_ms) {
            session.on_report(t_s, v.vehicle.id, &report)?;
        }
    }
    let second = time_us.is_multiple_of(1_000_000);
    for m in session.drain_feed() {
        if let Some(v) = vehicles.iter().find(|v| v.vehicle.id == m.to) {
            let bytes = feed.encode(&m.message);
            send(v, &bytes)?;
        }
    }
    if !second {
        return Ok(());
    }
    for v in vehicles.iter_mut() {
        if !v.serial0.heard() {
            continue;
        }
        let beat = feed.encode(&crate::feed::wire::heartbeat());
        send(v, &beat)?;
        let mut gcs = std::mem::replace(&mut v.gcs, Outbox::new(GCS));
        send(v, &gcs.encode(&gcs_heartbeat()))?;
        if !v.asked {
            v.asked = true;
            let ask = ask_positions(v.vehicle.id);
            send(v, &gcs.encode(&ask))?;
        }
        v.gcs = gcs;
    }
    Ok(())
}

fn send(v: &Lockstepped, bytes: &[u8]) -> Result<(), LoopError> {
    v.serial0.send(bytes).map_err(|source| LoopError::Mav {
        vehicle: v.vehicle.id,
        source,
    })
}

/// SET_MESSAGE_INTERVAL: GLOBAL_POSITION_INT at 10 Hz (the estimate compared with the truth).
fn ask_positions(to: SenderId) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: 33.0,
        param2: 100_000.0,
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        target_system: to.system_id,
        target_component: to.component_id,
        ..COMMAND_LONG_DATA::default()
    })
}

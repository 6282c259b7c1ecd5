//! One vehicle's companion: at each of its instants (`k / hz` of the vehicle's clock) the
//! planner is handed a frame, and its commands reach the autopilot `latency_s` of the clock
//! after the instant. In the lockstep loop ([`Slot::start`]) the loop waits for each answer,
//! so what the planner costs in wall time never moves them. Beside a vehicle in wall time
//! ([`Slot::start_beside`]) a worker waits instead: the commands go at the first step after
//! both the answer and `latency_s` have come, and an instant that finds the planner still busy
//! is skipped. Its counts go to the row's results.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DVec3;

use super::beside::{Answered, Beside};
use super::link::{CompanionError, Link};
use super::outgoing::{self, OutgoingError};
use super::protocol::{self, Command, FrameOut, State};
use crate::codec::outbox::Outbox;
use crate::feed::capture::Capture;
use crate::feed::AdsbSent;
use crate::world::SenderId;

/// A companion as a row asks for it.
#[derive(Debug, Clone, PartialEq)]
pub struct CompanionConfig {
    /// The planner's command line (run by `sh -c`).
    pub command: String,
    /// Its instants a second of the vehicle's clock.
    pub hz: f64,
    /// How long after its instant its commands reach the autopilot, seconds of the clock (its
    /// modelled compute time).
    pub latency_s: f64,
    /// How long savsim waits for one answer, wall time.
    pub timeout: Duration,
}

/// A companion's rate when none is given, Hz of the vehicle's clock.
pub const DEFAULT_HZ: f64 = 10.0;
/// How long savsim waits for one answer by default, wall time.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(10);

impl CompanionConfig {
    /// `command` at `hz` (above 0, at most 1000) with `latency_s` (0 to 10 s), waited for at
    /// most [`DEFAULT_TIMEOUT`]; or the setting that is wrong (`"hz"`, `"latency_s"`) and why.
    pub fn checked(command: &str, hz: f64, latency_s: f64) -> Result<Self, (&'static str, String)> {
        if !(hz.is_finite() && hz > 0.0 && hz <= 1000.0) {
            return Err(("hz", format!("{hz}: give more than 0 and at most 1000")));
        }
        if !(latency_s.is_finite() && (0.0..=10.0).contains(&latency_s)) {
            return Err(("latency_s", format!("{latency_s}: give 0 to 10 seconds")));
        }
        Ok(CompanionConfig {
            command: command.to_string(),
            hz,
            latency_s,
            timeout: DEFAULT_TIMEOUT,
        })
    }
}

/// What a companion did over a row.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct CompanionCounts {
    /// Frames it was handed.
    pub calls: u64,
    /// Commands it sent.
    pub commands: u64,
    /// Instants skipped because the planner was still on the last frame (wall time only).
    pub skipped: u64,
    /// Wall time of each round trip (frame out, commands back), milliseconds.
    #[serde(skip)]
    pub round_trips_ms: Vec<f64>,
}

impl CompanionCounts {
    /// The 99th percentile round trip, milliseconds (none without a call).
    pub fn p99_ms(&self) -> Option<f64> {
        let mut v = self.round_trips_ms.clone();
        v.sort_by(f64::total_cmp);
        let k = ((v.len() as f64) * 0.99).ceil() as usize;
        v.get(k.saturating_sub(1)).copied()
    }
}

/// Why the companion stopped the row.
#[derive(Debug, thiserror::Error)]
pub enum SlotError {
    /// Its link.
    #[error(transparent)]
    Link(#[from] CompanionError),
    /// A command that cannot be sent.
    #[error("companion {command:?}: frame {seq}: {why}")]
    Outgoing {
        /// The planner's command line.
        command: String,
        /// The frame answered.
        seq: u64,
        /// What is wrong.
        why: OutgoingError,
    },
}

/// The velocity the row's plan asks now (ENU m/s; none while taking off or landing): written
/// by the row's pilot, carried to the planner in each frame as `intent_enu_mps`.
pub type Intent = Arc<Mutex<Option<DVec3>>>;

/// How the planner is asked.
enum Asker {
    /// In the lockstep loop: each answer awaited.
    Waits(Link),
    /// Beside a vehicle in wall time: by a worker.
    Beside(Beside),
}

/// One vehicle's companion.
pub struct Slot {
    asker: Asker,
    command: String,
    period_us: u64,
    latency_us: u64,
    next_us: u64,
    /// The first frame of the vehicle's present life (answers to older frames are not sent).
    life_first_seq: u64,
    seq: u64,
    target: SenderId,
    px4: bool,
    outbox: Outbox,
    /// Frames to send, with when (the clock, us), in order.
    pending: VecDeque<(u64, Vec<u8>)>,
    captures: Vec<Arc<Capture>>,
    traffic: Vec<AdsbSent>,
    intent: Intent,
    /// What it did.
    pub counts: CompanionCounts,
    payload: Vec<u8>,
    message: Vec<u8>,
}

impl std::fmt::Debug for Slot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slot")
            .field("command", &self.command)
            .finish()
    }
}

impl Slot {
    /// Start `config`'s planner for vehicle `target` (its output in `dir`) and greet it with
    /// the vehicle's `devices`; the lockstep loop asks it and waits. Raising `stop` (a signal)
    /// ends the wait for it to connect.
    pub fn start(
        config: &CompanionConfig,
        (target, px4): (SenderId, bool),
        (dir, stop): (&Path, &AtomicBool),
        devices: &[String],
    ) -> Result<Slot, CompanionError> {
        let clock = protocol::Clock::Lockstep;
        let link = greeted(config, (target, px4), devices, clock, (dir, stop))?;
        let intent = Intent::default();
        Ok(Slot::new(Asker::Waits(link), config, target, px4, intent))
    }

    /// [`Slot::start`] for a vehicle flying in wall time: asked by a worker, never waited for;
    /// the pilot hands the plan's velocity to `intent`.
    pub fn start_beside(
        config: &CompanionConfig,
        (target, px4): (SenderId, bool),
        (dir, stop): (&Path, &AtomicBool),
        devices: &[String],
        intent: Intent,
    ) -> Result<Slot, CompanionError> {
        let clock = protocol::Clock::Wall;
        let link = greeted(config, (target, px4), devices, clock, (dir, stop))?;
        let beside = Beside::start(link)?;
        Ok(Slot::new(
            Asker::Beside(beside),
            config,
            target,
            px4,
            intent,
        ))
    }

    fn new(
        asker: Asker,
        config: &CompanionConfig,
        target: SenderId,
        px4: bool,
        intent: Intent,
    ) -> Slot {
        Slot {
            asker,
            command: config.command.clone(),
            period_us: (1e6 / config.hz).round().max(1.0) as u64,
            latency_us: (config.latency_s * 1e6).round() as u64,
            next_us: 0,
            life_first_seq: 0,
            seq: 0,
            target,
            px4,
            outbox: Outbox::new(outgoing::identity(target.system_id)),
            pending: VecDeque::new(),
            captures: Vec::new(),
            traffic: Vec::new(),
            intent,
            counts: CompanionCounts::default(),
            payload: Vec::new(),
            message: Vec::new(),
        }
    }

    /// Where the row's pilot puts what its plan asks now (the frames' `intent_enu_mps`).
    pub fn intent(&self) -> Intent {
        self.intent.clone()
    }

    /// Of what the run's devices made and the traffic the run sent (each with its vehicle's
    /// system id), what is this vehicle's: each device's newest reading is kept (every frame
    /// carries it, its `instant_s` saying how old it is), and every report until the next
    /// frame.
    pub fn collect(&mut self, captures: &[Arc<Capture>], traffic: &[(u8, AdsbSent)]) {
        let id = self.target.system_id;
        for c in captures.iter().filter(|c| c.system_id == id) {
            self.captures.retain(|old| old.device != c.device);
            self.captures.push(c.clone());
        }
        let told = traffic.iter().filter(|(to, _)| *to == id);
        self.traffic.extend(told.map(|(_, a)| a.clone()));
    }

    /// The vehicle rebooted: its instants start again on its new clock, and nothing asked in
    /// its last life is sent to this one (answers to its frames are counted, not sent).
    pub fn restart(&mut self) {
        self.next_us = 0;
        self.pending.clear();
        self.life_first_seq = self.seq;
    }

    /// At `time_us` of the clock: when an instant came, hand the planner its frame (and, in
    /// the lockstep loop, wait for its commands); commands answered are queued to go
    /// `latency_s` after their instant.
    pub fn at(
        &mut self,
        time_us: u64,
        truth: State,
        estimate: Option<(DVec3, f64)>,
    ) -> Result<(), SlotError> {
        self.take_answer()?;
        if time_us < self.next_us {
            return Ok(());
        }
        self.next_us = (time_us / self.period_us + 1) * self.period_us;
        if matches!(&self.asker, Asker::Beside(b) if b.busy()) {
            self.counts.skipped += 1;
            return Ok(());
        }
        let intent = self.intent.lock().map(|i| *i).unwrap_or(None);
        let frame = FrameOut {
            seq: self.seq,
            t_s: time_us as f64 / 1e6,
            truth,
            estimate,
            intent_enu_mps: intent,
            captures: &self.captures,
            traffic: &self.traffic,
        };
        protocol::frame(&frame, &mut self.payload, &mut self.message);
        self.traffic.clear();
        let seq = self.seq;
        self.seq += 1;
        match &mut self.asker {
            Asker::Waits(link) => {
                let began = Instant::now();
                let commands = link.ask(seq, &self.message)?;
                let round_trip_ms = began.elapsed().as_secs_f64() * 1e3;
                self.answered(seq, time_us, round_trip_ms, &commands)
            }
            Asker::Beside(beside) => {
                let message = std::mem::take(&mut self.message);
                Ok(beside.offer(seq, time_us, message)?)
            }
        }
    }

    /// The worker's answer, if one came: its commands queued.
    fn take_answer(&mut self) -> Result<(), SlotError> {
        let Asker::Beside(beside) = &mut self.asker else {
            return Ok(());
        };
        let Some(Answered {
            seq,
            instant_us,
            message,
            round_trip_ms,
            result,
        }) = beside.answer()?
        else {
            return Ok(());
        };
        self.message = message;
        let commands = result?;
        // An answer to a frame of the vehicle's last life is counted, not sent.
        let live = if seq < self.life_first_seq {
            &[][..]
        } else {
            &commands[..]
        };
        self.answered(seq, instant_us, round_trip_ms, live)
    }

    /// Frame `seq` of `instant_us` answered with `commands`: counted, and its commands queued
    /// to go `latency_s` after the instant.
    fn answered(
        &mut self,
        seq: u64,
        instant_us: u64,
        round_trip_ms: f64,
        commands: &[Command],
    ) -> Result<(), SlotError> {
        self.counts.round_trips_ms.push(round_trip_ms);
        self.counts.calls += 1;
        self.counts.commands += commands.len() as u64;
        let mut frames = Vec::new();
        for c in commands {
            outgoing::encode(c, self.target, self.px4, &mut self.outbox, &mut frames).map_err(
                |why| SlotError::Outgoing {
                    command: self.command.clone(),
                    seq,
                    why,
                },
            )?;
        }
        let release = instant_us + self.latency_us;
        self.pending
            .extend(frames.into_iter().map(|bytes| (release, bytes)));
        Ok(())
    }

    /// The frames due by `time_us`, in order.
    pub fn due(&mut self, time_us: u64) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        while self.pending.front().is_some_and(|(at, _)| *at <= time_us) {
            if let Some((_, bytes)) = self.pending.pop_front() {
                out.push(bytes);
            }
        }
        out
    }
}

/// `config`'s planner started, connected and greeted.
fn greeted(
    config: &CompanionConfig,
    (target, px4): (SenderId, bool),
    devices: &[String],
    clock: protocol::Clock,
    (dir, stop): (&Path, &AtomicBool),
) -> Result<Link, CompanionError> {
    let mut link = Link::start(&config.command, dir, config.timeout, stop)?;
    let hello = protocol::hello(&protocol::Hello {
        system_id: target.system_id,
        px4,
        devices,
        hz: config.hz,
        latency_s: config.latency_s,
        clock,
    });
    let mut message = Vec::new();
    protocol::message(&hello, &[], &mut message);
    link.tell(&message)?;
    Ok(link)
}

//! One vehicle's companion in the lockstep loop: at each of its instants (`k / hz` of the
//! vehicle's clock) the planner is handed a frame and the loop waits for its commands, which
//! reach the autopilot `latency_s` of the clock later; what the planner costs in wall time
//! never moves them. Its counts go to the row's results.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DVec3;

use super::link::{CompanionError, Link};
use super::outgoing::{self, OutgoingError};
use super::protocol::{self, FrameOut, State};
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

/// What a companion did over a row.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct CompanionCounts {
    /// Frames it was handed.
    pub calls: u64,
    /// Commands it sent.
    pub commands: u64,
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

/// One vehicle's companion.
pub struct Slot {
    link: Link,
    period_us: u64,
    latency_us: u64,
    next_us: u64,
    seq: u64,
    target: SenderId,
    px4: bool,
    outbox: Outbox,
    /// Frames to send, with when (the clock, us), in order.
    pending: VecDeque<(u64, Vec<u8>)>,
    captures: Vec<Arc<Capture>>,
    traffic: Vec<AdsbSent>,
    intent: Arc<Mutex<Option<DVec3>>>,
    /// What it did.
    pub counts: CompanionCounts,
    payload: Vec<u8>,
    message: Vec<u8>,
}

impl std::fmt::Debug for Slot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slot").field("link", &self.link).finish()
    }
}

impl Slot {
    /// Start `config`'s planner for vehicle `target` (its output in `dir`) and greet it with
    /// the vehicle's `devices`.
    pub fn start(
        config: &CompanionConfig,
        target: SenderId,
        px4: bool,
        dir: &Path,
        devices: &[String],
    ) -> Result<Slot, CompanionError> {
        let mut link = Link::start(&config.command, dir, config.timeout)?;
        let mut message = Vec::new();
        let hello = protocol::hello(target.system_id, devices, config.hz, config.latency_s);
        protocol::message(&hello, &[], &mut message);
        link.tell(&message)?;
        Ok(Slot {
            link,
            period_us: (1e6 / config.hz).round().max(1.0) as u64,
            latency_us: (config.latency_s * 1e6).round() as u64,
            next_us: 0,
            seq: 0,
            target,
            px4,
            outbox: Outbox::new(outgoing::identity(target.system_id)),
            pending: VecDeque::new(),
            captures: Vec::new(),
            traffic: Vec::new(),
            intent: Arc::new(Mutex::new(None)),
            counts: CompanionCounts::default(),
            payload: Vec::new(),
            message,
        })
    }

    /// Where the row's pilot puts what its plan asks now (the frames' `intent_enu_mps`).
    pub fn intent(&self) -> Arc<Mutex<Option<DVec3>>> {
        self.intent.clone()
    }

    /// What the vehicle's devices made and the traffic it was sent: each device's newest
    /// reading is kept (every frame carries it, its `instant_s` saying how old it is), and
    /// every report until the next frame.
    pub fn collect(&mut self, captures: &[Arc<Capture>], traffic: &[AdsbSent]) {
        for c in captures {
            self.captures.retain(|old| old.device != c.device);
            self.captures.push(c.clone());
        }
        self.traffic.extend_from_slice(traffic);
    }

    /// At `time_us` of the clock: when an instant came, hand the planner its frame, wait for
    /// its commands, and queue them to go `latency_s` later.
    pub fn at(
        &mut self,
        time_us: u64,
        truth: State,
        estimate: Option<(DVec3, f64)>,
    ) -> Result<(), SlotError> {
        if time_us < self.next_us {
            return Ok(());
        }
        self.next_us = (time_us / self.period_us + 1) * self.period_us;
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
        let began = Instant::now();
        let commands = self.link.ask(self.seq, &self.message)?;
        self.counts
            .round_trips_ms
            .push(began.elapsed().as_secs_f64() * 1e3);
        self.counts.calls += 1;
        self.counts.commands += commands.len() as u64;
        self.traffic.clear();
        let mut frames = Vec::new();
        for c in &commands {
            outgoing::encode(c, self.target, self.px4, &mut self.outbox, &mut frames).map_err(
                |why| SlotError::Outgoing {
                    command: self.link.command().to_string(),
                    seq: self.seq,
                    why,
                },
            )?;
        }
        let release = time_us + self.latency_us;
        self.pending
            .extend(frames.into_iter().map(|bytes| (release, bytes)));
        self.seq += 1;
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

//! A planner asked beside a vehicle that flies in wall time (SITL's own physics, a live
//! vehicle): a worker thread of its own holds the link and waits for each answer, so the
//! session thread never waits for the planner. One frame is in flight at a time; an instant
//! that comes while the planner is still on the last frame is skipped (a real companion drops
//! frames the same way), and counted.

use std::net::{Shutdown, TcpStream};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError};
use std::thread::JoinHandle;
use std::time::Instant;

use super::link::{CompanionError, Link};
use super::protocol::Command;

/// A frame handed to the worker.
struct Asked {
    seq: u64,
    instant_us: u64,
    message: Vec<u8>,
}

/// The worker's answer to a frame.
pub(super) struct Answered {
    /// The frame answered.
    pub(super) seq: u64,
    /// Its instant, microseconds of the vehicle's clock.
    pub(super) instant_us: u64,
    /// The frame's bytes, handed back to be written over.
    pub(super) message: Vec<u8>,
    /// Frame out to commands back, wall milliseconds.
    pub(super) round_trip_ms: f64,
    /// Its commands, or why there are none.
    pub(super) result: Result<Vec<Command>, CompanionError>,
}

/// The worker that asks the planner, and the way to it.
pub(super) struct Beside {
    command: String,
    frames: Option<SyncSender<Asked>>,
    answers: Receiver<Answered>,
    busy: bool,
    stopper: Option<TcpStream>,
    worker: Option<JoinHandle<()>>,
}

impl Beside {
    /// Hand `link` (greeted already) to a worker thread of its own.
    pub(super) fn start(link: Link) -> Result<Self, CompanionError> {
        let command = link.command().to_string();
        let stopper = link.stopper();
        let (frames, asked) = std::sync::mpsc::sync_channel::<Asked>(1);
        let (answer, answers) = std::sync::mpsc::sync_channel::<Answered>(1);
        let worker = std::thread::Builder::new()
            .name("savsim-companion".into())
            .spawn(move || ask_each(link, &asked, &answer))
            .map_err(|e| CompanionError::Start {
                command: command.clone(),
                why: format!("its thread: {e}"),
            })?;
        Ok(Self {
            command,
            frames: Some(frames),
            answers,
            busy: false,
            stopper,
            worker: Some(worker),
        })
    }

    /// Whether a frame is in flight.
    pub(super) fn busy(&self) -> bool {
        self.busy
    }

    /// Hand frame `seq` of `instant_us` to the planner (not [`Beside::busy`]).
    pub(super) fn offer(
        &mut self,
        seq: u64,
        instant_us: u64,
        message: Vec<u8>,
    ) -> Result<(), CompanionError> {
        let sent = self.frames.as_ref().map(|f| {
            f.send(Asked {
                seq,
                instant_us,
                message,
            })
        });
        match sent {
            Some(Ok(())) => {
                self.busy = true;
                Ok(())
            }
            _ => Err(self.gone()),
        }
    }

    /// The answer to the frame in flight, if it came.
    pub(super) fn answer(&mut self) -> Result<Option<Answered>, CompanionError> {
        if !self.busy {
            return Ok(None);
        }
        match self.answers.try_recv() {
            Ok(answered) => {
                self.busy = false;
                Ok(Some(answered))
            }
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => Err(self.gone()),
        }
    }

    fn gone(&self) -> CompanionError {
        CompanionError::Closed {
            command: self.command.clone(),
            why: "its link's thread ended".into(),
            log: String::new(),
        }
    }
}

/// The worker: each frame asked, its answer sent back; the first failure ends it, and the
/// link (and with it the planner) with it.
fn ask_each(mut link: Link, asked: &Receiver<Asked>, answer: &SyncSender<Answered>) {
    while let Ok(Asked {
        seq,
        instant_us,
        message,
    }) = asked.recv()
    {
        let began = Instant::now();
        let result = link.ask(seq, &message);
        let failed = result.is_err();
        let answered = Answered {
            seq,
            instant_us,
            message,
            round_trip_ms: began.elapsed().as_secs_f64() * 1e3,
            result,
        };
        if answer.send(answered).is_err() || failed {
            return;
        }
    }
}

impl Drop for Beside {
    fn drop(&mut self) {
        // A worker waiting on the planner wakes to a closed socket; one waiting for a frame,
        // to a closed channel. Either way it ends, and its link ends the planner.
        if let Some(stream) = self.stopper.take() {
            let _ = stream.shutdown(Shutdown::Both);
        }
        self.frames.take();
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

//! Replaying a recording (a tlog, a PX4 ULog, an ArduPilot DataFlash log) into a session, as fast as the machine can or paced by its timestamps.

use std::fs::File;
use std::io::{Read, Seek};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};
use crate::logs::flightlog::{read_dataflash, read_ulog, FlightLog, LogKind};
use crate::logs::tlog::TlogReader;
use crate::session::Session;

/// How fast a replay runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// As fast as the machine can.
    Max,
    /// This factor of the recorded time (1 = as flown).
    Factor(f64),
}

impl std::str::FromStr for Speed {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        if s == "max" {
            return Ok(Speed::Max);
        }
        match s.parse::<f64>() {
            Ok(f) if f.is_finite() && f > 0.0 => Ok(Speed::Factor(f)),
            _ => Err(Error::Usage(format!(
                "--speed {s:?}: give a positive factor (1 = as flown) or `max`"
            ))),
        }
    }
}

/// Longest wall-clock pause a replay makes for one gap in the recording, seconds.
const MAX_REPLAY_PAUSE_S: f64 = 10.0;

/// Paces a replay by its source's clock: sleeps until each record is due at `speed`, with no
/// pause longer than [`MAX_REPLAY_PAUSE_S`] for a gap.
struct Pacer {
    speed: Speed,
    wall_start: Instant,
    first_t_s: Option<f64>,
    paused_s: f64,
    last_t_s: f64,
}

impl Pacer {
    fn new(speed: Speed) -> Self {
        Self {
            speed,
            wall_start: Instant::now(),
            first_t_s: None,
            paused_s: 0.0,
            last_t_s: f64::NEG_INFINITY,
        }
    }

    /// Wait until a record at `t_s` is due.
    fn wait_for(&mut self, t_s: f64) {
        if let Speed::Factor(factor) = self.speed {
            let t0 = *self.first_t_s.get_or_insert(t_s);
            if t_s - self.last_t_s > MAX_REPLAY_PAUSE_S && self.last_t_s.is_finite() {
                self.paused_s += t_s - self.last_t_s - MAX_REPLAY_PAUSE_S;
            }
            let due = (t_s - t0 - self.paused_s) / factor;
            let now = self.wall_start.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(Duration::from_secs_f64((due - now).min(MAX_REPLAY_PAUSE_S)));
            }
        }
        self.last_t_s = self.last_t_s.max(t_s);
    }
}

/// When a replay stops before the end of its recording.
struct Stop<'a> {
    /// Seconds after the first message (`--until-s`).
    until_s: Option<f64>,
    /// Set by a signal.
    shutdown: &'a AtomicBool,
}

impl Stop<'_> {
    /// Whether a record at `t_s` is to be taken: not after a signal (the session is marked
    /// interrupted) nor past `until_s`. When it is, waits until it is due.
    fn admit(&self, session: &mut Session, pacer: &mut Pacer, t_s: f64) -> bool {
        if self.shutdown.load(Ordering::Relaxed) {
            session.set_interrupted(true);
            return false;
        }
        let past = matches!(
            (self.until_s, session.elapsed_s(t_s)),
            (Some(until_s), Some(elapsed_s)) if elapsed_s > until_s
        );
        if !past {
            pacer.wait_for(t_s);
        }
        !past
    }
}

/// Replay a recording into a session, paced by its timestamps: a tlog, a PX4 ULog or an
/// ArduPilot DataFlash log (told apart by their first bytes). With `until_s`, stop at the
/// first record more than that many seconds after the first message (the report's "+N s").
pub fn replay(
    path: &Path,
    speed: Speed,
    progress: bool,
    until_s: Option<f64>,
    session: &mut Session,
    shutdown: &AtomicBool,
) -> Result<()> {
    let stop = Stop { until_s, shutdown };
    let mut file = crate::files::open_stream(path).map_err(|e| Error::file(path, e))?;
    let mut head = Vec::with_capacity(16);
    let kind = file
        .by_ref()
        .take(16)
        .read_to_end(&mut head)
        .and_then(|_| file.rewind())
        .map(|()| LogKind::of(&head))
        .map_err(|e| Error::file(path, e))?;
    if kind == LogKind::Tlog {
        return replay_tlog(path, file, speed, progress, session, &stop);
    }
    drop(file);
    let data =
        crate::files::read(path, crate::files::MAX_LOG_BYTES).map_err(|e| Error::file(path, e))?;
    let log = match kind {
        LogKind::Ulog => read_ulog(&data).map_err(|e| Error::Log {
            path: path.to_path_buf(),
            source: Box::new(e),
        })?,
        _ => read_dataflash(&data),
    };
    replay_log(log, speed, session, &stop)
}

/// Replay an autopilot log's reports (already read) into a session.
fn replay_log(log: FlightLog, speed: Speed, session: &mut Session, stop: &Stop) -> Result<()> {
    let mut pacer = Pacer::new(speed);
    session.set_log(log.summary);
    for timed in &log.reports {
        let t_s = timed.t_us as f64 * 1e-6;
        if !stop.admit(session, &mut pacer, t_s) {
            break;
        }
        let t_s = session.stats_mut().observe_time(t_s);
        session.on_report(t_s, timed.sender, &timed.report)?;
    }
    Ok(())
}

/// Replay a tlog into a session.
fn replay_tlog(
    path: &Path,
    file: File,
    speed: Speed,
    progress: bool,
    session: &mut Session,
    stop: &Stop,
) -> Result<()> {
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let bar = (progress && len > (8 << 20) && std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .then(|| indicatif::ProgressBar::new(len));
    let mut reader = TlogReader::new(file);
    let mut pacer = Pacer::new(speed);
    let mut n: u64 = 0;
    loop {
        let record = reader
            .next_record(session.stats_mut())
            .map_err(|e| Error::file(path, e))?;
        let Some(record) = record else { break };
        let t_s = record.timestamp_us as f64 * 1e-6;
        if !stop.admit(session, &mut pacer, t_s) {
            break;
        }
        session.on_frame(t_s, &record.frame)?;
        n += 1;
        if let Some(bar) = &bar {
            if n.is_multiple_of(4096) {
                bar.set_position(reader.position());
            }
        }
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    Ok(())
}

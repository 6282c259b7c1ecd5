//! Replaying a tlog into a session, as fast as the machine can or paced by its timestamps.

use std::fs::File;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};
use crate::ingest::tlog::TlogReader;
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

/// Replay a tlog into a session, paced by its timestamps; with `until_s`, stop at the first
/// record more than that many seconds after the first message (the report's "+N s").
pub fn replay(
    path: &Path,
    speed: Speed,
    progress: bool,
    until_s: Option<f64>,
    session: &mut Session,
    shutdown: &AtomicBool,
) -> Result<()> {
    let file = File::open(path).map_err(|e| Error::file(path, e))?;
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let bar = (progress && len > (8 << 20) && std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .then(|| indicatif::ProgressBar::new(len));
    let mut reader = TlogReader::new(file);
    let wall_start = Instant::now();
    let mut first_t_s: Option<f64> = None;
    let mut paused_s = 0.0;
    let mut last_t_s = f64::NEG_INFINITY;
    let mut n: u64 = 0;
    loop {
        if shutdown.load(Ordering::Relaxed) {
            session.set_interrupted(true);
            break;
        }
        let record = reader
            .next_record(session.stats_mut())
            .map_err(|e| Error::file(path, e))?;
        let Some(record) = record else { break };
        let t_s = record.timestamp_us as f64 * 1e-6;
        if let (Some(until_s), Some(elapsed_s)) = (until_s, session.elapsed_s(t_s)) {
            if elapsed_s > until_s {
                break;
            }
        }
        if let Speed::Factor(factor) = speed {
            let t0 = *first_t_s.get_or_insert(t_s);
            if t_s - last_t_s > MAX_REPLAY_PAUSE_S && last_t_s.is_finite() {
                paused_s += t_s - last_t_s - MAX_REPLAY_PAUSE_S;
            }
            let due = (t_s - t0 - paused_s) / factor;
            let now = wall_start.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(Duration::from_secs_f64((due - now).min(MAX_REPLAY_PAUSE_S)));
            }
        }
        last_t_s = last_t_s.max(t_s);
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

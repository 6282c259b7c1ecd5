//! The turn-taking between savsim's physics loop and a pilot thread in lockstep: the loop hands
//! the pilot what its autopilot said, then waits until the pilot has acted on all of it (and
//! waits for more) before the autopilot's clock moves on. What the pilot sends therefore
//! reaches the autopilot at the same step of its clock in every run.

use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// One pilot's turn-taking with the physics loop.
#[derive(Debug, Default)]
pub struct Gate {
    state: Mutex<GateState>,
    changed: Condvar,
}

#[derive(Debug, Default)]
struct GateState {
    /// Messages handed to the pilot.
    delivered: u64,
    /// Messages the pilot had taken when it last waited for more.
    idle_at: Option<u64>,
    /// The pilot is gone (or the loop is): nobody waits.
    closed: bool,
}

/// The pilot did not become idle within the wait.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("the pilot did not act on its autopilot's messages within {0:.0} s of wall time")]
pub struct Stuck(pub f64);

impl Gate {
    /// The loop: `n` more messages were handed to the pilot.
    pub fn delivered(&self, n: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.delivered += n;
        }
    }

    /// The loop: wait until the pilot has taken every message handed to it and waits for
    /// more (or is gone), at most `limit`.
    pub fn wait_idle(&self, limit: Duration) -> Result<(), Stuck> {
        let started = Instant::now();
        let Ok(mut s) = self.state.lock() else {
            return Ok(());
        };
        while !s.closed && s.idle_at != Some(s.delivered) {
            let left = limit.saturating_sub(started.elapsed());
            if left.is_zero() {
                return Err(Stuck(limit.as_secs_f64()));
            }
            s = match self.changed.wait_timeout(s, left) {
                Ok((s, _)) => s,
                Err(_) => return Ok(()),
            };
        }
        Ok(())
    }

    /// The pilot: it has taken `consumed` messages and waits for more.
    pub fn idle(&self, consumed: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.idle_at = Some(consumed);
        }
        self.changed.notify_all();
    }

    /// Whether either side is gone.
    pub fn is_closed(&self) -> bool {
        self.state.lock().map_or(true, |s| s.closed)
    }

    /// Either side is gone: nobody waits any more.
    pub fn close(&self) {
        if let Ok(mut s) = self.state.lock() {
            s.closed = true;
        }
        self.changed.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// The loop waits for the pilot to take what it was handed, and no longer; a pilot that
    /// never does is an error after the limit, a pilot that leaves frees the loop.
    #[test]
    fn the_loop_waits_for_the_pilot_to_act_and_no_longer() {
        let gate = Arc::new(Gate::default());
        gate.idle(0);
        assert!(gate.wait_idle(Duration::from_millis(1)).is_ok());
        gate.delivered(2);
        let pilot = {
            let gate = gate.clone();
            std::thread::Builder::new()
                .name("test-pilot".into())
                .spawn(move || {
                    std::thread::sleep(Duration::from_millis(50));
                    gate.idle(2);
                })
                .unwrap()
        };
        let started = Instant::now();
        gate.wait_idle(Duration::from_secs(5)).unwrap();
        assert!(started.elapsed() >= Duration::from_millis(40));
        pilot.join().unwrap();
        gate.delivered(1);
        assert_eq!(gate.wait_idle(Duration::from_millis(20)), Err(Stuck(0.02)));
        gate.close();
        assert!(gate.wait_idle(Duration::from_secs(5)).is_ok());
    }
}

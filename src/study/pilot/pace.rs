//! Keeping two SITL clocks together. SITL instances are not synchronised: each paces its own
//! clock to the wall clock at its speedup, and PX4 SIH keeps to its speed factor only
//! roughly (docs/study.md, "Two autopilots", gives what was measured). An ArduCopter's speedup can be changed while it flies (`SIM_SPEEDUP`), so
//! the pilot of an ArduCopter paces it to the other vehicle's clock: at each of its positions
//! it reads how far its clock has drifted from the other's since both were first heard, and
//! asks for the other's measured pace, less (or more) what brings the drift back to zero
//! within [`SETTLE_S`] of its clock.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::study::pilot::heard::{carried, Heard};

/// The drift is brought back within this many seconds of the vehicle's clock.
pub const SETTLE_S: f64 = 2.0;
/// The other's pace is measured over this much wall time.
const PACE_WINDOW: Duration = Duration::from_millis(500);
/// A new speedup is sent when it differs from the last sent by more than this fraction, or
/// one second of the vehicle's clock after the last.
const RESEND_FRACTION: f64 = 0.003;

/// One vehicle's pacing to another's clock.
#[derive(Debug)]
pub struct Pace {
    /// What the other vehicle's pilot heard.
    other: Arc<Mutex<Heard>>,
    /// The other's speedup as asked (to carry its last position's time to now).
    other_speedup: f64,
    /// Own clock less the other's when both were first heard, seconds.
    start_s: Option<f64>,
    /// The other's clock at wall instants, over the last [`PACE_WINDOW`].
    other_clock: VecDeque<(Instant, f64)>,
    /// The last speedup sent, and own clock then (ms).
    sent: Option<(f64, u32)>,
    /// The largest drift read, seconds.
    pub largest_drift_s: f64,
}

impl Pace {
    /// Pace to `other` (its pilot's [`Heard`]), whose SITL was asked `other_speedup`.
    pub fn new(other: Arc<Mutex<Heard>>, other_speedup: f64) -> Self {
        Self {
            other,
            other_speedup,
            start_s: None,
            other_clock: VecDeque::new(),
            sent: None,
            largest_drift_s: 0.0,
        }
    }

    /// The other's clock now, seconds: its last message's, carried on at its speedup.
    fn other_now_s(&self, now: Instant) -> Option<f64> {
        let (ms, at) = self.other.lock().ok()?.clock?;
        Some(carried(ms, at, now, self.other_speedup))
    }

    /// With own clock `own` (ms in own last message that carries it, and when it came) at
    /// `now`: the speedup to ask of own SITL, when one is due.
    pub fn at(&mut self, own: (u32, Instant), now: Instant) -> Option<f64> {
        let other_s = self.other_now_s(now)?;
        let own_ms = own.0;
        let own_s = carried(
            own.0,
            own.1,
            now,
            self.sent.map_or(self.other_speedup, |s| s.0),
        );
        let drift_s = own_s - other_s - *self.start_s.get_or_insert(own_s - other_s);
        self.largest_drift_s = self.largest_drift_s.max(drift_s.abs());
        self.other_clock.push_back((now, other_s));
        while self
            .other_clock
            .front()
            .is_some_and(|(t, _)| now.duration_since(*t) > PACE_WINDOW)
        {
            self.other_clock.pop_front();
        }
        let (then, then_s) = *self.other_clock.front()?;
        let wall_s = now.duration_since(then).as_secs_f64();
        if wall_s < 0.5 * PACE_WINDOW.as_secs_f64() || other_s <= then_s {
            return None;
        }
        let other_pace = (other_s - then_s) / wall_s;
        let wanted = paced(other_pace, drift_s);
        let due = self.sent.is_none_or(|(last, last_ms)| {
            (wanted - last).abs() > RESEND_FRACTION * last || own_ms.wrapping_sub(last_ms) >= 1000
        });
        if !due {
            return None;
        }
        self.sent = Some((wanted, own_ms));
        Some(wanted)
    }
}

/// The speedup that keeps pace with a clock running at `other_pace` and brings `drift_s` (own
/// ahead positive) back to zero within [`SETTLE_S`]: at most 20% off the other's pace.
///
/// ```
/// use savsim::study::pilot::pace::paced;
/// assert_eq!(paced(4.7, 0.0), 4.7);
/// // 0.2 s ahead: slower, by a tenth over SETTLE_S = 2 s.
/// assert!((paced(4.7, 0.2) - 4.7 * 0.9).abs() < 1e-12);
/// assert!((paced(4.7, -30.0) - 4.7 * 1.2).abs() < 1e-12);
/// ```
pub fn paced(other_pace: f64, drift_s: f64) -> f64 {
    other_pace * (1.0 - drift_s / SETTLE_S).clamp(0.8, 1.2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The other clock runs at 1.9x: after the first half-second of wall time, own is asked
    /// 1.9x; once own has run ahead by 0.25 s, less.
    #[test]
    fn pace_follows_the_other_clock_and_pulls_back_a_drift() {
        let other = Arc::new(Mutex::new(Heard::default()));
        let mut pace = Pace::new(other.clone(), 2.0);
        let start = Instant::now();
        let mut asked = Vec::new();
        for k in 0..=100u32 {
            let now = start + Duration::from_millis(u64::from(k) * 10);
            let wall_s = f64::from(k) * 0.01;
            if let Ok(mut h) = other.lock() {
                h.clock = Some(((wall_s * 1.9 * 1000.0).round() as u32, now));
            }
            // Own runs at 2x from the same start, then jumps 0.25 s ahead at k = 80.
            let own_ms = (wall_s * 2.0 * 1000.0).round() as u32 + if k >= 80 { 250 } else { 0 };
            if let Some(s) = pace.at((own_ms, now), now) {
                asked.push((k, s));
            }
        }
        assert!(asked.first().is_some_and(|(k, _)| *k >= 25), "{asked:?}");
        let (_, first) = asked[0];
        assert!(
            (first - 1.9 * (1.0 - 0.025 / SETTLE_S)).abs() < 0.01,
            "{asked:?}"
        );
        let (k, last) = *asked.last().unwrap();
        assert!(k >= 80 && last < 1.9 * 0.96, "{asked:?}");
        assert!(pace.largest_drift_s > 0.29, "{}", pace.largest_drift_s);
    }
}

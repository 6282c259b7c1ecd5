//! Vehicle clocks: the one rule that says "this vehicle's clock restarted" (a reboot), and the
//! model that maps a vehicle's clock onto the receive clock.
//!
//! The world store, the link supervisor and the feed all ask [`step`]; none keeps a rule of its
//! own. A clock stamp is MAVLink's `time_boot_ms` (u32 milliseconds since boot, wrapping after
//! about 49.7 days).
//!
//! [`ClockMap`] maps a vehicle's clock to the receive clock with the rate it is seen to run at
//! (offset and skew, as a time-sync filter does): the arrival times' lower envelope, fitted
//! over the last few seconds of the vehicle's clock. A SITL at speedup 5, or one that runs
//! slow on a busy machine, is then timed as it arrived, not 1:1 with a clamp.
//!
//! Pure and synchronous; no I/O.

use std::collections::VecDeque;

/// A stamp this far back from the one before, or further, is a restart; less far back, a reordered
/// message (UDP, a router). A reboot that comes back less than this far behind is taken for
/// reordering (how far back real restarts come: docs/live.md).
pub const RESTART_BACK_MS: u32 = 500;

/// A stamp further ahead than this from the one before is a new clock too (a different boot
/// after a long silence): no vehicle's interval between two messages is an hour.
pub const RESTART_AHEAD_MS: u32 = 3_600_000;

/// How a stamp follows the one before it from the same sender.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockStep {
    /// Later (or the same), by this many milliseconds: the same boot. Across the u32 wrap too.
    Forward(u32),
    /// A little earlier: a reordered message of the same boot.
    Reordered,
    /// Far back (or implausibly far ahead): the vehicle restarted.
    Restart,
}

/// The one restart rule: how `now_ms` follows `last_ms` (wrap-safe).
///
/// ```
/// use savsim_core::world::clock::{step, ClockStep};
/// assert_eq!(step(6_500, 6_600), ClockStep::Forward(100));
/// assert_eq!(step(6_500, 6_400), ClockStep::Reordered);
/// // PX4 SITL restarted: its clock came back from 6.5 s to 1.5 s.
/// assert_eq!(step(6_500, 1_500), ClockStep::Restart);
/// // Across the u32 wrap (49.7 days of uptime) the clock goes on.
/// assert_eq!(step(u32::MAX - 50, 49), ClockStep::Forward(100));
/// // A restart after more than 24.8 days of uptime is still a restart.
/// assert_eq!(step(3_000_000_000, 1_200), ClockStep::Restart);
/// ```
pub fn step(last_ms: u32, now_ms: u32) -> ClockStep {
    let ahead = now_ms.wrapping_sub(last_ms);
    let back = last_ms.wrapping_sub(now_ms);
    if ahead <= RESTART_AHEAD_MS {
        ClockStep::Forward(ahead)
    } else if back < RESTART_BACK_MS {
        ClockStep::Reordered
    } else {
        ClockStep::Restart
    }
}

/// Width of one bin of the vehicle's clock in which the earliest arrival is kept, seconds.
const BIN_S: f64 = 0.5;
/// Bins the rate is fitted over (8 s of the vehicle's clock).
const BINS: usize = 16;
// Theil-Sen's pairs of the completed bins fit a SmallVec of this size without spilling.
const _: () = assert!(BINS * (BINS - 1) / 2 <= 128);
/// The fitted rate is kept within these (wall seconds per vehicle second): speedups from
/// 1/1000 to 1000.
const RATE_RANGE: (f64, f64) = (1e-3, 1e3);
/// A mapped time later than arrival by more than this is counted as pulled back, seconds.
const PULL_COUNTED_S: f64 = 0.05;

/// The earliest arrival seen in one bin of the vehicle's clock.
#[derive(Debug, Clone, Copy)]
struct Bin {
    index: i64,
    vehicle_s: f64,
    receive_s: f64,
}

/// One boot of one vehicle: its clock mapped onto the receive clock, `t = offset + rate x
/// vehicle_s`, never later than arrival and always advancing.
///
/// ```
/// use savsim_core::world::clock::ClockMap;
/// // A SITL at speedup 5: 100 ms of its clock every 20 ms of arrival, with a little jitter.
/// let mut clock = ClockMap::new(1.0);
/// let mut last = (0.0, false);
/// for i in 0..200u32 {
///     let jitter_s = if i % 3 == 0 { 0.004 } else { 0.0 };
///     last = clock.map(i * 100, 1000.0 + f64::from(i) * 0.02 + jitter_s);
/// }
/// assert!((clock.rate() - 0.2).abs() < 1e-3, "{}", clock.rate());
/// // The last sample (no jitter) is mapped to within a millisecond of its arrival.
/// assert!((last.0 - (1000.0 + 199.0 * 0.02)).abs() < 1e-3, "{last:?}");
/// ```
#[derive(Debug, Clone)]
pub struct ClockMap {
    /// The vehicle's clock, unwrapped, at the last sample, ms.
    last_boot_ms: Option<(u32, u64)>,
    /// The last mapped time, seconds of the receive clock.
    last_t_s: f64,
    /// Wall seconds per vehicle second (1 / speedup).
    rate: f64,
    /// `t = offset + rate x vehicle_s`.
    offset_s: f64,
    /// On the vehicle's own rate: `t = own_offset + vehicle_s` (the receive clock's fit is
    /// still kept, for [`ClockMap::speedup`]).
    own_offset_s: f64,
    bins: VecDeque<Bin>,
    /// Whether the map runs at the vehicle's own rate ([`ClockMap::own_rate`]).
    own_rate: bool,
    /// Whether `rate` was fitted (not the prior).
    fitted: bool,
}

impl ClockMap {
    /// A map for a new boot; `prior_rate` is the rate to assume until one is seen (1.0, or the
    /// rate of the vehicle's boot before).
    pub fn new(prior_rate: f64) -> Self {
        Self {
            last_boot_ms: None,
            last_t_s: f64::NEG_INFINITY,
            rate: prior_rate.clamp(RATE_RANGE.0, RATE_RANGE.1),
            offset_s: f64::INFINITY,
            own_offset_s: f64::INFINITY,
            bins: VecDeque::with_capacity(BINS + 1),
            own_rate: false,
            fitted: false,
        }
    }

    /// A map for a new boot that keeps the vehicle's own time: `t = offset + vehicle_s`, the
    /// offset fixed by the boot's first stamp (mapped to its arrival). A second of the
    /// vehicle's clock is a second of session time at any speedup or drift, so that scripted
    /// traffic and intruders move on the vehicle's clock (`savsim study`: one vehicle per
    /// session). Times may run ahead of arrival; they never go back.
    ///
    /// ```
    /// use savsim_core::world::clock::ClockMap;
    /// // A SITL at speedup 10: 100 ms of its clock every 10 ms of arrival.
    /// let mut clock = ClockMap::own_rate();
    /// let first = clock.map(5_000, 20.0).0;
    /// let later = clock.map(15_000, 21.0).0;
    /// assert_eq!((first, later), (20.0, 30.0));
    /// ```
    pub fn own_rate() -> Self {
        Self {
            own_rate: true,
            ..Self::new(1.0)
        }
    }

    /// Fix an own-rate map that has mapped nothing yet so that `time_boot_ms` maps to `t_s`
    /// (a later vehicle joining a timeline, [`super::timeline`]); a map already anchored, or
    /// one that fits the receive clock, is left as it is.
    pub fn anchor(&mut self, time_boot_ms: u32, t_s: f64) {
        if self.own_rate && self.last_boot_ms.is_none() {
            self.own_offset_s = t_s - f64::from(time_boot_ms) / 1000.0;
        }
    }

    /// Receive seconds per second of the vehicle's clock as fitted from its arrivals (`None`
    /// before a second of its clock was seen: the rate is the prior until then).
    pub fn fitted_rate(&self) -> Option<f64> {
        self.fitted.then_some(self.rate)
    }

    /// Whether this map keeps the vehicle's own time ([`ClockMap::own_rate`]).
    pub fn is_own_rate(&self) -> bool {
        self.own_rate
    }

    /// Wall seconds per second of the vehicle's clock: 1 / the speedup.
    pub fn rate(&self) -> f64 {
        self.rate
    }

    /// The vehicle's speedup: seconds of its clock per second of the receive clock.
    pub fn speedup(&self) -> f64 {
        1.0 / self.rate
    }

    /// The receive-clock time of the stamp `time_boot_ms` (of this boot, at or after the last
    /// one mapped: [`step`] says `Forward`) that arrived at `receive_t_s`, and whether it had
    /// to be pulled back to its arrival by more than 50 ms.
    pub fn map(&mut self, time_boot_ms: u32, receive_t_s: f64) -> (f64, bool) {
        let unwrapped_ms = match self.last_boot_ms {
            Some((last, unwrapped)) => unwrapped + u64::from(time_boot_ms.wrapping_sub(last)),
            None => u64::from(time_boot_ms),
        };
        self.last_boot_ms = Some((time_boot_ms, unwrapped_ms));
        let vehicle_s = unwrapped_ms as f64 / 1000.0;
        if self.own_rate {
            if !self.own_offset_s.is_finite() {
                self.own_offset_s = receive_t_s - vehicle_s;
            }
            // Its speedup is still measured.
            self.observe(vehicle_s, receive_t_s);
            let t_s = (self.own_offset_s + vehicle_s).max(self.last_t_s + 1e-6);
            self.last_t_s = t_s;
            return (t_s, false);
        }
        self.observe(vehicle_s, receive_t_s);
        let fitted = self.offset_s + self.rate * vehicle_s;
        let pulled = fitted > receive_t_s + PULL_COUNTED_S;
        let mut t_s = fitted.min(receive_t_s);
        if t_s <= self.last_t_s {
            // Never before (or at) the last sample: an interval is never empty.
            t_s = (self.last_t_s + 1e-3).min(self.last_t_s.max(receive_t_s));
            if t_s <= self.last_t_s {
                t_s = self.last_t_s + 1e-6;
            }
        }
        self.last_t_s = t_s;
        (t_s, pulled)
    }

    /// Take one arrival into the bins, the rate and the offset.
    fn observe(&mut self, vehicle_s: f64, receive_s: f64) {
        let index = (vehicle_s / BIN_S).floor() as i64;
        let key = |b: &Bin, rate: f64| b.receive_s - rate * b.vehicle_s;
        let point = Bin {
            index,
            vehicle_s,
            receive_s,
        };
        match self.bins.back_mut() {
            Some(last) if last.index == index => {
                if key(&point, self.rate) < key(last, self.rate) {
                    *last = point;
                }
            }
            _ => {
                self.bins.push_back(point);
                if self.bins.len() > BINS {
                    self.bins.pop_front();
                }
                self.fit_rate();
            }
        }
        let rate = self.rate;
        self.offset_s = self
            .bins
            .iter()
            .map(|b| key(b, rate))
            .fold(f64::INFINITY, f64::min);
    }

    /// The median of the slopes between every two completed bins' earliest arrivals
    /// (Theil-Sen: a bin whose every sample came late moves it little), when they span at least
    /// 1 s of the vehicle's clock. The newest bin is still filling and is left out.
    fn fit_rate(&mut self) {
        let complete = self.bins.len().saturating_sub(1);
        let bins = self.bins.range(..complete);
        let span_s = match (self.bins.front(), self.bins.get(complete.wrapping_sub(1))) {
            (Some(a), Some(b)) if complete >= 3 => b.vehicle_s - a.vehicle_s,
            _ => 0.0,
        };
        if span_s < 1.0 {
            return;
        }
        let mut slopes: smallvec::SmallVec<[f64; 128]> = smallvec::SmallVec::new();
        let points: smallvec::SmallVec<[Bin; BINS]> = bins.copied().collect();
        for (i, a) in points.iter().enumerate() {
            for b in &points[i + 1..] {
                let dx = b.vehicle_s - a.vehicle_s;
                if dx > 0.0 {
                    slopes.push((b.receive_s - a.receive_s) / dx);
                }
            }
        }
        if slopes.is_empty() {
            return;
        }
        let mid = slopes.len() / 2;
        let (_, median, _) = slopes.select_nth_unstable_by(mid, f64::total_cmp);
        if median.is_finite() {
            self.rate = median.clamp(RATE_RANGE.0, RATE_RANGE.1);
            self.fitted = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clock_at_one_to_one_with_latency_maps_to_its_earliest_arrivals() {
        let mut clock = ClockMap::new(1.0);
        for i in 0..400u32 {
            // 10 Hz, 5-25 ms of latency.
            let latency_s = 0.005 + f64::from(i * 7 % 21) * 1e-3;
            let (t, pulled) = clock.map(10_000 + i * 100, 50.0 + f64::from(i) * 0.1 + latency_s);
            assert!(!pulled);
            assert!(t <= 50.0 + f64::from(i) * 0.1 + latency_s);
        }
        assert!((clock.rate() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn a_slow_clock_is_followed_without_pulls() {
        // PX4 SIH on a busy machine: 0.9 s of its clock per wall second.
        let mut clock = ClockMap::new(1.0);
        let mut pulls = 0;
        for i in 0..2000u32 {
            let (_, pulled) = clock.map(i * 20, 7.0 + f64::from(i) * 0.020 / 0.9);
            pulls += u32::from(pulled);
        }
        assert_eq!(pulls, 0);
        assert!((clock.speedup() - 0.9).abs() < 1e-3, "{}", clock.speedup());
    }

    #[test]
    fn samples_in_one_read_keep_their_own_intervals() {
        let mut clock = ClockMap::new(1.0);
        for i in 0..100u32 {
            clock.map(i * 100, f64::from(i) * 0.1);
        }
        // Three samples 100 ms apart on the vehicle's clock that arrived in one read.
        let a = clock.map(10_000, 10.2).0;
        let b = clock.map(10_100, 10.2).0;
        let c = clock.map(10_200, 10.2).0;
        assert!(
            (b - a - 0.1).abs() < 1e-9 && (c - b - 0.1).abs() < 1e-9,
            "{a} {b} {c}"
        );
    }
}

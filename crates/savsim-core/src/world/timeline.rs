//! Several vehicles' clocks on one timeline ([`super::WorldConfig::vehicle_clock`]).
//!
//! Each SITL instance keeps its own clock from its own boot, at its own pace: instances are
//! not synchronised with each other, and one that cannot keep its speedup falls behind. On
//! the vehicle's clock a session's timeline is the clock of one vehicle, the reference (the
//! one named, else the first heard). Every other vehicle is placed on it by when its
//! positions were sent: when its clock read their time (from its last readings that came
//! soonest, [`RecentClock`]), and where the reference's clock was then (the same way). Two
//! vehicles are then where they were at the same moment whatever either clock's pace.
//!
//! How far each other vehicle's clock drifted from the timeline (its own time less where it
//! is placed) is its skew. One reading holds the arrival jitter left in the fits, either
//! way; the skew kept is the largest change of the median of [`SKEW_WINDOW`] readings in a
//! row from the first such median ([`SkewWindow`]).
//!
//! ```
//! use savsim_core::world::timeline::Timeline;
//! let mut line = Timeline::default();
//! // The reference at 10x: 1 s of its clock every 0.1 s of arrival (no fit yet).
//! line.reference_at(100.0, 1000.0, None);
//! assert_eq!(line.at(1000.05), None);
//! line.reference_at(101.0, 1000.1, None);
//! assert!((line.rate().unwrap() - 0.1).abs() < 1e-9);
//! // Another vehicle's position sent at 1000.15: the reference reads 101.5 then.
//! assert!((line.at(1000.15).unwrap() - 101.5).abs() < 1e-9);
//! ```

/// Positions a [`RecentClock`] keeps: at 50 Hz, 0.64 s of the vehicle's clock.
pub const RECENT: usize = 32;
/// A rate is read over readings at least this far apart on the clock, seconds: readings that
/// came in one burst tell none.
pub const RATE_SPAN_S: f64 = 0.3;

/// A clock's last [`RECENT`] readings with their arrivals. Arrival jitter only ever delays,
/// so the readings that came soonest tell best when a reading was sent and where the clock
/// is at a given moment; between readings the clock runs at a given rate. Over a short window
/// a rate that changes (a SITL whose speedup is changed) moves this little.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecentClock {
    /// (clock s, arrival s), a ring.
    readings: [(f64, f64); RECENT],
    len: usize,
    next: usize,
}

impl Default for RecentClock {
    fn default() -> Self {
        Self {
            readings: [(0.0, 0.0); RECENT],
            len: 0,
            next: 0,
        }
    }
}

impl RecentClock {
    /// Take one reading `clock_s` that arrived at `receive_s`.
    pub fn push(&mut self, clock_s: f64, receive_s: f64) {
        self.readings[self.next] = (clock_s, receive_s);
        self.next = (self.next + 1) % RECENT;
        self.len = (self.len + 1).min(RECENT);
    }

    /// Forget every reading (a new boot).
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    fn kept(&self) -> &[(f64, f64)] {
        &self.readings[..self.len]
    }

    /// Receive seconds per second of the clock from the oldest reading kept to the newest
    /// (`None` until they are [`RATE_SPAN_S`] apart on its clock and apart on arrival).
    pub fn rate(&self) -> Option<f64> {
        let newest = self.readings[(self.next + RECENT - 1) % RECENT];
        let oldest = if self.len < RECENT {
            self.readings[0]
        } else {
            self.readings[self.next]
        };
        let (dc, dr) = (newest.0 - oldest.0, newest.1 - oldest.1);
        (self.len >= 2 && dc >= RATE_SPAN_S && dr > 0.0).then(|| dr / dc)
    }

    /// The clock at receive time `receive_s`, running at `rate` (receive s per clock s) from
    /// the reading that came soonest; `None` with no reading.
    ///
    /// ```
    /// use savsim_core::world::timeline::RecentClock;
    /// let mut c = RecentClock::default();
    /// // 10x; the second reading came 5 ms late.
    /// c.push(100.0, 10.0);
    /// c.push(101.0, 10.105);
    /// assert!((c.clock_at(10.2, 0.1).unwrap() - 102.0).abs() < 1e-9);
    /// assert!((c.sent_at(101.0, 0.1).unwrap() - 10.1).abs() < 1e-9);
    /// ```
    pub fn clock_at(&self, receive_s: f64, rate: f64) -> Option<f64> {
        self.kept()
            .iter()
            .map(|(c, r)| c + (receive_s - r) / rate)
            .reduce(f64::max)
    }

    /// When the clock read `clock_s`, receive seconds, at `rate`, from the reading that came
    /// soonest; `None` with no reading.
    pub fn sent_at(&self, clock_s: f64, rate: f64) -> Option<f64> {
        self.kept()
            .iter()
            .map(|(c, r)| r + (clock_s - c) * rate)
            .reduce(f64::min)
    }
}

/// The reference's clock, as heard.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timeline {
    /// Its last readings (its time on the timeline) with their arrivals.
    reference: RecentClock,
    /// Its rate (receive s per second of its clock), as fitted over its last seconds.
    fitted_rate: Option<f64>,
}

impl Timeline {
    /// The reference's position mapped to `t_s`, arrived at `receive_s`; the rate of its clock
    /// as fitted from its arrivals ([`super::clock::ClockMap::fitted_rate`]) once it has one.
    pub fn reference_at(&mut self, t_s: f64, receive_s: f64, fitted_rate: Option<f64>) {
        self.reference.push(t_s, receive_s);
        self.fitted_rate = fitted_rate.or(self.fitted_rate);
    }

    /// Receive seconds per second of the reference's clock (1 / its speedup): fitted, else
    /// over its last readings; `None` before either is known.
    pub fn rate(&self) -> Option<f64> {
        self.fitted_rate.or_else(|| self.reference.rate())
    }

    /// Where the timeline is at receive time `receive_s` ([`RecentClock::clock_at`]); `None`
    /// before the reference's pace is known.
    pub fn at(&self, receive_s: f64) -> Option<f64> {
        self.reference.clock_at(receive_s, self.rate()?)
    }
}

/// Readings of a vehicle's drift whose median is one measure of its skew: at 50 Hz, 0.64 s of
/// its clock.
pub const SKEW_WINDOW: usize = 32;

/// The last readings of one vehicle's drift from the timeline, and the largest median of a
/// full window of them so far. Fixed size: no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkewWindow {
    /// The first position's time less its clock, seconds: readings are from there.
    origin_s: Option<f64>,
    /// The first full window's median: the drift is from there (one reading's jitter would
    /// shift every later one).
    baseline_s: Option<f64>,
    readings: [f64; SKEW_WINDOW],
    len: usize,
    /// The largest |median| of a full window, seconds.
    pub largest_s: f64,
}

impl Default for SkewWindow {
    fn default() -> Self {
        Self {
            origin_s: None,
            baseline_s: None,
            readings: [0.0; SKEW_WINDOW],
            len: 0,
            largest_s: 0.0,
        }
    }
}

impl SkewWindow {
    /// Start again (the vehicle rebooted: a new clock); the largest so far is kept.
    pub fn restart(&mut self) {
        self.origin_s = None;
        self.baseline_s = None;
        self.len = 0;
    }

    /// Take one position: `vehicle_s` of its clock placed at `t_s` on the timeline. Its
    /// reading is how far its clock moved from the timeline since the first position; when
    /// the window fills, how far its median is from the first window's counts towards the
    /// largest, and the window starts again.
    ///
    /// ```
    /// use savsim_core::world::timeline::{SkewWindow, SKEW_WINDOW};
    /// let mut w = SkewWindow::default();
    /// // A first window on time, then a clock 0.05 s ahead, read with +-0.3 s of jitter: the
    /// // medians read the drift.
    /// for k in 0..2 * SKEW_WINDOW {
    ///     let jitter = [0.3, -0.3, 0.0][k % 3];
    ///     let ahead = if k < SKEW_WINDOW { 0.0 } else { 0.05 };
    ///     w.take(10.0 + k as f64, 110.0 + k as f64 - ahead + jitter);
    /// }
    /// assert!((w.largest_s - 0.05).abs() < 1e-9, "{}", w.largest_s);
    /// ```
    pub fn take(&mut self, vehicle_s: f64, t_s: f64) {
        let origin_s = *self.origin_s.get_or_insert(t_s - vehicle_s);
        let reading_s = vehicle_s + origin_s - t_s;
        if !reading_s.is_finite() {
            return;
        }
        self.readings[self.len] = reading_s;
        self.len += 1;
        if self.len == SKEW_WINDOW {
            self.readings.sort_unstable_by(f64::total_cmp);
            let median =
                0.5 * (self.readings[SKEW_WINDOW / 2 - 1] + self.readings[SKEW_WINDOW / 2]);
            let baseline_s = *self.baseline_s.get_or_insert(median);
            self.largest_s = self.largest_s.max((median - baseline_s).abs());
            self.len = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::Geodetic;
    use crate::world::inputs::{PositionReport, Report, SenderId};
    use crate::world::{WorldConfig, WorldStore};

    fn at(world: &mut WorldStore, system_id: u8, time_boot_ms: u32, receive_s: f64) -> bool {
        let report = Report::Position(PositionReport {
            time_boot_ms,
            position: Geodetic::new(-35.36, 149.16, 600.0),
            relative_alt_m: 16.0,
            velocity_ned_mps: glam::DVec3::ZERO,
            heading_deg: None,
        });
        let sender = SenderId {
            system_id,
            component_id: 1,
        };
        world.apply(receive_s, sender, &report) == crate::world::WorldUpdate::VehicleMoved(sender)
    }

    fn t_of(world: &WorldStore, system_id: u8) -> f64 {
        let sender = SenderId {
            system_id,
            component_id: 1,
        };
        world.vehicles[&sender].history.latest().unwrap().t_s
    }

    /// Two SITLs at 10x, the second booted 0.5 s of arrival later (5 s of its clock behind),
    /// then one that runs at 9x: the first keeps the timeline, the second is placed where its
    /// positions were sent, and its skew is how far its clock drifted (1 s per second of
    /// arrival at 9x: the last full window's median, 1.115 s, from the first's, 0.155 s).
    #[test]
    fn a_second_clock_is_placed_by_its_arrivals_and_its_drift_is_its_skew() {
        for (rate, skew_s) in [(10.0, 0.0), (9.0, 0.96)] {
            let config = WorldConfig {
                vehicle_clock: true,
                timeline_system_id: Some(7),
                ..WorldConfig::default()
            };
            let mut world = WorldStore::new(Geodetic::new(-35.36, 149.16, 584.0), config);
            // Before the reference: not applied.
            assert!(!at(&mut world, 2, 100, 999.0));
            for k in 0..=200u32 {
                let receive_s = 1000.0 + f64::from(k) * 0.01;
                assert!(at(&mut world, 7, 1000 + k * 100, receive_s));
                if k >= 50 {
                    let own_ms = ((receive_s - 1000.5) * rate * 1000.0).round() as u32;
                    assert!(at(&mut world, 2, 2000 + own_ms, receive_s));
                }
            }
            // Sent at the same moment: at the same time on the timeline.
            let apart_s = t_of(&world, 7) - t_of(&world, 2);
            assert!(apart_s.abs() < 1e-3, "{rate}x: {apart_s}");
            let seen = world.seen[&SenderId {
                system_id: 2,
                component_id: 1,
            }];
            assert!(
                (seen.clock_skew_s - skew_s).abs() < 0.01,
                "{rate}x: {seen:?}"
            );
            assert!((seen.clock_speedup - rate).abs() < 0.01, "{seen:?}");
            assert_eq!(seen.before_timeline, 1);
            let reference = world.seen[&SenderId {
                system_id: 7,
                component_id: 1,
            }];
            assert_eq!(reference.clock_skew_s, 0.0);
            assert!(
                (reference.clock_speedup - 10.0).abs() < 0.01,
                "{reference:?}"
            );
        }
    }

    #[test]
    fn a_later_arrival_is_carried_on_at_the_references_speedup() {
        let mut line = Timeline::default();
        assert_eq!(line.at(5.0), None);
        line.reference_at(10.0, 100.0, None);
        // One point: no pace yet.
        assert_eq!(line.at(100.5), None);
        line.reference_at(30.0, 101.0, None);
        assert!((line.at(101.25).unwrap() - 35.0).abs() < 1e-9);
    }
}

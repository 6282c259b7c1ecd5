//! How far an autopilot's own estimate of where it is strays from the truth savsim flies it
//! on: each position it reports, against the truth at the same instant of its clock.

use std::collections::VecDeque;

use glam::DVec3;
use serde::Serialize;

/// Truth kept for looking estimates up, steps (an estimate older than this is not compared).
const KEPT: usize = 8192;

/// One vehicle's truth at each step, and its estimate's error so far.
#[derive(Debug, Clone, Default)]
pub struct EstimateErrors {
    truth: VecDeque<(u64, DVec3)>,
    stats: ErrorStats,
    last: Option<(u32, DVec3)>,
}

/// The estimate's error, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Estimates compared.
    pub count: u64,
    /// The largest horizontal error.
    pub horizontal_max_m: f64,
    /// The mean horizontal error.
    pub horizontal_mean_m: f64,
    /// The largest vertical error.
    pub vertical_max_m: f64,
}

impl EstimateErrors {
    /// The truth at `time_us`, scene ENU metres.
    pub fn truth(&mut self, time_us: u64, enu_m: DVec3) {
        if self.truth.len() == KEPT {
            self.truth.pop_front();
        }
        self.truth.push_back((time_us, enu_m));
    }

    /// An estimate at `time_ms` of the clock (`enu_m`, scene ENU): compared with the truth
    /// there (between the two steps about it, linearly).
    pub fn estimate(&mut self, time_ms: u32, enu_m: DVec3) {
        self.last = Some((time_ms, enu_m));
        let t_us = u64::from(time_ms) * 1000;
        let after = self.truth.partition_point(|(t, _)| *t < t_us);
        let Some(&(t1, p1)) = self.truth.get(after) else {
            return;
        };
        let truth = match after.checked_sub(1).and_then(|k| self.truth.get(k)) {
            Some(&(t0, p0)) if t1 > t0 => p0.lerp(p1, (t_us - t0) as f64 / (t1 - t0) as f64),
            _ if t1 == t_us => p1,
            _ => return,
        };
        let error = enu_m - truth;
        let s = &mut self.stats;
        let horizontal = error.truncate().length();
        s.count += 1;
        s.horizontal_mean_m += (horizontal - s.horizontal_mean_m) / s.count as f64;
        s.horizontal_max_m = s.horizontal_max_m.max(horizontal);
        s.vertical_max_m = s.vertical_max_m.max(error.z.abs());
    }

    /// The newest estimate: its time on the clock (ms) and where, scene ENU metres.
    pub fn last(&self) -> Option<(u32, DVec3)> {
        self.last
    }

    /// The error so far.
    pub fn stats(&self) -> ErrorStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_estimate_is_compared_with_the_truth_at_its_instant() {
        let mut e = EstimateErrors::default();
        for k in 0..10u64 {
            e.truth(k * 2_500, DVec3::new(k as f64, 0.0, 0.0));
        }
        // 5 ms: the truth is at x = 2; the estimate says 2.5 east and 1 up.
        e.estimate(5, DVec3::new(2.5, 0.0, 1.0));
        // 6 ms: between steps 2 and 3, x = 2.4.
        e.estimate(6, DVec3::new(2.4, 0.0, 0.0));
        // Past the last truth: not compared.
        e.estimate(100, DVec3::ZERO);
        let s = e.stats();
        assert_eq!(s.count, 2);
        assert!((s.horizontal_max_m - 0.5).abs() < 1e-12);
        assert!((s.horizontal_mean_m - 0.25).abs() < 1e-12);
        assert!((s.vertical_max_m - 1.0).abs() < 1e-12);
    }
}

//! Alert levels as a DAIDALUS configuration defines them: an alerter is a list of levels, each
//! a well-clear volume with an alerting time and an early alerting time; the level raised for
//! an intruder is the most severe one whose volume is violated within its alerting time (the
//! early alerting time while that level is the one already raised), then filtered over time by
//! M-of-N, hysteresis and persistence.
//!
//! Pure: an [`Alerter`] and [`Filter`] per intruder, stepped in time order.

use crate::daa::sum::{self, Errors};
use crate::daa::well_clear::{Relative, Volume};

/// One alert level of an alerter.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// The volume whose violation raises this level.
    pub volume: Volume,
    /// Raised when the violation comes within this time, seconds.
    pub alerting_time_s: f64,
    /// Kept while the violation comes within this (longer) time, seconds.
    pub early_alerting_time_s: f64,
    /// The guidance region of the level (`NONE`, `FAR`, `MID`, `NEAR`...), as configured.
    pub region: String,
    /// Its detector mitigates sensor uncertainty (DAIDALUS's `WCV_TAUMOD_SUM`).
    pub sum: bool,
}

/// An alerter: its name and its levels, least severe first (level 1 is `levels[0]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Alerter {
    /// The alerter's name in the configuration.
    pub name: String,
    /// Its levels, least severe first.
    pub levels: Vec<Level>,
}

/// A conflict found by a level's volume within the lookahead: when the violation starts and
/// ends, seconds from now; `time_in = lookahead, time_out = 0` when there is none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conflict {
    /// Start of the violation, seconds from now (the lookahead when none).
    pub time_in_s: f64,
    /// End of the violation, seconds from now (0 when none).
    pub time_out_s: f64,
}

impl Conflict {
    /// The violation of `level`'s volume by `rel` within `[0, lookahead_s]`: under the
    /// relative state `errors` when the level mitigates uncertainty and they are not all 0
    /// (DAIDALUS's SUM interval), else nominal.
    pub fn of_level(level: &Level, rel: &Relative, errors: &Errors, lookahead_s: f64) -> Self {
        let uncertain = if level.sum {
            sum::interval(&level.volume, rel.s_m, rel.v_mps, *errors, 0.0, lookahead_s)
        } else {
            None
        };
        match uncertain {
            Some(loss) if loss.conflict() => Conflict {
                time_in_s: loss.t_in,
                time_out_s: loss.t_out,
            },
            Some(_) => Conflict {
                time_in_s: lookahead_s,
                time_out_s: 0.0,
            },
            None => Conflict::of(&level.volume, rel, lookahead_s),
        }
    }

    /// The violation of `volume` by `rel` within `[0, lookahead_s]`.
    pub fn of(volume: &Volume, rel: &Relative, lookahead_s: f64) -> Self {
        match volume.interval(rel, 0.0, lookahead_s) {
            Some((time_in_s, time_out_s)) => Conflict {
                time_in_s,
                time_out_s,
            },
            None => Conflict {
                time_in_s: lookahead_s,
                time_out_s: 0.0,
            },
        }
    }

    /// Whether there is a violation that lasts a while.
    pub fn lasts(&self) -> bool {
        clearly_less(self.time_in_s, self.time_out_s)
    }

    /// Whether the violation lasts a while and starts now or before `t_s`.
    pub fn before(&self, t_s: f64) -> bool {
        let starts = self.time_in_s == 0.0 || clearly_less(self.time_in_s, t_s);
        starts && self.lasts()
    }
}

/// `a < b` by more than a relative 1e-13 (so that a rounding is not a difference).
fn clearly_less(a: f64, b: f64) -> bool {
    a < b && (b - a) > 1e-13 * a.abs().max(b.abs())
}

impl Alerter {
    /// The level the state raises now, before filtering: the most severe level violated within
    /// its alerting time, or its early alerting time when `previous` (the filtered level of the
    /// previous step, at an earlier time) is that level; 0 for none.
    pub fn raw_level(&self, rel: &Relative, lookahead_s: f64, previous: Option<i32>) -> i32 {
        self.raw_level_with(rel, &Errors::default(), lookahead_s, previous)
    }

    /// [`Alerter::raw_level`] with the relative state's `errors`: levels that mitigate
    /// uncertainty test their volume under them.
    pub fn raw_level_with(
        &self,
        rel: &Relative,
        errors: &Errors,
        lookahead_s: f64,
        previous: Option<i32>,
    ) -> i32 {
        for (k, level) in self.levels.iter().enumerate().rev() {
            let number = k as i32 + 1;
            let within = if previous == Some(number) {
                level.early_alerting_time_s
            } else {
                level.alerting_time_s
            };
            if Conflict::of_level(level, rel, errors, lookahead_s).before(within) {
                return number;
            }
        }
        0
    }
}

/// Time filtering of alert levels for one intruder: M of the last N raw levels, reset after
/// `hysteresis_time_s` without a step, and a raised level held for `persistence_time_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct Filter {
    hysteresis_time_s: f64,
    persistence_time_s: f64,
    m: usize,
    n: usize,
    /// The last N raw levels (-1 fills the window after a reset).
    window: std::collections::VecDeque<i32>,
    /// The most severe level seen since the reset.
    max: i32,
    /// The time of the last step.
    last_time_s: Option<f64>,
    /// The level given at the last step (-1 before any).
    last: i32,
    /// When the level last went up.
    raised_at_s: Option<f64>,
}

impl Filter {
    /// A filter with these parameters (M of N applies when `0 < m <= n`).
    pub fn new(hysteresis_time_s: f64, persistence_time_s: f64, m: usize, n: usize) -> Self {
        Filter {
            hysteresis_time_s,
            persistence_time_s,
            m,
            n,
            window: std::collections::VecDeque::new(),
            max: -1,
            last_time_s: None,
            last: -1,
            raised_at_s: None,
        }
    }

    /// The filtered level of the last step at a time before `t_s`, if any.
    pub fn previous(&self, t_s: f64) -> Option<i32> {
        self.last_time_s
            .filter(|&last| last < t_s)
            .map(|_| self.last)
    }

    /// Filter `raw` (the raw level at `t_s`); the level to report.
    ///
    /// ```
    /// use savsim_core::daa::alerting::Filter;
    /// // 2 of 4, hysteresis 5 s, persistence 4 s: a raised level is held 4 s after it drops.
    /// let mut f = Filter::new(5.0, 4.0, 2, 4);
    /// let got: Vec<i32> = [0, 2, 2, 0, 0, 0, 0, 0, 0].iter().enumerate()
    ///     .map(|(t, &raw)| f.step(raw, t as f64)).collect();
    /// // M of N raises at t = 2 and holds to t = 4; persistence holds t = 5 (3 s after).
    /// assert_eq!(got, [0, 0, 2, 2, 2, 2, 0, 0, 0]);
    /// ```
    pub fn step(&mut self, raw: i32, t_s: f64) -> i32 {
        let stale = match self.last_time_s {
            None => true,
            Some(last) => t_s <= last || t_s - last > self.hysteresis_time_s,
        };
        if stale {
            self.reset(raw);
        }
        let voted = self.vote(raw);
        let held = self.raised_at_s.is_some_and(|at| {
            self.last > 0 && voted < self.last && t_s >= at && t_s - at < self.persistence_time_s
        });
        if raw < 0 {
            self.last = raw;
            self.raised_at_s = None;
        } else if !held {
            if voted > 0 && voted > self.last {
                self.raised_at_s = Some(t_s);
            }
            self.last = voted.max(0);
        }
        self.last_time_s = Some(t_s);
        self.last
    }

    fn voting(&self) -> bool {
        self.m > 0 && self.m <= self.n
    }

    fn reset(&mut self, raw: i32) {
        self.window.clear();
        if self.voting() {
            self.window
                .extend((0..self.n).map(|i| if i < self.m { raw } else { -1 }));
        }
        self.max = raw;
        self.last_time_s = None;
        self.last = -1;
        self.raised_at_s = None;
    }

    /// The most severe level that at least M of the last N raw levels reach.
    fn vote(&mut self, raw: i32) -> i32 {
        if !self.voting() {
            return raw;
        }
        self.max = self.max.max(raw);
        self.window.pop_front();
        self.window.push_back(raw);
        if self.max < 0 {
            return self.max;
        }
        (0..=self.max)
            .rev()
            .find(|&level| self.window.iter().filter(|&&v| v >= level).count() >= self.m)
            .unwrap_or(-1)
    }
}

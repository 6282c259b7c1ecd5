//! Losses of well clear (or of a separation minimum) over a flight: for each pair of tracks,
//! the episodes in which the region (the well-clear volume, a [`Region`]) is violated, exact
//! for motion that is linear between samples (each interval's relative velocity is its
//! displacement over its length).

use glam::DVec3;
use smallvec::SmallVec;

use crate::daa::well_clear::{Relative, Volume};

/// What a pair must stay out of: the well-clear volume ([`Volume`]), a separation minimum
/// ([`crate::daa::separation::Separation`]).
pub trait Region {
    /// The times within `[from_s, to_s]` at which `rel` (moving linearly) is inside, if any.
    fn interval(&self, rel: &Relative, from_s: f64, to_s: f64) -> Option<(f64, f64)>;
    /// True when `rel` surely stays outside throughout `[0, dt_s]` (false says nothing).
    fn surely_clear(&self, rel: &Relative, dt_s: f64) -> bool;
    /// The distance modified tau is measured with (the volume's DTHR), if the region has one.
    fn tau_dthr_m(&self) -> Option<f64>;
}

impl Region for Volume {
    fn interval(&self, rel: &Relative, from_s: f64, to_s: f64) -> Option<(f64, f64)> {
        Volume::interval(self, rel, from_s, to_s)
    }

    fn surely_clear(&self, rel: &Relative, dt_s: f64) -> bool {
        Volume::surely_clear(self, rel, dt_s)
    }

    fn tau_dthr_m(&self) -> Option<f64> {
        Some(self.dthr_m)
    }
}

/// One loss of well clear.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Episode {
    /// When well clear was lost, seconds.
    pub start_t_s: f64,
    /// When it was regained, seconds (`None` while it lasts).
    pub end_t_s: Option<f64>,
    /// Horizontal separation when it was lost, metres.
    pub lost_horizontal_m: f64,
    /// Vertical separation when it was lost, metres.
    pub lost_vertical_m: f64,
    /// Least horizontal separation in it (exact for motion linear between samples), metres.
    pub min_horizontal_m: f64,
    /// Least vertical separation in it (exact for motion linear between samples), metres.
    pub min_vertical_m: f64,
}

impl Episode {
    /// How long it lasted, seconds (to `now_t_s` while it lasts).
    pub fn duration_s(&self, now_t_s: f64) -> f64 {
        self.end_t_s.unwrap_or(now_t_s) - self.start_t_s
    }
}

/// A change of a pair's state within one interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change {
    /// Well clear was lost at this time.
    Lost {
        /// When, seconds.
        t_s: f64,
    },
    /// Well clear was regained at this time, after an episode of this length.
    Regained {
        /// When, seconds.
        t_s: f64,
        /// How long the episode lasted, seconds.
        duration_s: f64,
    },
}

/// One pair's well-clear history.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PairLog {
    /// Its episodes, in time order (the last may be open).
    pub episodes: Vec<Episode>,
    /// Least modified tau (for the volume's DTHR) seen at any sample while closing, seconds.
    pub min_tau_mod_s: Option<f64>,
    /// The last time observed, seconds.
    pub last_t_s: f64,
}

impl PairLog {
    /// Whether well clear is lost now.
    pub fn open(&self) -> bool {
        self.episodes.last().is_some_and(|e| e.end_t_s.is_none())
    }

    /// Total time without well clear, seconds.
    pub fn duration_s(&self) -> f64 {
        self.episodes
            .iter()
            .map(|e| e.duration_s(self.last_t_s))
            .sum()
    }

    /// Fold in one interval from `t0_s` to `t1_s` in which the relative position (either
    /// sign) moves linearly from `rel0_enu_m` to `rel1_enu_m`; the changes within it.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::daa::episodes::{Change, PairLog};
    /// use savsim_core::daa::well_clear::Volume;
    /// let cylinder = Volume { dthr_m: 600.0, zthr_m: 100.0, tthr_s: 0.0, tcoa_s: 0.0 };
    /// let mut log = PairLog::default();
    /// // Closing at 100 m/s from 3000 m: lost at 24 s, regained at 36 s, within one 60 s step.
    /// let changes = log.observe(&cylinder, 0.0, 60.0, DVec3::new(3000.0, 0.0, 0.0), DVec3::new(-3000.0, 0.0, 0.0));
    /// assert_eq!(changes.len(), 2);
    /// assert!(matches!(changes[0], Change::Lost { t_s } if (t_s - 24.0).abs() < 1e-9));
    /// assert!((log.duration_s() - 12.0).abs() < 1e-9);
    /// // Lost at 600 m; the least separation in it, 0 m at 30 s, between the samples.
    /// let e = &log.episodes[0];
    /// assert!((e.lost_horizontal_m - 600.0).abs() < 1e-9 && e.min_horizontal_m < 1e-9);
    /// ```
    pub fn observe(
        &mut self,
        volume: &impl Region,
        t0_s: f64,
        t1_s: f64,
        rel0_enu_m: DVec3,
        rel1_enu_m: DVec3,
    ) -> SmallVec<[Change; 2]> {
        let mut changes = SmallVec::new();
        let dt = t1_s - t0_s;
        if dt.is_nan() || dt <= 0.0 {
            return changes;
        }
        let rel = Relative {
            s_m: rel0_enu_m,
            v_mps: (rel1_enu_m - rel0_enu_m) / dt,
        };
        let at_end = Relative {
            s_m: rel1_enu_m,
            ..rel
        };
        if let Some(tau) = volume
            .tau_dthr_m()
            .and_then(|dthr_m| at_end.tau_mod_s(dthr_m))
        {
            self.min_tau_mod_s = Some(self.min_tau_mod_s.map_or(tau, |m| m.min(tau)));
        }
        self.last_t_s = t1_s;
        if !self.open() && volume.surely_clear(&rel, dt) {
            return changes;
        }
        match volume.interval(&rel, 0.0, dt) {
            None => self.close(t0_s, &mut changes),
            Some((a, b)) => {
                if self.open() && a > 0.0 {
                    self.close(t0_s, &mut changes);
                }
                if !self.open() {
                    self.start(t0_s + a, rel0_enu_m.lerp(rel1_enu_m, a / dt), &mut changes);
                }
                self.note_least(&rel, a, b);
                if b < dt {
                    self.close(t0_s + b, &mut changes);
                }
            }
        }
        changes
    }

    fn start(&mut self, t_s: f64, rel: DVec3, changes: &mut SmallVec<[Change; 2]>) {
        let (horizontal, vertical) = (rel.truncate().length(), rel.z.abs());
        self.episodes.push(Episode {
            start_t_s: t_s,
            end_t_s: None,
            lost_horizontal_m: horizontal,
            lost_vertical_m: vertical,
            min_horizontal_m: horizontal,
            min_vertical_m: vertical,
        });
        changes.push(Change::Lost { t_s });
    }

    /// Fold into the open episode the least horizontal and vertical separations of `s + t v`
    /// for `t` in `[a, b]` (each at its own closest instant: linear motion).
    fn note_least(&mut self, rel: &Relative, a: f64, b: f64) {
        let (s, v) = (rel.s_m, rel.v_mps);
        let vh = v.truncate().length_squared();
        let th = if vh > 0.0 {
            -s.truncate().dot(v.truncate()) / vh
        } else {
            a
        };
        let tz = if v.z != 0.0 { -s.z / v.z } else { a };
        let horizontal = (s + v * th.clamp(a, b)).truncate().length();
        let vertical = (s.z + v.z * tz.clamp(a, b)).abs();
        if let Some(e) = self.episodes.last_mut().filter(|e| e.end_t_s.is_none()) {
            e.min_horizontal_m = e.min_horizontal_m.min(horizontal);
            e.min_vertical_m = e.min_vertical_m.min(vertical);
        }
    }

    fn close(&mut self, t_s: f64, changes: &mut SmallVec<[Change; 2]>) {
        if let Some(e) = self.episodes.last_mut().filter(|e| e.end_t_s.is_none()) {
            e.end_t_s = Some(t_s);
            changes.push(Change::Regained {
                t_s,
                duration_s: t_s - e.start_t_s,
            });
        }
    }
}

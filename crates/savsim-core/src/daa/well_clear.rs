//! DO-365's well clear (DWC) for two aircraft in linear relative motion: the predicate at an
//! instant and the interval of time in which it holds.
//!
//! With `s` the horizontal position of the ownship relative to the intruder and `v` their
//! relative horizontal velocity (both ENU metres, m/s), and `sz`, `vz` the vertical ones:
//!
//! - horizontal violation: `|s| <= DTHR`, or the horizontal miss distance
//!   `dcpa <= DTHR` with `0 <= tau_mod <= TTHR`, where `tau_mod = (DTHR^2 - |s|^2) / (s . v)`
//!   while closing (`s . v < 0`);
//! - vertical violation: `|sz| <= ZTHR`, or `0 <= tcoa <= TCOA` with `tcoa = -sz / vz` while
//!   closing vertically (`sz vz < 0`);
//! - loss of well clear: both at once.
//!
//! The interval is solved in closed form (quadratic in time for the horizontal part, linear for
//! the vertical), so that a step of any length is exact.

/// Metres in a foot.
pub const FT_M: f64 = 0.3048;
/// Metres in a nautical mile.
pub const NMI_M: f64 = 1852.0;

/// A well-clear volume: DTHR, ZTHR, TTHR and TCOA.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Volume {
    /// Horizontal distance threshold (DTHR), metres.
    pub dthr_m: f64,
    /// Vertical distance threshold (ZTHR), metres.
    pub zthr_m: f64,
    /// Modified-tau threshold (TTHR), seconds.
    pub tthr_s: f64,
    /// Time-to-co-altitude threshold (TCOA), seconds.
    pub tcoa_s: f64,
}

impl Volume {
    /// DO-365 Phase I (en route): 0.66 nmi, 450 ft, 35 s, 0 s.
    pub const DO_365_PHASE_I: Volume = Volume {
        dthr_m: 0.66 * NMI_M,
        zthr_m: 450.0 * FT_M,
        tthr_s: 35.0,
        tcoa_s: 0.0,
    };
    /// DO-365B Phase II (terminal): 1500 ft, 450 ft, 0 s, 0 s.
    pub const DO_365_PHASE_II: Volume = Volume {
        dthr_m: 1500.0 * FT_M,
        zthr_m: 450.0 * FT_M,
        tthr_s: 0.0,
        tcoa_s: 0.0,
    };
    /// DO-365B against non-cooperative traffic: 2200 ft, 450 ft, 0 s, 0 s.
    pub const DO_365_NON_COOPERATIVE: Volume = Volume {
        dthr_m: 2200.0 * FT_M,
        zthr_m: 450.0 * FT_M,
        tthr_s: 0.0,
        tcoa_s: 0.0,
    };
    /// Small UAS (ASTM F3442, UK CAA CAP 3015): a cylinder of 2000 ft and +/-250 ft.
    pub const SMALL_UAS: Volume = Volume {
        dthr_m: 2000.0 * FT_M,
        zthr_m: 250.0 * FT_M,
        tthr_s: 0.0,
        tcoa_s: 0.0,
    };

    /// The volume named `name` (`small-uas`, `phase-1`, `phase-2`, `non-coop`), or a custom one
    /// as `DTHR_M,ZTHR_M,TTHR_S,TCOA_S`; `None` when it is neither or a number is negative or
    /// not finite.
    ///
    /// ```
    /// use savsim_core::daa::well_clear::Volume;
    /// assert_eq!(Volume::parse("small-uas"), Some(Volume::SMALL_UAS));
    /// let v = Volume::parse("100,30,0,0").unwrap();
    /// assert_eq!((v.dthr_m, v.zthr_m), (100.0, 30.0));
    /// assert_eq!(Volume::parse("100,-1,0,0"), None);
    /// ```
    pub fn parse(name: &str) -> Option<Volume> {
        match name {
            "small-uas" => return Some(Self::SMALL_UAS),
            "phase-1" => return Some(Self::DO_365_PHASE_I),
            "phase-2" => return Some(Self::DO_365_PHASE_II),
            "non-coop" => return Some(Self::DO_365_NON_COOPERATIVE),
            _ => {}
        }
        let numbers: Vec<f64> = name
            .split(',')
            .map(|x| x.trim().parse::<f64>().ok())
            .collect::<Option<_>>()?;
        let [dthr_m, zthr_m, tthr_s, tcoa_s] = numbers[..] else {
            return None;
        };
        let valid = numbers.iter().all(|x| x.is_finite() && *x >= 0.0);
        valid.then_some(Volume {
            dthr_m,
            zthr_m,
            tthr_s,
            tcoa_s,
        })
    }

    /// Whether the relative state violates well clear at this instant.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::daa::well_clear::{Relative, Volume};
    /// // Closing head on at 50 m/s, level, DTHR 500 m, TTHR 20 s.
    /// let v = Volume { dthr_m: 500.0, zthr_m: 100.0, tthr_s: 20.0, tcoa_s: 0.0 };
    /// let at = |x: f64| Relative { s_m: DVec3::new(x, 0.0, 0.0), v_mps: DVec3::new(-50.0, 0.0, 0.0) };
    /// // At 1000 m, tau_mod = (500^2 - 1000^2) / (1000 * -50) = 15 s <= 20 s: violated.
    /// assert!(v.violated(&at(1000.0)));
    /// // At 1500 m, tau_mod = 26.7 s: not.
    /// assert!(!v.violated(&at(1500.0)));
    /// ```
    pub fn violated(&self, rel: &Relative) -> bool {
        self.horizontal(rel) && self.vertical(rel)
    }

    /// The horizontal part of the predicate.
    pub fn horizontal(&self, rel: &Relative) -> bool {
        let (s, v) = (rel.s_m.truncate(), rel.v_mps.truncate());
        let d2 = self.dthr_m * self.dthr_m;
        if s.length_squared() <= d2 {
            return true;
        }
        let sv = s.dot(v);
        if sv >= 0.0 {
            return false;
        }
        let dcpa = rel.dcpa_m();
        let tau_mod = (d2 - s.length_squared()) / sv;
        dcpa <= self.dthr_m && (0.0..=self.tthr_s).contains(&tau_mod)
    }

    /// The vertical part of the predicate.
    pub fn vertical(&self, rel: &Relative) -> bool {
        let (sz, vz) = (rel.s_m.z, rel.v_mps.z);
        if sz.abs() <= self.zthr_m {
            return true;
        }
        sz * vz < 0.0 && -sz / vz <= self.tcoa_s
    }

    /// The times in `[from_s, to_s]` (seconds from the state's instant) during which the
    /// relative motion `s + t v` violates well clear, as `(time_in, time_out)`; `None` when it
    /// never does in that span.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::daa::well_clear::{Relative, Volume};
    /// // Head on at 100 m/s closing from 3000 m, level; a 600 m cylinder (TTHR 0): inside from
    /// // 24 s (600 m left) to 36 s.
    /// let v = Volume { dthr_m: 600.0, zthr_m: 100.0, tthr_s: 0.0, tcoa_s: 0.0 };
    /// let rel = Relative { s_m: DVec3::new(3000.0, 0.0, 0.0), v_mps: DVec3::new(-100.0, 0.0, 0.0) };
    /// let (t_in, t_out) = v.interval(&rel, 0.0, 180.0).unwrap();
    /// assert!((t_in - 24.0).abs() < 1e-9 && (t_out - 36.0).abs() < 1e-9);
    /// // With TTHR 30 s, from 5000 m: from when tau_mod reaches 30 s (at 3000 m it is 28.8 s:
    /// // already violated).
    /// let v = Volume { tthr_s: 30.0, ..v };
    /// let far = Relative { s_m: DVec3::new(5000.0, 0.0, 0.0), ..rel };
    /// let (t_in, _) = v.interval(&far, 0.0, 180.0).unwrap();
    /// let s = 5000.0 - 100.0 * t_in;
    /// assert!(((s * s - 600.0 * 600.0) / (100.0 * s) - 30.0).abs() < 1e-9);
    /// assert_eq!(v.interval(&rel, 0.0, 180.0).unwrap().0, 0.0);
    /// ```
    pub fn interval(&self, rel: &Relative, from_s: f64, to_s: f64) -> Option<(f64, f64)> {
        let (v_lo, v_hi) = self.vertical_span(rel.s_m.z, rel.v_mps.z)?;
        let (h_lo, h_hi) = self.horizontal_span(rel)?;
        let lo = v_lo.max(h_lo).max(from_s);
        let hi = v_hi.min(h_hi).min(to_s);
        (lo <= hi).then_some((lo, hi))
    }

    /// True when well clear surely holds throughout `[0, dt_s]` (a cheap bound, for the many
    /// pairs far apart): the least horizontal separation over it exceeds the largest at which
    /// the horizontal predicate can hold (`|s|^2 + TTHR (s . v) <= DTHR^2` needs
    /// `|s|^2 - TTHR |s| |v| <= DTHR^2`). False says nothing.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::daa::well_clear::{Relative, Volume};
    /// let far = Relative { s_m: DVec3::new(5000.0, 0.0, 0.0), v_mps: DVec3::new(-10.0, 0.0, 0.0) };
    /// assert!(Volume::SMALL_UAS.surely_clear(&far, 1.0));
    /// assert!(!Volume::SMALL_UAS.surely_clear(&far, 600.0));
    /// ```
    pub fn surely_clear(&self, rel: &Relative, dt_s: f64) -> bool {
        let (s, v) = (rel.s_m.truncate(), rel.v_mps.truncate());
        let speed = v.length();
        let tv = self.tthr_s * speed;
        let reach = 0.5 * (tv + (tv * tv + 4.0 * self.dthr_m * self.dthr_m).sqrt());
        let least = (s + v * (0.5 * dt_s)).length() - 0.5 * dt_s * speed;
        least > reach
    }

    /// The times (unbounded) during which the vertical predicate holds.
    fn vertical_span(&self, sz: f64, vz: f64) -> Option<(f64, f64)> {
        if vz == 0.0 {
            return (sz.abs() <= self.zthr_m).then_some((f64::NEG_INFINITY, f64::INFINITY));
        }
        // Co-altitude at t_co; within ZTHR for |t - t_co| <= ZTHR / |vz|, and TCOA ahead of it.
        let t_co = -sz / vz;
        let band = self.zthr_m / vz.abs();
        Some((t_co - band.max(self.tcoa_s), t_co + band))
    }

    /// The times (unbounded) during which the horizontal predicate holds: from the earlier
    /// root of `|s(t)|^2 + TTHR (s(t) . v) = DTHR^2` (tau_mod reaching TTHR) to leaving the
    /// DTHR circle; empty when the miss distance exceeds DTHR.
    fn horizontal_span(&self, rel: &Relative) -> Option<(f64, f64)> {
        let (s, v) = (rel.s_m.truncate(), rel.v_mps.truncate());
        let d2 = self.dthr_m * self.dthr_m;
        let a = v.length_squared();
        if a == 0.0 {
            return (s.length_squared() <= d2).then_some((f64::NEG_INFINITY, f64::INFINITY));
        }
        if rel.dcpa_m() > self.dthr_m {
            return None;
        }
        let sv = s.dot(v);
        let exit = root(a, 2.0 * sv, s.length_squared() - d2, true)?;
        let entry = root(
            a,
            2.0 * sv + self.tthr_s * a,
            s.length_squared() + self.tthr_s * sv - d2,
            false,
        )?;
        Some((entry, exit))
    }
}

/// What `--well-clear` and the `well_clear` column accept.
pub const SETTING_HELP: &str = "give small-uas, phase-1, phase-2, non-coop, \
    DTHR_M,ZTHR_M,TTHR_S,TCOA_S (non-negative) or none";

/// The well-clear volume a name gives (`Some(None)` for `none`: not judged), `None` for a name
/// that is none of them.
///
/// ```
/// use savsim_core::daa::well_clear::setting;
/// assert_eq!(setting("none"), Some(None));
/// assert!(setting("phase-1").unwrap().is_some());
/// assert_eq!(setting("nonsense"), None);
/// ```
pub fn setting(name: &str) -> Option<Option<Volume>> {
    match name.trim() {
        "none" => Some(None),
        other => Volume::parse(other).map(Some),
    }
}

/// A root of `a t^2 + b t + c` (a > 0): the larger when `larger`, else the smaller; `None`
/// when there is none (a discriminant a rounding below zero counts as a double root).
fn root(a: f64, b: f64, c: f64, larger: bool) -> Option<f64> {
    let disc = b * b - 4.0 * a * c;
    if disc < -1e-12 * b * b {
        return None;
    }
    let q = disc.max(0.0).sqrt();
    Some(if larger {
        (-b + q) / (2.0 * a)
    } else {
        (-b - q) / (2.0 * a)
    })
}

/// The state of an ownship relative to one intruder: positions and velocities as ownship minus
/// intruder, ENU (z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relative {
    /// Ownship position minus intruder position, ENU metres.
    pub s_m: glam::DVec3,
    /// Ownship velocity minus intruder velocity, ENU m/s.
    pub v_mps: glam::DVec3,
}

impl Relative {
    /// Time to the horizontal closest point of approach, seconds (negative when diverging; 0
    /// with no relative horizontal motion).
    pub fn tcpa_s(&self) -> f64 {
        let (s, v) = (self.s_m.truncate(), self.v_mps.truncate());
        let vv = v.length_squared();
        if vv == 0.0 {
            0.0
        } else {
            -s.dot(v) / vv
        }
    }

    /// Horizontal distance at the closest point of approach of the infinite line, metres.
    pub fn dcpa_m(&self) -> f64 {
        let (s, v) = (self.s_m.truncate(), self.v_mps.truncate());
        (s + v * self.tcpa_s()).length()
    }

    /// Modified tau for distance `dthr_m`, seconds: `(DTHR^2 - |s|^2) / (s . v)` while closing
    /// and outside DTHR; `None` otherwise.
    pub fn tau_mod_s(&self, dthr_m: f64) -> Option<f64> {
        let (s, v) = (self.s_m.truncate(), self.v_mps.truncate());
        let sv = s.dot(v);
        let num = dthr_m * dthr_m - s.length_squared();
        (num < 0.0 && sv < 0.0).then(|| num / sv)
    }

    /// Time to co-altitude, seconds (`-sz / vz`); `None` with no relative vertical motion
    /// (co-altitude then is always or never).
    pub fn tcoa_s(&self) -> Option<f64> {
        let (sz, vz) = (self.s_m.z, self.v_mps.z);
        (vz.abs() > 1e-12).then(|| -sz / vz)
    }

    /// Horizontal miss distance within `lookahead_s`: the horizontal separation at the closest
    /// point of approach when closing, cut at the lookahead; the current one when not.
    pub fn hmd_m(&self, lookahead_s: f64) -> f64 {
        let (s, v) = (self.s_m.truncate(), self.v_mps.truncate());
        let t = if s.dot(v) < 0.0 {
            self.tcpa_s().min(lookahead_s)
        } else {
            0.0
        };
        (s + v * t).length()
    }

    /// Vertical miss distance within `lookahead_s`: 0 when co-altitude comes within it, the
    /// separation at the lookahead when converging more slowly, the current one when not.
    pub fn vmd_m(&self, lookahead_s: f64) -> f64 {
        let (sz, vz) = (self.s_m.z, self.v_mps.z);
        if sz * vz < 0.0 {
            if -sz / vz <= lookahead_s {
                0.0
            } else {
                (sz + lookahead_s * vz).abs()
            }
        } else {
            sz.abs()
        }
    }
}

#[cfg(test)]
mod bound_tests {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;

    proptest! {
        /// The cheap bound never says clear where the exact interval has a loss.
        #[test]
        fn surely_clear_is_never_wrong(
            sx in -3000.0..3000.0f64, sy in -3000.0..3000.0f64, sz in -300.0..300.0f64,
            vx in -150.0..150.0f64, vy in -150.0..150.0f64, vz in -20.0..20.0f64,
            dt in 0.01..30.0f64, which in 0usize..4,
        ) {
            let volume = [
                Volume::SMALL_UAS,
                Volume::DO_365_PHASE_I,
                Volume::DO_365_PHASE_II,
                Volume::DO_365_NON_COOPERATIVE,
            ][which];
            let rel = Relative { s_m: DVec3::new(sx, sy, sz), v_mps: DVec3::new(vx, vy, vz) };
            if volume.surely_clear(&rel, dt) {
                prop_assert_eq!(volume.interval(&rel, 0.0, dt), None);
            }
        }
    }
}

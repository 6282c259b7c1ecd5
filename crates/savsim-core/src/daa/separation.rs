//! A separation minimum: a sphere of `minimum_m` about each vehicle's reference point, lost
//! while two are strictly nearer than it (a drone show's or a swarm's own rule, `--separation-m`:
//! no standard's volume). Exact for motion that is linear between samples, as well clear is.

use crate::daa::episodes::Region;
use crate::daa::well_clear::Relative;

/// A separation minimum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separation {
    /// Two reference points nearer than this (3D), metres, have lost separation.
    pub minimum_m: f64,
}

impl Region for Separation {
    /// The times within `[from_s, to_s]` at which `|s + v t| < minimum_m` (an open interval,
    /// returned closed; none when the two only touch the sphere).
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::daa::episodes::Region;
    /// use savsim_core::daa::separation::Separation;
    /// use savsim_core::daa::well_clear::Relative;
    /// // 10 m apart, closing at 1 m/s, passing 3 m abeam: inside 5 m for 8 s around t = 10.
    /// let rel = Relative { s_m: DVec3::new(-10.0, 3.0, 0.0), v_mps: DVec3::new(1.0, 0.0, 0.0) };
    /// let (a, b) = Separation { minimum_m: 5.0 }.interval(&rel, 0.0, 100.0).unwrap();
    /// assert!((a - 6.0).abs() < 1e-12 && (b - 14.0).abs() < 1e-12);
    /// assert!(Separation { minimum_m: 3.0 }.interval(&rel, 0.0, 100.0).is_none());
    /// ```
    fn interval(&self, rel: &Relative, from_s: f64, to_s: f64) -> Option<(f64, f64)> {
        let (s, v) = (rel.s_m, rel.v_mps);
        let m2 = self.minimum_m * self.minimum_m;
        let vv = v.length_squared();
        let (lo, hi) = if vv == 0.0 {
            if s.length_squared() >= m2 {
                return None;
            }
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            // |s + v t|^2 = m^2: vv t^2 + 2 (s.v) t + |s|^2 - m^2 = 0.
            let half_b = s.dot(v);
            let disc = half_b * half_b - vv * (s.length_squared() - m2);
            if disc <= 0.0 {
                return None;
            }
            let root = disc.sqrt();
            ((-half_b - root) / vv, (-half_b + root) / vv)
        };
        let (lo, hi) = (lo.max(from_s), hi.min(to_s));
        (lo < hi || (lo == hi && (s + v * lo).length_squared() < m2)).then_some((lo, hi))
    }

    /// True when the two stay at least `minimum_m` apart throughout `[0, dt_s]`: their least
    /// distance over it (linear motion) is not under the minimum.
    fn surely_clear(&self, rel: &Relative, dt_s: f64) -> bool {
        let (s, v) = (rel.s_m, rel.v_mps);
        let vv = v.length_squared();
        let t = if vv > 0.0 {
            (-s.dot(v) / vv).clamp(0.0, dt_s)
        } else {
            0.0
        };
        (s + v * t).length() >= self.minimum_m
    }

    fn tau_dthr_m(&self) -> Option<f64> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// The interval's ends against the distance sampled every millisecond, over many passes.
    #[test]
    fn the_interval_is_where_the_sampled_distance_is_under_the_minimum() {
        let sep = Separation { minimum_m: 3.0 };
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for _ in 0..200 {
            let rel = Relative {
                s_m: DVec3::new(10.0 * next(), 10.0 * next(), 3.0 * next()),
                v_mps: DVec3::new(4.0 * next(), 4.0 * next(), next()),
            };
            let inside: Vec<f64> = (0..=5000)
                .map(|k| f64::from(k) * 1e-3)
                .filter(|&t| (rel.s_m + rel.v_mps * t).length() < 3.0)
                .collect();
            match sep.interval(&rel, 0.0, 5.0) {
                None => assert!(inside.is_empty(), "{rel:?}"),
                Some((a, b)) => {
                    let (first, last) = (inside[0], inside[inside.len() - 1]);
                    assert!(
                        first - a < 1.001e-3 && first >= a - 1e-12,
                        "{rel:?} {a} {first}"
                    );
                    assert!(
                        b - last < 1.001e-3 && last <= b + 1e-12,
                        "{rel:?} {b} {last}"
                    );
                }
            }
            assert_eq!(sep.surely_clear(&rel, 5.0), inside.is_empty(), "{rel:?}");
        }
    }
}

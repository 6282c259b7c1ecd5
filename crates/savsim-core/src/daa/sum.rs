//! DAIDALUS's sensor uncertainty mitigation (SUM): each aircraft's state carries 1-sigma
//! errors (the `.daa` columns `s_EW_std, s_NS_std, s_EN_std, sz_std, v_EW_std, v_NS_std,
//! v_EN_std, vz_std`), a level whose detector is `WCV_TAUMOD_SUM` tests the well-clear volume
//! against the worst relative state those errors allow, scaled by z-scores, and the alerting
//! times of DO-365B's SUM alerters are 5 s shorter (in their configuration).
//!
//! - Per aircraft: the horizontal errors are the square root of the largest eigenvalue of the
//!   2x2 covariance (`s_EN_std` is the signed square root of the covariance); the vertical ones
//!   as given.
//! - Relative errors add the ownship's and the intruder's, times their z-score: `h_pos`,
//!   `v_pos`, `v_vel`, and for the horizontal velocity a z-score from `h_vel_z_score_max` at
//!   range 0 down to `h_vel_z_score_min` at `h_vel_z_distance` (the range less the position
//!   error), linearly.
//! - The violation interval ([`interval`]): horizontally, entry at the earlier of the nominal
//!   entry and the entry of the worst pair of relative position and velocity within the error
//!   disks (as head-on as their tangent cones allow), exit when the range reaches DTHR plus the
//!   position error plus the velocity error times the time; vertically, the union over the
//!   boxes of altitude and vertical speed; the two intersected. All four errors 0: the nominal
//!   interval. The numbers follow DAIDALUS's rounding rules ([`almost_equals`]), so that the
//!   alert levels are the same at every step.

use glam::{DVec2, DVec3};

use crate::daa::well_clear::Volume;

/// One aircraft's 1-sigma state errors, SI units.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Uncertainty {
    /// East position sigma, metres.
    pub s_ew_m: f64,
    /// North position sigma, metres.
    pub s_ns_m: f64,
    /// East-north position covariance's signed square root, metres.
    pub s_en_m: f64,
    /// Altitude sigma, metres.
    pub sz_m: f64,
    /// East velocity sigma, m/s.
    pub v_ew_mps: f64,
    /// North velocity sigma, m/s.
    pub v_ns_mps: f64,
    /// East-north velocity covariance's signed square root, m/s.
    pub v_en_mps: f64,
    /// Vertical speed sigma, m/s.
    pub vz_mps: f64,
}

/// The largest eigenvalue's square root of the covariance [[x^2, c], [c, y^2]], c = sign(xy)
/// xy^2: the 1-sigma semi-major axis.
fn semi_major(x: f64, y: f64, xy: f64) -> f64 {
    let (a, b) = (x * x, y * y);
    let c = sign(xy) * xy * xy;
    let m = (a + b) / 2.0;
    let lambda = m + sqrt_safe(m * m - (a * b - c * c));
    sqrt_safe(lambda)
}

impl Uncertainty {
    /// The horizontal position error (semi-major axis), metres.
    ///
    /// ```
    /// use savsim_core::daa::sum::Uncertainty;
    /// let u = Uncertainty { s_ew_m: 3.0, s_ns_m: 4.0, ..Uncertainty::default() };
    /// assert_eq!(u.position_error_m(), 4.0);
    /// ```
    pub fn position_error_m(&self) -> f64 {
        semi_major(self.s_ew_m, self.s_ns_m, self.s_en_m)
    }

    /// The horizontal velocity error (semi-major axis), m/s.
    pub fn velocity_error_mps(&self) -> f64 {
        semi_major(self.v_ew_mps, self.v_ns_mps, self.v_en_mps)
    }
}

/// The z-scores that scale the errors (DAIDALUS's `h_pos_z_score` ... `v_vel_z_score`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ZScores {
    /// Horizontal position.
    pub h_pos: f64,
    /// Horizontal velocity at `h_vel_distance_m` and beyond.
    pub h_vel_min: f64,
    /// Horizontal velocity at range 0.
    pub h_vel_max: f64,
    /// The range over which the velocity z-score goes from max to min, metres.
    pub h_vel_distance_m: f64,
    /// Vertical position.
    pub v_pos: f64,
    /// Vertical speed.
    pub v_vel: f64,
}

/// Relative errors, scaled: horizontal position (m), vertical position (m), horizontal
/// velocity (m/s), vertical speed (m/s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Errors {
    /// Horizontal position, metres.
    pub s_m: f64,
    /// Vertical position, metres.
    pub sz_m: f64,
    /// Horizontal velocity, m/s.
    pub v_mps: f64,
    /// Vertical speed, m/s.
    pub vz_mps: f64,
}

impl Errors {
    /// True when every error is 0 (then detection is nominal).
    pub fn are_zero(&self) -> bool {
        self.s_m == 0.0 && self.sz_m == 0.0 && self.v_mps == 0.0 && self.vz_mps == 0.0
    }
}

impl ZScores {
    /// The relative errors of `own` and `intruder` `range_m` apart horizontally.
    pub fn errors(&self, own: &Uncertainty, intruder: &Uncertainty, range_m: f64) -> Errors {
        let s_m = self.h_pos * (own.position_error_m() + intruder.position_error_m());
        let r = (range_m - s_m).max(0.0);
        let z_v = if r >= self.h_vel_distance_m {
            self.h_vel_min
        } else {
            let f = r / self.h_vel_distance_m;
            (1.0 - f) * self.h_vel_max + f * self.h_vel_min
        };
        Errors {
            s_m,
            sz_m: self.v_pos * (own.sz_m + intruder.sz_m),
            v_mps: z_v * (own.velocity_error_mps() + intruder.velocity_error_mps()),
            vz_mps: self.v_vel * (own.vz_mps + intruder.vz_mps),
        }
    }
}

/// Errors below this are taken as this (DAIDALUS's floor), SI units.
const MIN_ERROR: f64 = 0.001;

/// An interval of violation, raw ends: a conflict when `almost_less(t_in, t_out)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loss {
    /// Entry, seconds.
    pub t_in: f64,
    /// Exit, seconds.
    pub t_out: f64,
}

impl Loss {
    /// No violation.
    pub const EMPTY: Loss = Loss {
        t_in: f64::INFINITY,
        t_out: f64::NEG_INFINITY,
    };

    /// Whether it is a violation.
    pub fn conflict(&self) -> bool {
        almost_less(self.t_in, self.t_out)
    }

    /// Its entry, `+inf` when it is not a violation.
    pub fn entry(&self) -> f64 {
        if self.conflict() {
            self.t_in
        } else {
            f64::INFINITY
        }
    }
}

/// The violation of `volume` between times `b` and `t` (seconds from now) by the relative
/// state `s`, `v` (ownship minus intruder: position, metres; velocity, m/s; z up) under the
/// relative `errors`. All errors 0: `None` (the caller takes the nominal interval).
pub fn interval(
    volume: &Volume,
    s: DVec3,
    v: DVec3,
    errors: Errors,
    b: f64,
    t: f64,
) -> Option<Loss> {
    if errors.are_zero() {
        return None;
    }
    let e = Errors {
        s_m: errors.s_m.max(MIN_ERROR),
        sz_m: errors.sz_m.max(MIN_ERROR),
        v_mps: errors.v_mps.max(MIN_ERROR),
        vz_mps: errors.vz_mps.max(MIN_ERROR),
    };
    let vertical = vertical_sum(volume, b, t, s.z, v.z, e.sz_m, e.vz_mps);
    if !vertical.conflict() {
        return Some(vertical);
    }
    let horizontal = horizontal_sum(volume, s.truncate(), v.truncate(), e.s_m, e.v_mps, t);
    if !horizontal.conflict() {
        return Some(horizontal);
    }
    if horizontal.t_out < b {
        return Some(Loss::EMPTY);
    }
    Some(Loss {
        t_in: vertical.t_in.max(horizontal.t_in),
        t_out: vertical.t_out.min(horizontal.t_out),
    })
}

// ---- The horizontal part. ----

/// Whether the nominal horizontal predicate holds now.
fn hwcv(vol: &Volume, s: DVec2, v: DVec2) -> bool {
    if s.length() <= vol.dthr_m {
        return true;
    }
    let sv = s.dot(v);
    let tau = if sv < 0.0 {
        (vol.dthr_m * vol.dthr_m - s.length_squared()) / sv
    } else {
        -1.0
    };
    let tcpa = if v.length_squared() == 0.0 {
        0.0
    } else {
        -sv / v.length_squared()
    };
    let dcpa = (s + v * tcpa).length();
    dcpa <= vol.dthr_m && 0.0 <= tau && tau <= vol.tthr_s
}

/// The nominal horizontal interval (TAUMOD entry, DTHR exit) within `[0, t]`, raw ends.
fn nominal_horizontal(vol: &Volume, t: f64, s: DVec2, v: DVec2) -> Loss {
    let d2 = vol.dthr_m * vol.dthr_m;
    let sq_s = s.length_squared();
    let sq_v = v.length_squared();
    let sv = s.dot(v);
    let exit = || root2b(sq_v, sv, sq_s - d2, 1);
    if almost_equals(sq_v, 0.0) && sq_s <= d2 {
        return Loss {
            t_in: 0.0,
            t_out: t,
        };
    }
    if sq_s <= d2 {
        return Loss {
            t_in: 0.0,
            t_out: t.min(exit()),
        };
    }
    let a = sq_v;
    let b = 2.0 * sv + vol.tthr_s * sq_v;
    let c = sq_s + vol.tthr_s * sv - d2;
    if sv >= 0.0 || b * b - 4.0 * a * c < 0.0 {
        return Loss {
            t_in: t,
            t_out: 0.0,
        };
    }
    let entry = (-b - (b * b - 4.0 * a * c).sqrt()) / (2.0 * a);
    let cross = s.perp_dot(v);
    if d2 * sq_v - cross * cross >= 0.0 && entry <= t {
        Loss {
            t_in: entry.max(0.0),
            t_out: t.min(exit()),
        }
    } else {
        Loss {
            t_in: t,
            t_out: 0.0,
        }
    }
}

fn hat(u: DVec2) -> DVec2 {
    let n = u.length();
    if n == 0.0 {
        DVec2::ZERO
    } else {
        u / n
    }
}

/// The vector from `p` to the point where the line through `p` touches the circle of radius
/// `d` about the origin, on side `eps` (zero from inside the circle).
fn tangent_line(p: DVec2, d: f64, eps: f64) -> DVec2 {
    let sq = p.length_squared();
    if almost_equals(sq, d * d) {
        return DVec2::new(eps * p.y, -eps * p.x);
    }
    if sq >= d * d {
        let alpha = d * d / sq;
        let beta = d * sqrt_safe(sq - d * d) / sq;
        let q = DVec2::new(
            alpha * p.x + eps * beta * p.y,
            alpha * p.y - eps * beta * p.x,
        );
        if q == DVec2::ZERO {
            DVec2::ZERO
        } else {
            q - p
        }
    } else {
        DVec2::ZERO
    }
}

/// Whether `w` lies between `x` and `y`.
fn in_cone(x: DVec2, y: DVec2, w: DVec2) -> bool {
    let det = |p: DVec2, q: DVec2| p.x * q.y - p.y * q.x;
    det(w, x) * det(y, x) >= 0.0 && det(w, y) * det(y, x) <= 0.0
}

/// The most head-on pair of directions from the position cone (a1, a2) and the velocity cone
/// (b1, b2).
fn best_pair(a1: DVec2, a2: DVec2, b1: DVec2, b2: DVec2) -> (DVec2, DVec2) {
    let same = |m: DVec2| (m, m);
    if in_cone(a1, a2, b1) && in_cone(a1, a2, b2) {
        return same(hat(b1 + b2));
    }
    if in_cone(b1, b2, a1) && in_cone(b1, b2, a2) {
        return same(hat(a1 + a2));
    }
    if in_cone(b1, b2, a1) && in_cone(a1, a2, b1) {
        return same(hat(a1 + b1));
    }
    if in_cone(b1, b2, a1) && in_cone(a1, a2, b2) {
        return same(hat(a1 + b2));
    }
    if in_cone(b1, b2, a2) && in_cone(a1, a2, b1) {
        return same(hat(a2 + b1));
    }
    if in_cone(b1, b2, a2) && in_cone(a1, a2, b2) {
        return same(hat(a2 + b2));
    }
    let pairs = [(a1, b1), (a1, b2), (a2, b1), (a2, b2)];
    let dots = pairs.map(|(a, b)| a.dot(b));
    let mut best = 0;
    for k in 0..4 {
        if dots.iter().all(|&d| dots[k] >= d) {
            best = k;
            break;
        }
    }
    pairs[best]
}

/// The horizontal interval under the position error `se` and velocity error `ve`.
fn horizontal_sum(vol: &Volume, s: DVec2, v: DVec2, se: f64, ve: f64, t: f64) -> Loss {
    let r = vol.dthr_m + se;
    let sq_s = s.length_squared();
    let sq_v = v.length_squared();
    let slow = || {
        let sh = hat(s);
        nominal_horizontal(vol, t, sh * (s.length() - se), -sh * (v.length() + ve))
    };
    let entry = if hwcv(vol, s, v) || sq_s <= r * r {
        0.0
    } else if sq_v <= ve * ve {
        let ee = slow();
        if ee.conflict() {
            ee.t_in
        } else {
            t + 1.0
        }
    } else {
        let a1 = hat(tangent_line(s, se, -1.0));
        let a2 = hat(tangent_line(s, se, 1.0));
        let b1 = hat(tangent_line(-v, ve, -1.0));
        let b2 = hat(tangent_line(-v, ve, 1.0));
        let (p, q) = best_pair(a1, a2, b1, b2);
        let s_star = -p * (s.length() - se);
        let v_star = q * (v.length() + ve);
        if s_star.dot(v_star) < 0.0 {
            nominal_horizontal(vol, t, s, v)
                .entry()
                .min(nominal_horizontal(vol, t, s_star, v_star).entry())
        } else {
            t + 1.0
        }
    };
    let exit = if sq_v <= ve * ve && sq_s <= r * r {
        t
    } else if sq_v <= ve * ve {
        if slow().conflict() {
            t
        } else {
            -1.0
        }
    } else {
        let x = root(sq_v - ve * ve, 2.0 * (s.dot(v) - ve * r), sq_s - r * r, 1);
        if x.is_finite() {
            x
        } else {
            -1.0
        }
    };
    if entry > t || exit < 0.0 || entry > exit {
        Loss::EMPTY
    } else {
        Loss {
            t_in: entry.max(0.0),
            t_out: t.min(exit),
        }
    }
}

// ---- The vertical part. ----

/// The nominal vertical interval (TCOA entry, ZTHR exit) within `[b, t]`, raw ends.
fn nominal_vertical(vol: &Volume, b: f64, t: f64, sz: f64, vz: f64) -> Loss {
    if almost_equals(vz, 0.0) {
        return if sz.abs() <= vol.zthr_m {
            Loss { t_in: b, t_out: t }
        } else {
            Loss { t_in: t, t_out: b }
        };
    }
    let h = vol.zthr_m.max(vz.abs() * vol.tcoa_s);
    let entry = (-sign(vz) * h - sz) / vz;
    let exit = (sign(vz) * vol.zthr_m - sz) / vz;
    if t < entry || exit < b {
        Loss { t_in: t, t_out: b }
    } else {
        Loss {
            t_in: b.max(entry),
            t_out: t.min(exit),
        }
    }
}

/// Climbing or level relative speeds only.
fn vpos(vol: &Volume, t: f64, min_sz: f64, min_vz: f64) -> Loss {
    nominal_vertical(vol, 0.0, t, min_sz, min_vz)
}

/// Descending relative speeds only (compared as raw intervals).
fn vneg(vol: &Volume, t: f64, (min_sz, max_sz): (f64, f64), (min_vz, max_vz): (f64, f64)) -> Loss {
    let e = nominal_vertical(vol, 0.0, t, min_sz, min_vz);
    let x = nominal_vertical(vol, 0.0, t, max_sz, max_vz);
    if e.t_in > e.t_out {
        Loss::EMPTY
    } else if x.t_in > x.t_out {
        Loss {
            t_in: e.t_in,
            t_out: t,
        }
    } else {
        Loss {
            t_in: e.t_in,
            t_out: x.t_out,
        }
    }
}

fn join(only_p: bool, only_n: bool, ip: Loss, in_: Loss) -> Loss {
    if only_p || !in_.conflict() {
        ip
    } else if only_n || !ip.conflict() {
        in_
    } else {
        Loss {
            t_in: ip.t_in.min(in_.t_in),
            t_out: ip.t_out.max(in_.t_out),
        }
    }
}

/// Non-negative altitudes (`min_sz >= 0`).
fn sz_pos(vol: &Volume, t: f64, sz: (f64, f64), (min_vz, max_vz): (f64, f64)) -> Loss {
    let only_p = min_vz >= 0.0;
    let only_n = !only_p && max_vz <= 0.0;
    let ip = if only_n {
        Loss::EMPTY
    } else {
        vpos(vol, t, sz.0, min_vz.max(0.0))
    };
    let in_ = if only_p {
        Loss::EMPTY
    } else {
        vneg(vol, t, sz, (min_vz, max_vz.min(0.0)))
    };
    join(only_p, only_n, ip, in_)
}

fn split(vol: &Volume, t: f64, (min_sz, max_sz): (f64, f64), (min_vz, max_vz): (f64, f64)) -> Loss {
    let only_p = min_sz >= 0.0;
    let only_n = !only_p && max_sz <= 0.0;
    let ip = if only_n {
        Loss::EMPTY
    } else {
        sz_pos(vol, t, (min_sz.max(0.0), max_sz), (min_vz, max_vz))
    };
    let in_ = if only_p {
        Loss::EMPTY
    } else {
        sz_pos(vol, t, (-max_sz.min(0.0), -min_sz), (-max_vz, -min_vz))
    };
    join(only_p, only_n, ip, in_)
}

fn vertical_sum(vol: &Volume, b: f64, t: f64, sz: f64, vz: f64, sze: f64, vze: f64) -> Loss {
    let p = split(vol, t, (sz - sze, sz + sze), (vz - vze, vz + vze));
    if !p.conflict() || p.t_out < b {
        Loss::EMPTY
    } else {
        Loss {
            t_in: b.max(p.t_in),
            t_out: t.min(p.t_out),
        }
    }
}

// ---- DAIDALUS's numeric rules. ----

/// Equal, or within 16348 units in the last place (about 13 decimal digits); two numbers
/// within 1e-13 of 0 are equal to 0; NaN and infinities equal nothing but themselves.
///
/// ```
/// use savsim_core::daa::sum::almost_equals;
/// assert!(almost_equals(1.0, 1.0 + 1e-14));
/// assert!(!almost_equals(1.0, 1.0 + 1e-11));
/// assert!(almost_equals(0.0, 1e-14));
/// ```
pub fn almost_equals(a: f64, b: f64) -> bool {
    if a == b {
        return true;
    }
    if (a == 0.0 || b == 0.0) && a.abs() < 1e-13 && b.abs() < 1e-13 {
        return true;
    }
    if !a.is_finite() || !b.is_finite() {
        return false;
    }
    let lex = |x: f64| {
        let bits = x.to_bits() as i64;
        if bits < 0 {
            i64::MIN.wrapping_sub(bits)
        } else {
            bits
        }
    };
    lex(a).wrapping_sub(lex(b)).wrapping_abs() <= 16_348
}

/// `a < b` and not almost equal.
pub fn almost_less(a: f64, b: f64) -> bool {
    !almost_equals(a, b) && a < b
}

fn sign(x: f64) -> f64 {
    if x >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

fn sqrt_safe(x: f64) -> f64 {
    x.max(0.0).sqrt()
}

/// A root of `a t^2 + b t + c` (`eps` the side), NaN when none.
fn root(a: f64, b: f64, c: f64, eps: i32) -> f64 {
    if a == 0.0 && b == 0.0 {
        return f64::NAN;
    }
    if a == 0.0 {
        return -c / b;
    }
    let (sqb, ac) = (b * b, 4.0 * a * c);
    if almost_equals(sqb, ac) || sqb > ac {
        (-b + f64::from(eps) * sqrt_safe(sqb - ac)) / (2.0 * a)
    } else {
        f64::NAN
    }
}

/// A root of `a t^2 + 2 b t + c` (`eps` the side), NaN when none.
fn root2b(a: f64, b: f64, c: f64, eps: i32) -> f64 {
    if a == 0.0 && b == 0.0 {
        return f64::NAN;
    }
    if a == 0.0 {
        return -c / (2.0 * b);
    }
    let (sqb, ac) = (b * b, a * c);
    if almost_equals(sqb, ac) || sqb > ac {
        (-b + f64::from(eps) * sqrt_safe(sqb - ac)) / a
    } else {
        f64::NAN
    }
}

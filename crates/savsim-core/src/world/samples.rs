//! A track's samples: each position with its attitude and both clocks (a [`TrackSample`]),
//! and a track's short history of them, interpolated between samples and carried ahead of the
//! newest along its velocity ([`History`]).

use std::collections::VecDeque;

use glam::{DMat3, DQuat, DVec3, EulerRot};

use crate::geo::{Geodetic, LocalTangentPlane};

/// Orientation of a body: the rotation from its Forward-Right-Down axes to the scene's ENU axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attitude {
    /// Vehicle clock of the ATTITUDE message, ms (0 when derived from a heading).
    pub time_boot_ms: u32,
    /// Rotation taking body FRD vectors into scene ENU.
    pub enu_from_frd: DQuat,
    /// Body rates (roll, pitch, yaw), rad/s.
    pub body_rates_radps: DVec3,
}

impl Attitude {
    /// The attitude of a body at `position` with MAVLink roll, pitch, yaw (relative to the local
    /// NED frame there), expressed in `plane`'s ENU axes.
    ///
    /// ```
    /// use savsim_core::{geo::{Geodetic, LocalTangentPlane}, world::Attitude};
    /// use glam::DVec3;
    /// let origin = Geodetic::new(47.0, 8.0, 500.0);
    /// let plane = LocalTangentPlane::new(origin);
    /// // Yaw 90 degrees: nose east.
    /// let a = Attitude::from_euler_ned(&plane, &origin, 0.0, 0.0, std::f64::consts::FRAC_PI_2, 0);
    /// let forward = a.forward_enu();
    /// assert!((forward - DVec3::X).length() < 1e-9);
    /// ```
    pub fn from_euler_ned(
        plane: &LocalTangentPlane,
        position: &Geodetic,
        roll_rad: f64,
        pitch_rad: f64,
        yaw_rad: f64,
        time_boot_ms: u32,
    ) -> Self {
        let ned_from_frd = DQuat::from_euler(EulerRot::ZYX, yaw_rad, pitch_rad, roll_rad);
        let enu_from_ned = DMat3::from_cols(DVec3::Y, DVec3::X, DVec3::NEG_Z);
        let plane_from_local = plane.plane_enu_from_local_enu_at(position);
        let enu_from_frd =
            DQuat::from_mat3(&(plane_from_local * enu_from_ned * DMat3::from_quat(ned_from_frd)))
                .normalize();
        Self {
            time_boot_ms,
            enu_from_frd,
            body_rates_radps: DVec3::ZERO,
        }
    }

    /// Its roll, pitch and yaw (radians, relative to the local NED frame at `position`, as
    /// MAVLink's ATTITUDE gives them): the inverse of [`Attitude::from_euler_ned`].
    ///
    /// ```
    /// use savsim_core::{geo::{Geodetic, LocalTangentPlane}, world::Attitude};
    /// let origin = Geodetic::new(47.0, 8.0, 500.0);
    /// let away = Geodetic::new(47.05, 8.07, 620.0);
    /// let plane = LocalTangentPlane::new(origin);
    /// let a = Attitude::from_euler_ned(&plane, &away, 0.1, -0.2, 2.5, 0);
    /// let [roll, pitch, yaw] = a.euler_ned_rad(&plane, &away);
    /// assert!((roll - 0.1).abs() < 1e-9 && (pitch + 0.2).abs() < 1e-9 && (yaw - 2.5).abs() < 1e-9);
    /// ```
    pub fn euler_ned_rad(&self, plane: &LocalTangentPlane, position: &Geodetic) -> [f64; 3] {
        let enu_from_ned = DMat3::from_cols(DVec3::Y, DVec3::X, DVec3::NEG_Z);
        let plane_from_local = plane.plane_enu_from_local_enu_at(position);
        let ned_from_frd = DQuat::from_mat3(
            &(enu_from_ned.transpose()
                * plane_from_local.transpose()
                * DMat3::from_quat(self.enu_from_frd)),
        );
        let (yaw_rad, pitch_rad, roll_rad) = ned_from_frd.to_euler(EulerRot::ZYX);
        [roll_rad, pitch_rad, yaw_rad]
    }

    /// The body's forward (x) axis in ENU.
    pub fn forward_enu(&self) -> DVec3 {
        self.enu_from_frd * DVec3::X
    }
}

/// One state of a vehicle or aircraft at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSample {
    /// When, seconds on the receive/tlog clock (UNIX time for tlogs and live). For a MAVLink
    /// vehicle this is its own clock (`time_boot_ms`) mapped onto the receive clock: intervals
    /// between its samples are the vehicle's, even when several arrive in one read.
    pub t_s: f64,
    /// Vehicle clock of the position, ms since boot (0 for ADS-B).
    pub time_boot_ms: u32,
    /// WGS84 position (alt AMSL).
    pub position: Geodetic,
    /// Position in the scene's ENU frame, metres from the origin.
    pub position_enu_m: DVec3,
    /// Velocity in the scene's ENU axes, m/s.
    pub velocity_enu_mps: DVec3,
    /// Orientation (the latest ATTITUDE, or one derived from the course for traffic).
    pub attitude: Attitude,
}

impl TrackSample {
    /// Its position (scene ENU, metres) and attitude (`enu_from_frd`) carried `dt_s` seconds
    /// along its velocity and its body rates, both held constant (a negative `dt_s` goes back):
    /// where the body was or will be close to the sample. Body rates are about the FRD axes, so
    /// the rotation is applied on the body's side.
    ///
    /// ```
    /// use glam::{DMat3, DQuat, DVec3};
    /// use savsim_core::world::{Attitude, TrackSample};
    /// use savsim_core::geo::Geodetic;
    /// // Nose north (FRD x along ENU north), yawing right at 1 rad/s, flying north at 10 m/s.
    /// let nose_north = DQuat::from_mat3(&DMat3::from_cols(DVec3::Y, DVec3::X, -DVec3::Z));
    /// let s = TrackSample {
    ///     t_s: 0.0, time_boot_ms: 0, position: Geodetic::new(0.0, 0.0, 0.0),
    ///     position_enu_m: DVec3::ZERO, velocity_enu_mps: DVec3::new(0.0, 10.0, 0.0),
    ///     attitude: Attitude { time_boot_ms: 0, enu_from_frd: nose_north,
    ///         body_rates_radps: DVec3::new(0.0, 0.0, 1.0) },
    /// };
    /// let (p, q) = s.pose_carried(std::f64::consts::FRAC_PI_2);
    /// assert!((p - DVec3::new(0.0, 15.707963, 0.0)).length() < 1e-6);
    /// // A quarter turn to the right: the nose points east.
    /// assert!((q * DVec3::X - DVec3::X).length() < 1e-12);
    /// ```
    pub fn pose_carried(&self, dt_s: f64) -> (DVec3, DQuat) {
        let position_enu_m = self.position_enu_m + self.velocity_enu_mps * dt_s;
        let turned = DQuat::from_scaled_axis(self.attitude.body_rates_radps * dt_s);
        (
            position_enu_m,
            (self.attitude.enu_from_frd * turned).normalize(),
        )
    }

    /// Linear interpolation of position and velocity, spherical of attitude; `u` in [0, 1].
    pub fn lerp(&self, next: &TrackSample, u: f64) -> TrackSample {
        let u = u.clamp(0.0, 1.0);
        TrackSample {
            t_s: self.t_s + (next.t_s - self.t_s) * u,
            time_boot_ms: if u < 0.5 {
                self.time_boot_ms
            } else {
                next.time_boot_ms
            },
            position: if u < 0.5 {
                self.position
            } else {
                next.position
            },
            position_enu_m: self.position_enu_m.lerp(next.position_enu_m, u),
            velocity_enu_mps: self.velocity_enu_mps.lerp(next.velocity_enu_mps, u),
            attitude: Attitude {
                time_boot_ms: next.attitude.time_boot_ms,
                enu_from_frd: self
                    .attitude
                    .enu_from_frd
                    .slerp(next.attitude.enu_from_frd, u),
                body_rates_radps: next.attitude.body_rates_radps,
            },
        }
    }
}

/// Where an instant falls in a [`History`].
enum Bracket<'a> {
    /// On this sample.
    At(&'a TrackSample),
    /// Between these two, at this fraction of the way (`TrackSample::lerp`'s `u`).
    Between(&'a TrackSample, &'a TrackSample, f64),
}

/// `latest`'s position carried along its velocity to `t_s`, at most `max_ahead_s` ahead.
fn carried_m(latest: &TrackSample, t_s: f64, max_ahead_s: f64) -> DVec3 {
    let ahead_s = (t_s - latest.t_s).min(max_ahead_s);
    latest.position_enu_m + latest.velocity_enu_mps * ahead_s
}

/// A track's history: latest samples in time order.
#[derive(Debug, Clone, Default)]
pub struct History {
    samples: VecDeque<TrackSample>,
}

impl History {
    pub(super) fn push(&mut self, sample: TrackSample, capacity: usize) {
        if self.samples.len() == capacity.max(2) {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The newest sample.
    pub fn latest(&self) -> Option<&TrackSample> {
        self.samples.back()
    }

    /// The sample before the newest.
    pub fn previous(&self) -> Option<&TrackSample> {
        self.samples.len().checked_sub(2).map(|i| &self.samples[i])
    }

    /// The state at `t_s`: interpolated inside the history, held at its ends.
    pub fn at(&self, t_s: f64) -> Option<TrackSample> {
        Some(match self.bracket(t_s)? {
            Bracket::At(s) => *s,
            Bracket::Between(a, b, u) => a.lerp(b, u),
        })
    }

    /// Where `t_s` falls in the history: on a sample (before the first, after the newest, or
    /// between two of one instant), or between two at `u` (0 at the earlier).
    fn bracket(&self, t_s: f64) -> Option<Bracket<'_>> {
        let first = self.samples.front()?;
        if t_s <= first.t_s {
            return Some(Bracket::At(first));
        }
        let i = self.after(t_s);
        if i >= self.samples.len() {
            return self.samples.back().map(Bracket::At);
        }
        let (a, b) = (&self.samples[i - 1], &self.samples[i]);
        let span = b.t_s - a.t_s;
        Some(if span > 0.0 {
            Bracket::Between(a, b, (t_s - a.t_s) / span)
        } else {
            Bracket::At(b)
        })
    }

    /// The index of the first sample after `t_s` (the length when none is): found from the
    /// newest end, where a tick's times nearly always are, before a binary search.
    fn after(&self, t_s: f64) -> usize {
        let n = self.samples.len();
        for back in 0..n.min(4) {
            if self.samples[n - 1 - back].t_s <= t_s {
                return n - back;
            }
        }
        self.samples.partition_point(|s| s.t_s <= t_s)
    }

    /// The state at `t_s`, extrapolated along the newest velocity (at most `max_ahead_s`) when
    /// `t_s` is past the newest sample: traffic reports slower than the vehicle's ticks.
    pub fn predict(&self, t_s: f64, max_ahead_s: f64) -> Option<TrackSample> {
        let latest = self.samples.back()?;
        if t_s <= latest.t_s {
            return self.at(t_s);
        }
        Some(TrackSample {
            t_s,
            position_enu_m: carried_m(latest, t_s, max_ahead_s),
            ..*latest
        })
    }

    /// The position and velocity [`History::predict`] gives at `t_s`, without the rest of the
    /// state (no attitude interpolated): the same numbers, for deciding whether a track is
    /// near before its whole state is made.
    pub fn predict_motion(&self, t_s: f64, max_ahead_s: f64) -> Option<(DVec3, DVec3)> {
        let latest = self.samples.back()?;
        if t_s > latest.t_s {
            return Some((carried_m(latest, t_s, max_ahead_s), latest.velocity_enu_mps));
        }
        Some(match self.bracket(t_s)? {
            Bracket::At(s) => (s.position_enu_m, s.velocity_enu_mps),
            Bracket::Between(a, b, u) => {
                let u = u.clamp(0.0, 1.0);
                (
                    a.position_enu_m.lerp(b.position_enu_m, u),
                    a.velocity_enu_mps.lerp(b.velocity_enu_mps, u),
                )
            }
        })
    }

    /// The samples, oldest first.
    pub fn samples(&self) -> impl DoubleEndedIterator<Item = &TrackSample> {
        self.samples.iter()
    }

    /// Number of samples held.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True when no sample is held.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    pub(super) fn clear(&mut self) {
        self.samples.clear();
    }
}

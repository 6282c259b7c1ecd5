//! Closest point of approach (CPA) and near mid-air collision (NMAC) between two moving
//! reference points, exact for motion that is linear between samples.
//!
//! Detect-and-avoid studies score an encounter by its CPA (the least 3D separation, with the
//! horizontal and vertical separation at that moment) and by NMAC: both aircraft within
//! 500 ft (152.4 m) horizontally *and* 100 ft (30.48 m) vertically at the same time.
//! Separation is between the two tracks' reference points (their reported positions), not
//! their surfaces: that is what these standards measure; contact of the shapes is the
//! contact layer's.
//!
//! Pure: one [`Approach::over`] per interval, folded with [`Approach::merge`]; [`Approaches`]
//! keeps one per pair of tracks, and each pair's losses of well clear
//! ([`crate::daa::episodes`]).

use std::collections::{BTreeMap, HashMap};

use foldhash::fast::RandomState;
use std::sync::Arc;

use glam::DVec3;

use crate::collision::bodies::{BodySource, DynamicBody};
use crate::daa::episodes::{Change, PairLog};
use crate::daa::well_clear::Volume;
use crate::world::TrackSample;

/// NMAC horizontal threshold: 500 ft, metres.
pub const NMAC_HORIZONTAL_M: f64 = 152.4;
/// NMAC vertical threshold: 100 ft, metres.
pub const NMAC_VERTICAL_M: f64 = 30.48;

/// The closest approach of two tracks over some time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    /// Least 3D separation, metres.
    pub distance_m: f64,
    /// Horizontal separation at that moment, metres.
    pub horizontal_m: f64,
    /// Vertical separation at that moment (other above own is positive), metres.
    pub vertical_m: f64,
    /// That moment, seconds (on the clock of the times given).
    pub t_s: f64,
    /// Whether the two were ever within both NMAC thresholds at once.
    pub nmac: bool,
}

impl Approach {
    /// The closest approach over one interval from `t0_s` to `t1_s` in which the other's
    /// position relative to own (`other - own`, ENU metres) moves linearly from `rel0_enu_m` to
    /// `rel1_enu_m`. A zero-length interval is its one instant.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::collision::approach::Approach;
    /// // Passing 100 m abeam, 20 m above, at mid-interval.
    /// let a = Approach::over(0.0, 10.0, DVec3::new(-50.0, 100.0, 20.0), DVec3::new(50.0, 100.0, 20.0));
    /// assert!((a.t_s - 5.0).abs() < 1e-12);
    /// assert!((a.horizontal_m - 100.0).abs() < 1e-12 && (a.vertical_m - 20.0).abs() < 1e-12);
    /// assert!(a.nmac);
    /// ```
    pub fn over(t0_s: f64, t1_s: f64, rel0_enu_m: DVec3, rel1_enu_m: DVec3) -> Self {
        let d = rel1_enu_m - rel0_enu_m;
        let u = closest_u(rel0_enu_m, d, 0.0, 1.0);
        let at = rel0_enu_m + d * u;
        Self {
            distance_m: at.length(),
            horizontal_m: at.truncate().length(),
            vertical_m: at.z,
            t_s: t0_s + (t1_s - t0_s) * u,
            nmac: nmac_within(rel0_enu_m, d),
        }
    }

    /// The closer of two approaches (the earlier on a tie); NMAC if either had one.
    pub fn merge(self, other: Approach) -> Approach {
        let nmac = self.nmac || other.nmac;
        let closer = if other.distance_m < self.distance_m {
            other
        } else {
            self
        };
        Approach { nmac, ..closer }
    }
}

/// The closest approach of each vehicle (MAVLink system id) to each moving body (by where it
/// comes from: a scene track, a vehicle's system and component id, an ICAO address) over a
/// run, and its losses of well clear.
#[derive(Debug, Clone)]
pub struct Approaches {
    /// By vehicle, then by body (a hash map with a fast hash: a fleet's tick looks up every
    /// body near it).
    by_vehicle: BTreeMap<u8, HashMap<BodySource, Pair, RandomState>>,
    /// The well-clear volume judged (`None`: well clear is not judged).
    volume: Option<Volume>,
}

/// What is known of one (vehicle, moving body) pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Pair {
    /// The body's id (its label).
    pub id: Arc<str>,
    /// Their closest approach so far.
    pub approach: Approach,
    /// Their losses of well clear (empty when well clear is not judged).
    pub well_clear: PairLog,
}

impl Default for Approaches {
    fn default() -> Self {
        Self::with_volume(Some(Volume::SMALL_UAS))
    }
}

/// A loss or a regain of well clear between a vehicle and a moving body.
#[derive(Debug, Clone, PartialEq)]
pub struct WellClearChange {
    /// The moving body's id.
    pub body: Arc<str>,
    /// Where the moving body comes from.
    pub source: BodySource,
    /// What changed, and when.
    pub change: Change,
}

impl Approaches {
    /// No approaches yet; well clear judged with `volume` (`None`: not judged).
    pub fn with_volume(volume: Option<Volume>) -> Self {
        Self {
            by_vehicle: BTreeMap::new(),
            volume,
        }
    }

    /// The well-clear volume judged (`None`: well clear is not judged).
    pub fn volume(&self) -> Option<Volume> {
        self.volume
    }

    /// Every pair, by vehicle, then body id, then body source (a fixed order: what a summary
    /// lists and sums).
    ///
    /// ```
    /// use savsim_core::collision::approach::Approaches;
    /// assert!(Approaches::default().pairs().is_empty());
    /// ```
    pub fn pairs(&self) -> Vec<(u8, &Pair)> {
        let mut pairs = Vec::new();
        for (&vehicle, bodies) in &self.by_vehicle {
            let mut of_vehicle: Vec<_> = bodies.iter().collect();
            of_vehicle.sort_unstable_by(|a, b| (&a.1.id, a.0).cmp(&(&b.1.id, b.0)));
            pairs.extend(of_vehicle.into_iter().map(|(_, pair)| (vehicle, pair)));
        }
        pairs
    }

    /// The pair of vehicle `own` and the body from `source`, if they have been seen together.
    pub fn pair(&self, own: u8, source: BodySource) -> Option<&Pair> {
        self.by_vehicle.get(&own)?.get(&source)
    }

    /// Fold in one tick of vehicle `own` (from its `previous` sample, if any, to `current`)
    /// against every moving body of that interval, as the pipeline sees them; the losses and
    /// regains of well clear within it, in `changes` (cleared first). Allocates only the first
    /// time a pair is seen.
    pub fn observe(
        &mut self,
        own: u8,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        bodies: &[DynamicBody],
        changes: &mut Vec<WellClearChange>,
    ) {
        changes.clear();
        let before = previous.unwrap_or(current);
        let pairs = self.by_vehicle.entry(own).or_default();
        for body in bodies {
            let (rel0, rel1) = (
                body.previous.position_enu_m - before.position_enu_m,
                body.current.position_enu_m - current.position_enu_m,
            );
            let a = Approach::over(before.t_s, current.t_s, rel0, rel1);
            let pair = pairs
                .entry(body.key.source)
                .and_modify(|pair| pair.approach = pair.approach.merge(a))
                .or_insert_with(|| Pair {
                    id: body.id.clone(),
                    approach: a,
                    well_clear: PairLog::default(),
                });
            let Some(volume) = &self.volume else {
                continue;
            };
            for change in pair
                .well_clear
                .observe(volume, before.t_s, current.t_s, rel0, rel1)
            {
                changes.push(WellClearChange {
                    body: body.id.clone(),
                    source: body.key.source,
                    change,
                });
            }
        }
    }
}

/// The `u` in `[lo, hi]` at which `|p + d u|` is least (the earliest on a tie).
fn closest_u(p: DVec3, d: DVec3, lo: f64, hi: f64) -> f64 {
    let dd = d.length_squared();
    if dd <= 0.0 {
        return lo;
    }
    (-p.dot(d) / dd).clamp(lo, hi)
}

/// Whether `p + d u` is within both NMAC thresholds (strictly) for some `u` in `[0, 1]`.
fn nmac_within(p: DVec3, d: DVec3) -> bool {
    // The open sub-interval where the vertical separation is under its threshold (it is
    // linear in u): empty, or of positive length.
    let (lo, hi) = if d.z == 0.0 {
        if p.z.abs() >= NMAC_VERTICAL_M {
            return false;
        }
        (0.0, 1.0)
    } else {
        let a = (-NMAC_VERTICAL_M - p.z) / d.z;
        let b = (NMAC_VERTICAL_M - p.z) / d.z;
        (a.min(b).max(0.0), a.max(b).min(1.0))
    };
    if lo >= hi {
        return false;
    }
    // The least horizontal separation over its closure: horizontal separation is continuous,
    // so it is under its threshold somewhere inside exactly when it is at that least point.
    let (ph, dh) = (p.truncate().extend(0.0), d.truncate().extend(0.0));
    let u = closest_u(ph, dh, lo, hi);
    (ph + dh * u).length() < NMAC_HORIZONTAL_M
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nmac_needs_both_thresholds_at_the_same_time() {
        // Horizontally inside only while vertically far, and the other way round.
        let a = Approach::over(
            0.0,
            1.0,
            DVec3::new(0.0, 0.0, 200.0),
            DVec3::new(1000.0, 0.0, 0.0),
        );
        assert!(!a.nmac, "{a:?}");
        // A climb through the other's level while abeam at 100 m.
        let b = Approach::over(
            0.0,
            1.0,
            DVec3::new(100.0, 0.0, -100.0),
            DVec3::new(100.0, 0.0, 100.0),
        );
        assert!(b.nmac && (b.distance_m - 100.0).abs() < 1e-9, "{b:?}");
    }
}

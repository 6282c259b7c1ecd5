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

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::DVec3;

use crate::collision::bodies::{BodySource, DynamicBody};
use crate::daa::episodes::{Change, PairLog};
use crate::daa::separation::Separation;
use crate::daa::well_clear::Volume;
use crate::world::{SenderId, TrackSample};

/// NMAC horizontal threshold: 500 ft, metres.
pub const NMAC_HORIZONTAL_M: f64 = 152.4;
/// NMAC vertical threshold: 100 ft, metres.
pub const NMAC_VERTICAL_M: f64 = 30.48;

/// A moving body as closest approaches and well clear see it: who it is and its positions at
/// both ends of the interval (no attitude: they judge reference points).
#[derive(Debug, Clone, Copy)]
pub struct Passing<'a> {
    /// Where it comes from (the pair's key).
    pub source: BodySource,
    /// Its id.
    pub id: &'a Arc<str>,
    /// Its reference point at the interval's start, scene ENU metres.
    pub previous_enu_m: DVec3,
    /// Its reference point at the interval's end, scene ENU metres.
    pub current_enu_m: DVec3,
}

impl<'a> From<&'a DynamicBody> for Passing<'a> {
    fn from(body: &'a DynamicBody) -> Self {
        Self {
            source: body.key.source,
            id: &body.id,
            previous_enu_m: body.previous.position_enu_m,
            current_enu_m: body.current.position_enu_m,
        }
    }
}

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
    /// use savsim_core::daa::approach::Approach;
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

/// The closest approach of each vehicle (its MAVLink system and component id: a fleet past 250 vehicles numbers them by component) to each moving body (by where it
/// comes from: a scene track, a vehicle's system and component id, an ICAO address) over a
/// run, and its losses of well clear.
#[derive(Debug, Clone)]
pub struct Approaches {
    /// By vehicle, the pairs sorted by body source: a tick's bodies come in key order, so a
    /// tick walks its vehicle's pairs in order.
    by_vehicle: BTreeMap<SenderId, VehiclePairs>,
    /// The well-clear volume judged (`None`: well clear is not judged).
    volume: Option<Volume>,
    /// The separation minimum judged (`None`: not judged).
    separation: Option<Separation>,
}

/// One vehicle's pairs: the bodies' sources, sorted, and beside them (same index) what is
/// known of each pair. The sources are kept apart so that finding one reads few cache lines.
#[derive(Debug, Clone, Default)]
struct VehiclePairs {
    sources: Vec<BodySource>,
    pairs: Vec<Pair>,
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
    /// Their losses of the separation minimum (empty when none is judged).
    pub separation: PairLog,
}

impl Default for Approaches {
    fn default() -> Self {
        Self::with_volume(Some(Volume::SMALL_UAS))
    }
}

/// A loss or a regain of well clear (or of the separation minimum) between a vehicle and a
/// moving body.
#[derive(Debug, Clone, PartialEq)]
pub struct WellClearChange {
    /// The moving body's id.
    pub body: Arc<str>,
    /// Where the moving body comes from.
    pub source: BodySource,
    /// What changed, and when.
    pub change: Change,
    /// Whether it is the separation minimum's (else well clear's).
    pub separation: bool,
}

impl Approaches {
    /// No approaches yet; well clear judged with `volume` (`None`: not judged).
    pub fn with_volume(volume: Option<Volume>) -> Self {
        Self {
            by_vehicle: BTreeMap::new(),
            volume,
            separation: None,
        }
    }

    /// Also judge `separation` (`None`: not judged).
    pub fn with_separation(self, separation: Option<Separation>) -> Self {
        Self { separation, ..self }
    }

    /// The separation minimum judged.
    pub fn separation(&self) -> Option<Separation> {
        self.separation
    }

    /// The well-clear volume judged (`None`: well clear is not judged).
    pub fn volume(&self) -> Option<Volume> {
        self.volume
    }

    /// Every pair, by vehicle, then body id, then body source (a fixed order: what a summary
    /// lists and sums).
    ///
    /// ```
    /// use savsim_core::daa::approach::Approaches;
    /// assert!(Approaches::default().pairs().is_empty());
    /// ```
    pub fn pairs(&self) -> Vec<(SenderId, &Pair)> {
        let mut pairs = Vec::new();
        for (&vehicle, of_vehicle) in &self.by_vehicle {
            let mut of_vehicle: Vec<_> = of_vehicle.pairs.iter().collect();
            of_vehicle.sort_by(|a, b| a.id.cmp(&b.id));
            pairs.extend(of_vehicle.into_iter().map(|pair| (vehicle, pair)));
        }
        pairs
    }

    /// The pair of vehicle `own` and the body from `source`, if they have been seen together.
    pub fn pair(&self, own: SenderId, source: BodySource) -> Option<&Pair> {
        let of_vehicle = self.by_vehicle.get(&own)?;
        let at = slot(&of_vehicle.sources, 0, source).ok()?;
        Some(&of_vehicle.pairs[at])
    }

    /// Fold in one tick of vehicle `own` (from its `previous` sample, if any, to `current`)
    /// against every moving body of that interval (their positions: [`Passing`]); the losses
    /// and regains of well clear within it, in `changes` (cleared first). Allocates only the
    /// first time a pair is seen. Fastest with `bodies` in the order of their keys, as a
    /// session's tick has them; any order gives the same answer.
    pub fn observe<'b>(
        &mut self,
        own: SenderId,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        bodies: impl IntoIterator<Item = Passing<'b>>,
        changes: &mut Vec<WellClearChange>,
    ) {
        changes.clear();
        let before = previous.unwrap_or(current);
        let VehiclePairs { sources, pairs } = self.by_vehicle.entry(own).or_default();
        let mut hint = 0;
        for body in bodies {
            let (rel0, rel1) = (
                body.previous_enu_m - before.position_enu_m,
                body.current_enu_m - current.position_enu_m,
            );
            let a = Approach::over(before.t_s, current.t_s, rel0, rel1);
            let source = body.source;
            let at = match slot(sources, hint, source) {
                Ok(at) => {
                    pairs[at].approach = pairs[at].approach.merge(a);
                    at
                }
                Err(at) => {
                    let pair = Pair {
                        id: body.id.clone(),
                        approach: a,
                        well_clear: PairLog::default(),
                        separation: PairLog::default(),
                    };
                    sources.insert(at, source);
                    pairs.insert(at, pair);
                    at
                }
            };
            hint = at + 1;
            let pair = &mut pairs[at];
            let (t0, t1) = (before.t_s, current.t_s);
            let mut note = |change, separation| {
                changes.push(WellClearChange {
                    body: body.id.clone(),
                    source: body.source,
                    change,
                    separation,
                });
            };
            if let Some(volume) = &self.volume {
                for change in pair.well_clear.observe(volume, t0, t1, rel0, rel1) {
                    note(change, false);
                }
            }
            // The interval's least distance is `a`'s: a pair that stays at least the minimum
            // apart and is not inside it has nothing to fold (its log reads the time only of
            // an open episode).
            let near = |s: &Separation| a.distance_m < s.minimum_m || pair.separation.open();
            if let Some(separation) = self.separation.as_ref().filter(|s| near(s)) {
                for change in pair.separation.observe(separation, t0, t1, rel0, rel1) {
                    note(change, true);
                }
            }
        }
    }
}

/// Where `source` is in `sources` (sorted), or where it would go. Searched by galloping from
/// `hint` when `source` comes after the one before `hint` (as the next body in key order
/// does: the cost grows with the log of how far it is), else in all of them.
fn slot(sources: &[BodySource], hint: usize, source: BodySource) -> Result<usize, usize> {
    let from = if hint > 0 && hint <= sources.len() && sources[hint - 1] < source {
        hint
    } else {
        0
    };
    // Everything before `lo` is before `source`; nothing after `probe` is.
    let (mut lo, mut probe, mut step) = (from, from, 1);
    while probe < sources.len() && sources[probe] < source {
        lo = probe + 1;
        probe = from + step;
        step *= 2;
    }
    sources[lo..(probe + 1).min(sources.len())]
        .binary_search(&source)
        .map(|i| lo + i)
        .map_err(|i| lo + i)
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
    fn a_slot_is_where_a_binary_search_puts_it_from_any_hint() {
        let sources: Vec<_> = (0..37).map(|i| BodySource::Scripted(2 * i)).collect();
        for n in [0, 1, 2, 3, 7, 8, 9, 37] {
            let sources = &sources[..n];
            for hint in 0..=n + 1 {
                for i in 0..2 * n as u32 + 2 {
                    let source = BodySource::Scripted(i);
                    assert_eq!(
                        slot(sources, hint, source),
                        sources.binary_search(&source),
                        "{n} sources, hint {hint}, {source:?}"
                    );
                }
            }
        }
    }
    use crate::collision::bodies::{BodyKey, BodyPose};
    use crate::geo::Geodetic;
    use crate::scene::Kind;
    use crate::world::Attitude;
    use glam::DQuat;

    fn sample(t_s: f64, east_m: f64) -> TrackSample {
        TrackSample {
            t_s,
            time_boot_ms: 0,
            position: Geodetic::new(0.0, 0.0, 0.0),
            position_enu_m: DVec3::new(east_m, 0.0, 50.0),
            velocity_enu_mps: DVec3::ZERO,
            attitude: Attitude {
                time_boot_ms: 0,
                enu_from_frd: DQuat::IDENTITY,
                body_rates_radps: DVec3::ZERO,
            },
        }
    }

    fn body(source: BodySource, north_m: f64) -> DynamicBody {
        let pose = |n: f64| BodyPose {
            position_enu_m: DVec3::new(0.0, n, 50.0),
            enu_from_body: DQuat::IDENTITY,
        };
        DynamicBody {
            key: BodyKey {
                source,
                generation: 0,
            },
            id: format!("{source:?}").into(),
            kind: Kind::Dji,
            threat: 45.0,
            geometry_index: 0,
            previous: pose(north_m),
            current: pose(north_m - 10.0),
            speed_mps: 10.0,
        }
    }

    #[test]
    fn pairs_are_the_same_in_any_order_of_bodies() {
        // Ticks whose body sets overlap, some new each tick, one gone and back.
        let sources: Vec<BodySource> = (0..6)
            .map(BodySource::Scripted)
            .chain((1..6).map(|v| BodySource::Vehicle {
                vehicle: v,
                component_id: 1,
            }))
            .chain([BodySource::Traffic(7), BodySource::Traffic(3)])
            .collect();
        let ticks: Vec<Vec<DynamicBody>> = (0..5)
            .map(|k| {
                let mut bodies: Vec<_> = sources
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| (i + k) % 3 != 0)
                    .map(|(i, &s)| body(s, 100.0 * i as f64 - 20.0 * k as f64))
                    .collect();
                bodies.sort_by_key(|b| b.key);
                bodies
            })
            .collect();
        let run = |reorder: &dyn Fn(&mut Vec<DynamicBody>)| {
            let mut approaches = Approaches::default();
            let mut changes = Vec::new();
            let mut all = Vec::new();
            for (k, bodies) in ticks.iter().enumerate() {
                let mut bodies = bodies.clone();
                reorder(&mut bodies);
                let (a, b) = (sample(k as f64, 0.0), sample(k as f64 + 1.0, 5.0));
                approaches.observe(
                    SenderId {
                        system_id: 1,
                        component_id: 1,
                    },
                    Some(&a),
                    &b,
                    bodies.iter().map(Passing::from),
                    &mut changes,
                );
                changes.sort_by_key(|c| c.source);
                all.append(&mut changes);
            }
            let pairs: Vec<_> = approaches
                .pairs()
                .into_iter()
                .map(|(v, p)| (v, p.clone()))
                .collect();
            (pairs, all)
        };
        let sorted = run(&|_| {});
        assert_eq!(sorted.0.len(), sources.len());
        assert!(
            !sorted.1.is_empty(),
            "the test should see losses of well clear"
        );
        assert_eq!(run(&|b| b.reverse()), sorted);
        assert_eq!(run(&|b| b.rotate_left(3)), sorted);
    }

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

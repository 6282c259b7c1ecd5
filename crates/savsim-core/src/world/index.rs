//! The world's spatial index: which tracks may be near a region, without a scan of every
//! track.
//!
//! Built from the tracks at one instant (a snapshot with stable keys) and rebuilt when it is
//! [`REFRESH_S`] old or when too many tracks have left it. Each entry is a box that holds
//! every position [`History::predict`] can give for its track at any time from
//! [`LOOKBACK_S`] before the build on: the samples since then (and the one before, for
//! interpolation) and the newest sample carried ahead along its velocity for as long as
//! prediction goes. A new sample whose position or forward prediction leaves its box puts
//! the track on a short list that every query visits as well, so a query is a superset
//! (never a miss) whatever the tracks do between builds. A query for times older than the
//! look-back scans every track.
//!
//! Pure and synchronous.

use std::collections::HashSet;

use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};

use crate::scene::Aabb64;
use crate::world::inputs::SenderId;
use crate::world::{History, PREDICT_MAX_S};

/// An index older than this (receive clock, seconds) is rebuilt before it is queried.
pub const REFRESH_S: f64 = 0.25;

/// A query may ask for positions this long before the index was built, seconds.
pub const LOOKBACK_S: f64 = 2.0;

/// Tracks outside their boxes beyond this many (or a tenth of all) trigger a rebuild.
const MOVED_OUT_MAX: usize = 32;

/// A track's key: stable for the track's life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TrackKey {
    /// A MAVLink vehicle.
    Vehicle(SenderId),
    /// An ADS-B aircraft by ICAO address.
    Traffic(u32),
}

/// The index. Queries go through [`crate::world::WorldStore::tracks_near`].
#[derive(Debug, Clone, Default)]
pub struct TrackIndex {
    /// When it was built (receive clock), `None` before the first build.
    built_t_s: Option<f64>,
    keys: Vec<TrackKey>,
    bvh: Option<Bvh>,
    /// Tracks whose newest samples are outside their box (or that have none): always visited.
    moved_out: HashSet<TrackKey>,
    /// A query's keys, sorted before they are visited (scratch).
    hits: Vec<TrackKey>,
    /// Each entry's box, by key, to check new samples against.
    boxes: std::collections::HashMap<TrackKey, Aabb64>,
    /// The fastest speed of any track's newest sample since the build, m/s.
    max_speed_mps: f64,
    /// Builds so far.
    pub builds: u64,
    /// Queries that asked for times older than the look-back and scanned every track.
    pub scans: u64,
}

impl TrackIndex {
    /// Note that `key` has a new sample (in `history`): if it can leave its box, it joins the
    /// tracks every query visits.
    pub(crate) fn moved(&mut self, key: TrackKey, history: &History) {
        if let Some(s) = history.latest() {
            self.max_speed_mps = self.max_speed_mps.max(speed_mps(s));
        }
        if self.moved_out.contains(&key) {
            return;
        }
        let inside = self.boxes.get(&key).is_some_and(|b| {
            history
                .latest()
                .is_some_and(|s| b.contains(s.position_enu_m) && b.contains(ahead(s)))
        });
        if !inside {
            self.moved_out.insert(key);
        }
    }

    /// Whether a query at `now_t_s` should rebuild first.
    pub(crate) fn stale(&self, now_t_s: f64, tracks: usize) -> bool {
        self.built_t_s
            .is_none_or(|b| now_t_s - b >= REFRESH_S || now_t_s < b)
            || self.moved_out.len() > MOVED_OUT_MAX.max(tracks / 10)
    }

    /// Whether a query for positions from `since_t_s` on can use the index.
    pub(crate) fn covers(&self, since_t_s: f64) -> bool {
        self.built_t_s.is_some_and(|b| since_t_s >= b - LOOKBACK_S)
    }

    /// Rebuild at `now_t_s` from every track's history.
    pub(crate) fn build<'a>(
        &mut self,
        now_t_s: f64,
        tracks: impl Iterator<Item = (TrackKey, &'a History)>,
    ) {
        self.keys.clear();
        self.boxes.clear();
        self.moved_out.clear();
        self.max_speed_mps = 0.0;
        let mut leaves = Vec::new();
        for (key, history) in tracks {
            let since_t_s = now_t_s - LOOKBACK_S;
            for s in since(history, since_t_s) {
                self.max_speed_mps = self.max_speed_mps.max(speed_mps(s));
            }
            match entry_box(history, since_t_s) {
                Some(b) => {
                    leaves.push((self.keys.len(), to_f32(&b)));
                    self.keys.push(key);
                    self.boxes.insert(key, b);
                }
                None => {
                    self.moved_out.insert(key);
                }
            }
        }
        self.bvh = Some(Bvh::from_iter(BvhBuildStrategy::Binned, leaves));
        self.built_t_s = Some(now_t_s);
        self.builds += 1;
    }

    /// The fastest speed of any track's newest sample since the last build, m/s (finite).
    pub(crate) fn max_speed_mps(&self) -> f64 {
        self.max_speed_mps
    }

    /// Call `visit` for every track whose box meets `region`, and for every track that left
    /// its box since the build (a track may be visited that is nowhere near), each once, in
    /// the order of their keys.
    pub(crate) fn near(&mut self, region: &Aabb64, mut visit: impl FnMut(TrackKey)) {
        self.hits.clear();
        if let Some(bvh) = &self.bvh {
            let moved_out = &self.moved_out;
            self.hits.extend(
                bvh.intersect_aabb(&to_f32(region))
                    .map(|i| self.keys[i as usize])
                    .filter(|key| !moved_out.contains(key)),
            );
        }
        self.hits.extend(self.moved_out.iter().copied());
        self.hits.sort_unstable();
        self.hits.iter().for_each(|&k| visit(k));
    }
}

/// The samples `History::predict` can use for times from `since_t_s` on, newest first: through
/// the first at or before `since_t_s` (interpolation reaches back to it; `at` holds the oldest
/// sample for earlier times).
fn since(history: &History, since_t_s: f64) -> impl Iterator<Item = &crate::world::TrackSample> {
    let mut done = false;
    history.samples().rev().take_while(move |s| {
        let take = !done;
        done = s.t_s <= since_t_s;
        take
    })
}

/// A sample's speed, m/s; 0 when not finite (its box is not finite either: always visited).
fn speed_mps(s: &crate::world::TrackSample) -> f64 {
    let v = s.velocity_enu_mps.length();
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Where `History::predict` carries the newest sample to at most.
fn ahead(s: &crate::world::TrackSample) -> glam::DVec3 {
    s.position_enu_m + s.velocity_enu_mps * PREDICT_MAX_S
}

/// The box of every position `history` can predict from `since_t_s` on, grown by a slack that
/// lets the track go on a while before it leaves it; `None` when it is empty or not finite.
fn entry_box(history: &History, since_t_s: f64) -> Option<Aabb64> {
    let latest = history.latest()?;
    let mut b = Aabb64::new(latest.position_enu_m, latest.position_enu_m).including(ahead(latest));
    for s in since(history, since_t_s) {
        b = b.including(s.position_enu_m);
    }
    let slack_m = 5.0_f64.max(latest.velocity_enu_mps.length() * 1.0);
    let b = b.inflated(slack_m);
    (b.min.is_finite() && b.max.is_finite()).then_some(b)
}

/// `b` in f32, grown by a centimetre and f32's steps at its coordinates, so that it holds `b`.
fn to_f32(b: &Aabb64) -> Aabb {
    let scale = b.min.abs().max(b.max.abs()).max_element();
    let grown = b.inflated(0.01 + 4.0 * f64::from(f32::EPSILON) * scale);
    Aabb::new(grown.min.as_vec3(), grown.max.as_vec3())
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use proptest::prelude::*;

    use crate::geo::Geodetic;
    use crate::scene::Aabb64;
    use crate::world::inputs::{PositionReport, Report, SenderId};
    use crate::world::{Track, WorldConfig, WorldStore, PREDICT_MAX_S};

    fn world() -> WorldStore {
        WorldStore::new(Geodetic::new(47.0, 8.0, 400.0), WorldConfig::default())
    }

    fn sender(n: u16) -> SenderId {
        SenderId {
            system_id: (n % 250 + 1) as u8,
            component_id: (n / 250 + 1) as u8,
        }
    }

    /// Vehicle `n` at `enu_m` moving at `v_enu_mps`, on its clock at `t_s` (received then).
    fn report(world: &mut WorldStore, n: u16, t_s: f64, enu_m: DVec3, v_enu_mps: DVec3) {
        let position = world.plane().geodetic_from_enu_m(enu_m);
        let velocity_ned_mps = DVec3::new(v_enu_mps.y, v_enu_mps.x, -v_enu_mps.z);
        let r = Report::Position(PositionReport {
            time_boot_ms: (t_s * 1000.0) as u32,
            position,
            relative_alt_m: enu_m.z,
            velocity_ned_mps,
            heading_deg: None,
        });
        world.apply(t_s, sender(n), &r);
    }

    fn found(world: &mut WorldStore, region: &Aabb64, since: f64, now: f64) -> Vec<SenderId> {
        let mut out = Vec::new();
        world.tracks_near(region, since, now, |t| {
            if let Track::Vehicle(v) = t {
                out.push(v.id);
            }
        });
        out.sort();
        out.dedup();
        out
    }

    /// A query looks at the tracks near it, not at all of them: 1000 vehicles a kilometre
    /// apart, a query 100 m across finds one (a scan would visit all 1000).
    #[test]
    fn a_query_visits_only_what_is_near() {
        let mut w = world();
        for n in 0..1000u16 {
            let at = DVec3::new(f64::from(n % 40) * 1000.0, f64::from(n / 40) * 1000.0, 50.0);
            report(&mut w, n, 1.0, at, DVec3::ZERO);
        }
        let mut visits = 0;
        let region = Aabb64::around(DVec3::new(3000.0, 2000.0, 50.0), DVec3::splat(50.0));
        w.tracks_near(&region, 1.0, 1.0, |_| visits += 1);
        assert_eq!(visits, 1);
        assert_eq!(w.index_counts(), (1, 0));
        // A second query within the refresh period reuses the index.
        w.tracks_near(&region, 1.0, 1.1, |_| visits += 1);
        assert_eq!(w.index_counts(), (1, 0));
        // One that asks for times older than the index looks back scans everything.
        w.tracks_near(&region, -5.0, 1.1, |_| visits += 1);
        assert_eq!(w.index_counts(), (1, 1));
        assert_eq!(visits, 1 + 1 + 1000);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        /// Whatever the tracks do between builds (turn, jump, appear, reboot), a query finds
        /// every track with a predicted position in its region at any of a set of times from
        /// `since` on: checked against the predictions themselves.
        #[test]
        fn a_query_never_misses_a_track(
            starts in prop::collection::vec((-500.0..500.0f64, -500.0..500.0f64), 1..40),
            moves in prop::collection::vec(
                (0usize..40, -300.0..300.0f64, -300.0..300.0f64, -30.0..30.0f64, -30.0..30.0f64),
                0..200,
            ),
            centre in (-500.0..500.0f64, -500.0..500.0f64),
            half_m in 1.0..200.0f64,
            lag_s in 0.0..1.5f64,
        ) {
            let mut w = world();
            let mut at: Vec<DVec3> = Vec::new();
            for (n, (e, nn)) in starts.iter().enumerate() {
                at.push(DVec3::new(*e, *nn, 50.0));
                report(&mut w, n as u16, 0.0, at[n], DVec3::ZERO);
            }
            let region = Aabb64::around(DVec3::new(centre.0, centre.1, 50.0), DVec3::splat(half_m));
            let mut t = 0.0;
            for (k, (n, de, dn, ve, vn)) in moves.iter().enumerate() {
                let n = n % starts.len();
                t = 0.05 * (k + 1) as f64;
                at[n] += DVec3::new(*de, *dn, 0.0) * if k % 7 == 0 { 1.0 } else { 0.02 };
                report(&mut w, n as u16, t, at[n], DVec3::new(*ve, *vn, 0.0));
                if k % 5 == 0 {
                    // Queries between samples keep the index in use (and rebuild it).
                    let _ = found(&mut w, &region, t, t);
                }
            }
            let since = t - lag_s;
            let got = found(&mut w, &region, since, t);
            for v in w.vehicles.values() {
                let times = (0..=20).map(|i| since + (t + PREDICT_MAX_S + 1.0 - since) * f64::from(i) / 20.0);
                let inside = times
                    .filter_map(|s| v.history.predict(s, PREDICT_MAX_S))
                    .any(|s| region.contains(s.position_enu_m));
                if inside {
                    prop_assert!(got.contains(&v.id), "missed {:?}", v.id);
                }
            }
        }
    }
}

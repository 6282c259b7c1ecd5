//! Alerting on sensed states, for a batch encounter: the ownship's DAA system knows the
//! intruders through the row's surveillance devices (ADS-B, radar, EO/IR: each report arrives
//! its latency later, the newest one a track) and its own state through its navigation (the
//! `gps-ins` device when the row lists one, else exactly), and raises alert levels as a
//! DAIDALUS configuration says, every second, with each state's uncertainty the sigmas of the
//! models that made it (so that a `*_SUM` configuration mitigates them). The sensed states can
//! be written as a DAIDALUS state file with its uncertainty columns, for `savsim daa` or
//! DaidalusAlerting to read.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use glam::{DQuat, DVec3};

use crate::daa::alerting::Filter;
use crate::daa::conf::Config;
use crate::daa::sum::Uncertainty;
use crate::daa::well_clear::Relative;
use crate::sensors::device::{Device, Model};
use crate::sensors::draws::{mix, Draws};
use crate::sensors::surveillance::{Look, Own, Target, TargetReport, TargetState};

/// What alerting on sensed states found.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct SensedAlerting {
    /// The most severe level raised (0: none).
    pub max_level: i32,
    /// When each level (1, 2, 3) was first raised, seconds from the start.
    pub first_level_t_s: [Option<f64>; 3],
    /// When the first report of any intruder arrived, seconds.
    pub first_detection_t_s: Option<f64>,
    /// The closest an intruder was reported (true ownship to reported intruder), metres.
    pub sensed_closest_m: Option<f64>,
    /// Reports that got through.
    pub reports_received: u64,
    /// Reports that did not, while the intruder was within reach.
    pub reports_lost: u64,
}

/// A report on its way: when it arrives, the intruder, the report.
type InFlight = (f64, usize, TargetReport);

/// A track without a newer report is dropped after this long, seconds.
pub const TRACK_KEPT_S: f64 = 20.0;

/// The ownship's DAA system over one encounter.
pub struct SensedDaa {
    config: Config,
    devices: Vec<Device>,
    navigation: Option<Device>,
    draws: Draws,
    seed: u64,
    last_k: Vec<Option<u64>>,
    targets: Vec<BTreeMap<usize, TargetState>>,
    own_state: TargetState,
    in_flight: Vec<InFlight>,
    /// Each intruder's newest report that arrived, and when it arrived (a track is dropped
    /// [`TRACK_KEPT_S`] after its last report).
    tracks: BTreeMap<usize, (f64, TargetReport)>,
    filters: BTreeMap<usize, Filter>,
    next_step_s: f64,
    found: SensedAlerting,
    /// The sensed states as a DAIDALUS state file, when asked for.
    daa: Option<String>,
}

/// An intruder's truth at a sample: its index and state.
pub struct Truth {
    /// Which intruder (its index in the encounter).
    pub index: usize,
    /// Its state.
    pub target: Target,
}

impl SensedDaa {
    /// The DAA system of a row: its configuration, its devices (surveillance ones report the
    /// intruders; a `gps-ins` device is its navigation), its seed; `daa_file` to keep the
    /// sensed states as a state file.
    pub fn new(config: Config, devices: &[Device], seed: u64, daa_file: bool) -> Self {
        let (navigation, devices): (Vec<Device>, Vec<Device>) = devices
            .iter()
            .filter(|d| !matches!(d.model, Model::Range(_)))
            .cloned()
            .partition(|d| d.name == "gps-ins");
        let n = devices.len();
        let daa = daa_file.then(|| {
            "NAME, sx, sy, sz, vx, vy, vz, time, s_EW_std, s_NS_std, s_EN_std, sz_std, v_EW_std, \
             v_NS_std, v_EN_std, vz_std\nunitless, [m], [m], [m], [m/s], [m/s], [m/s], [s], [m], \
             [m], [m], [m], [m/s], [m/s], [m/s], [m/s]\n"
                .to_string()
        });
        Self {
            config,
            devices,
            navigation: navigation.into_iter().next(),
            draws: Draws::new(seed),
            seed,
            last_k: vec![None; n],
            targets: vec![BTreeMap::new(); n],
            own_state: TargetState::default(),
            in_flight: Vec::new(),
            tracks: BTreeMap::new(),
            filters: BTreeMap::new(),
            next_step_s: 0.0,
            found: SensedAlerting::default(),
            daa,
        }
    }

    /// At a sample `t_s` seconds from the start: the devices whose instant came report, what
    /// arrived becomes the tracks, and on each whole second the alert levels are judged.
    pub fn step(&mut self, t_s: f64, own: &Own, intruders: &[Truth]) {
        self.survey(t_s, own, intruders);
        self.in_flight.sort_by(|a, b| a.0.total_cmp(&b.0));
        while self.in_flight.first().is_some_and(|f| f.0 <= t_s) {
            let (at, i, report) = self.in_flight.remove(0);
            let found = &mut self.found;
            found.reports_received += 1;
            found.first_detection_t_s.get_or_insert(at);
            let d = (report.position_enu_m - own.position_enu_m).length();
            found.sensed_closest_m = Some(found.sensed_closest_m.map_or(d, |m| m.min(d)));
            self.tracks.insert(i, (at, report));
        }
        self.tracks.retain(|_, (at, _)| t_s - *at <= TRACK_KEPT_S);
        if t_s + 1e-9 >= self.next_step_s {
            self.alert(self.next_step_s, own);
            self.next_step_s += 1.0;
        }
    }

    /// Each surveillance device whose instant came reports each intruder.
    fn survey(&mut self, t_s: f64, own: &Own, intruders: &[Truth]) {
        for (d, device) in self.devices.iter().enumerate() {
            let k = (t_s * device.rate_hz).floor().max(0.0) as u64;
            if self.last_k[d].is_some_and(|last| k <= last) {
                continue;
            }
            self.last_k[d] = Some(k);
            let dt_s = 1.0 / device.rate_hz;
            let key = mix(mix(self.seed, 1), d as u64);
            for truth in intruders {
                let state = self.targets[d].entry(truth.index).or_default();
                let look = Look {
                    draws: &self.draws,
                    key,
                    k,
                    dt_s,
                    own,
                };
                let report = device.model.report(state, &look, &truth.target);
                match report {
                    Some(r) => self.in_flight.push((
                        k as f64 * dt_s + device.latency_s + r.jitter_s,
                        truth.index,
                        r,
                    )),
                    None => self.found.reports_lost += 1,
                }
            }
        }
    }

    /// The ownship as its navigation knows it at `t_s`, with its uncertainty.
    fn own_sensed(&mut self, t_s: f64, own: &Own) -> (DVec3, DVec3, Uncertainty) {
        let exact = (
            own.position_enu_m,
            own.velocity_enu_mps,
            Uncertainty::default(),
        );
        let Some(nav) = self
            .navigation
            .as_ref()
            .filter(|n| matches!(n.model, Model::Adsb(_)))
        else {
            return exact;
        };
        let dt_s = 1.0 / nav.rate_hz;
        let k = (t_s * nav.rate_hz).round() as u64;
        let me = Target {
            key: 0,
            position_enu_m: own.position_enu_m,
            velocity_enu_mps: own.velocity_enu_mps,
            altitude_m: own.position_enu_m.z,
        };
        let look = Look {
            draws: &self.draws,
            key: mix(self.seed, 2),
            k,
            dt_s,
            own,
        };
        match nav.model.report(&mut self.own_state, &look, &me) {
            Some(r) => (r.position_enu_m, r.velocity_enu_mps, uncertainty(&r)),
            None => exact,
        }
    }

    /// Judge every tracked intruder at the alerting step `t_s`.
    fn alert(&mut self, t_s: f64, own: &Own) {
        let (own_p, own_v, own_u) = self.own_sensed(t_s, own);
        if let Some(daa) = &mut self.daa {
            row(daa, "Own", own_p, own_v, t_s, &own_u);
        }
        let Some(alerter) = self.config.alerters.first() else {
            return;
        };
        for (&i, (_, report)) in &self.tracks {
            let u = uncertainty(report);
            if let Some(daa) = &mut self.daa {
                row(
                    daa,
                    &format!("Intruder{i}"),
                    report.position_enu_m,
                    report.velocity_enu_mps,
                    t_s,
                    &u,
                );
            }
            let rel = Relative {
                s_m: own_p - report.position_enu_m,
                v_mps: own_v - report.velocity_enu_mps,
            };
            let errors = self
                .config
                .z_scores
                .errors(&own_u, &u, rel.s_m.truncate().length());
            let filter = self.filters.entry(i).or_insert_with(|| {
                Filter::new(
                    self.config.hysteresis_time_s,
                    self.config.persistence_time_s,
                    self.config.alerting_m,
                    self.config.alerting_n,
                )
            });
            let raw = alerter.raw_level_with(
                &rel,
                &errors,
                self.config.lookahead_s,
                filter.previous(t_s),
            );
            let level = filter.step(raw, t_s);
            let found = &mut self.found;
            found.max_level = found.max_level.max(level);
            for l in 1..=level.clamp(0, 3) {
                found.first_level_t_s[(l - 1) as usize].get_or_insert(t_s);
            }
        }
    }

    /// What it found, and the sensed states' state file (when asked for).
    pub fn finish(self) -> (SensedAlerting, Option<String>) {
        (self.found, self.daa)
    }
}

/// A report's uncertainty as DAIDALUS's columns: the same sigma east and north, uncorrelated.
fn uncertainty(r: &TargetReport) -> Uncertainty {
    Uncertainty {
        s_ew_m: r.position_sigma_m,
        s_ns_m: r.position_sigma_m,
        s_en_m: 0.0,
        sz_m: r.altitude_sigma_m,
        v_ew_mps: r.velocity_sigma_mps,
        v_ns_mps: r.velocity_sigma_mps,
        v_en_mps: 0.0,
        vz_mps: r.vertical_rate_sigma_mps,
    }
}

/// One state file row.
fn row(out: &mut String, name: &str, p: DVec3, v: DVec3, t_s: f64, u: &Uncertainty) {
    let _ =
        writeln!(
        out,
        "{name}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {t_s:.1}, {:.6}, {:.6}, {:.6}, {:.6}, \
         {:.6}, {:.6}, {:.6}, {:.6}",
        p.x, p.y, p.z, v.x, v.y, v.z, u.s_ew_m, u.s_ns_m, u.s_en_m, u.sz_m, u.v_ew_mps,
        u.v_ns_mps, u.v_en_mps, u.vz_mps
    );
}

/// The ownship of an encounter as a surveillance device sees it from (level, nose along its
/// velocity).
pub fn own_of(position_enu_m: DVec3, velocity_enu_mps: DVec3, enu_from_frd: DQuat) -> Own {
    Own {
        position_enu_m,
        velocity_enu_mps,
        enu_from_frd,
    }
}

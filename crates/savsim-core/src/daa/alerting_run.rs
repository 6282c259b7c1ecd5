//! A state file's alerting, step by step and intruder by intruder: what DAIDALUS's
//! `DaidalusAlerting` reports (the alert level, the time to each level's volume, the current
//! separations and closure rates, the projected miss distances and times), in SI units.

use std::collections::HashMap;

use glam::DVec3;

use crate::daa::alerting::{Conflict, Filter};
use crate::daa::conf::Config;
use crate::daa::projection::TangentPlane;
use crate::daa::scenario::{AlerterRef, Position, State, Step};
use crate::daa::well_clear::Relative;

/// One intruder at one step.
#[derive(Debug, Clone, PartialEq)]
pub struct AlertRow {
    /// The step's time, seconds.
    pub time_s: f64,
    /// The ownship's name.
    pub ownship: String,
    /// The intruder's name.
    pub traffic: String,
    /// The alerter used (1-based).
    pub alerter: usize,
    /// The filtered alert level (0: none).
    pub level: i32,
    /// For each level of the alerter, when its volume's violation starts, seconds (infinite
    /// when there is none within the lookahead).
    pub time_to_volume_s: Vec<f64>,
    /// Horizontal separation, metres.
    pub horizontal_m: f64,
    /// Vertical separation (absolute), metres.
    pub vertical_m: f64,
    /// Relative horizontal speed, m/s.
    pub horizontal_closure_mps: f64,
    /// Relative vertical speed (absolute), m/s.
    pub vertical_closure_mps: f64,
    /// Horizontal miss distance within the lookahead, metres.
    pub hmd_m: f64,
    /// Vertical miss distance within the lookahead, metres.
    pub vmd_m: f64,
    /// Time to horizontal closest approach (0 when diverging), seconds.
    pub tcpa_s: f64,
    /// Horizontal distance at the closest approach (now when diverging), metres.
    pub dcpa_m: f64,
    /// Time to co-altitude when ahead, seconds.
    pub tcoa_s: Option<f64>,
    /// Modified tau for the corrective level's DTHR, when closing outside it, seconds.
    pub tau_mod_s: Option<f64>,
}

/// The relative state of `intruder` to `ownship` (ownship minus intruder), Euclidean.
pub fn relative(ownship: &State, intruder: &State) -> Relative {
    let (s, v) = match (ownship.position, intruder.position) {
        (
            Position::Geodetic {
                lat_deg,
                lon_deg,
                alt_m,
            },
            Position::Geodetic {
                lat_deg: lat_i,
                lon_deg: lon_i,
                alt_m: alt_i,
            },
        ) => {
            let plane = TangentPlane::at(lat_deg, lon_deg, alt_m);
            let own_v = plane.project_velocity(lat_deg, lon_deg, alt_m, ownship.velocity_enu_mps);
            let own_s = plane.project(lat_deg, lon_deg, alt_m);
            let intr_s = plane.project(lat_i, lon_i, alt_i);
            let intr_v = plane.project_velocity(lat_i, lon_i, alt_i, intruder.velocity_enu_mps);
            (own_s - intr_s, own_v - intr_v)
        }
        (Position::Euclidean(own), Position::Euclidean(intr)) => (
            own - intr,
            ownship.velocity_enu_mps - intruder.velocity_enu_mps,
        ),
        // A file mixes both only if it is malformed: compare without projecting.
        _ => (DVec3::NAN, DVec3::NAN),
    };
    Relative { s_m: s, v_mps: v }
}

/// The alerter (0-based) a row names, or the first.
fn alerter_of(config: &Config, state: &State) -> Option<usize> {
    match &state.alerter {
        None => Some(0),
        Some(AlerterRef::Index(k)) => k.checked_sub(1),
        Some(AlerterRef::Name(name)) => config.alerters.iter().position(|a| &a.name == name),
    }
    .filter(|&k| k < config.alerters.len())
}

/// Every step's rows: one per intruder whose alerter exists, in the file's order.
///
/// ```
/// use savsim_core::daa::{alerting_run::alert_rows, conf::Config, scenario::parse};
/// let conf = "alerters = A\nA_alert_1_detector = d\nA_alert_1_alerting_time = 30 [s]\n\
///     A_d_WCV_DTHR = 600 [m]\nA_d_WCV_ZTHR = 100 [m]\nA_d_WCV_TTHR = 0 [s]\nA_d_WCV_TCOA = 0 [s]\n\
///     A_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD\n";
/// // Head on at 100 m/s closing, 3000 m apart: inside 600 m 24 s from now.
/// let daa = "name sx sy sz vx vy vz time\n[none] [m] [m] [m] [m/s] [m/s] [m/s] [s]\n\
///     own 0 0 0 50 0 0 0\nintr 3000 0 0 -50 0 0 0\n";
/// let rows = alert_rows(&parse(daa).unwrap(), &Config::parse(conf).unwrap());
/// assert!((rows[0].time_to_volume_s[0] - 24.0).abs() < 1e-9);
/// assert_eq!(rows[0].level, 1);
/// ```
pub fn alert_rows(steps: &[Step], config: &Config) -> Vec<AlertRow> {
    let mut filters: HashMap<String, Filter> = HashMap::new();
    let mut ownship_name: Option<&str> = None;
    let mut rows = Vec::new();
    for step in steps {
        let Some((own, traffic)) = step.aircraft.split_first() else {
            continue;
        };
        if ownship_name != Some(own.name.as_str()) {
            filters.clear();
            ownship_name = Some(own.name.as_str());
        }
        for intruder in traffic {
            let by = if config.ownship_centric {
                own
            } else {
                intruder
            };
            let Some(alerter_index) = alerter_of(config, by) else {
                continue;
            };
            let filter = filters.entry(intruder.name.clone()).or_insert_with(|| {
                Filter::new(
                    config.hysteresis_time_s,
                    config.persistence_time_s,
                    config.alerting_m,
                    config.alerting_n,
                )
            });
            rows.push(row(
                config,
                alerter_index,
                step.time_s,
                own,
                intruder,
                filter,
            ));
        }
    }
    rows
}

fn row(
    config: &Config,
    alerter_index: usize,
    time_s: f64,
    own: &State,
    intruder: &State,
    filter: &mut Filter,
) -> AlertRow {
    let alerter = &config.alerters[alerter_index];
    let rel = relative(own, intruder);
    let lookahead = config.lookahead_s;
    let errors = config.z_scores.errors(
        &own.uncertainty,
        &intruder.uncertainty,
        rel.s_m.truncate().length(),
    );
    let raw = alerter.raw_level_with(&rel, &errors, lookahead, filter.previous(time_s));
    let level = filter.step(raw, time_s);
    let time_to_volume_s = alerter
        .levels
        .iter()
        .map(|l| {
            let c = Conflict::of_level(l, &rel, &errors, lookahead);
            if c.lasts() {
                c.time_in_s
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let corrective = config
        .corrective_level(0)
        .and_then(|k| config.alerters[0].levels.get(k - 1));
    let (s, v) = (rel.s_m, rel.v_mps);
    let tcpa = rel.tcpa_s();
    AlertRow {
        time_s,
        ownship: own.name.clone(),
        traffic: intruder.name.clone(),
        alerter: alerter_index + 1,
        level,
        time_to_volume_s,
        horizontal_m: s.truncate().length(),
        vertical_m: s.z.abs(),
        horizontal_closure_mps: v.truncate().length(),
        vertical_closure_mps: v.z.abs(),
        hmd_m: rel.hmd_m(lookahead),
        vmd_m: rel.vmd_m(lookahead),
        tcpa_s: tcpa.max(0.0),
        dcpa_m: if tcpa <= 0.0 {
            s.truncate().length()
        } else {
            (s.truncate() + v.truncate() * tcpa).length()
        },
        tcoa_s: rel.tcoa_s().filter(|t| *t >= 0.0),
        tau_mod_s: corrective.and_then(|l| rel.tau_mod_s(l.volume.dthr_m)),
    }
}

//! What savsim measures of a run, the same in batch and study results: its contacts (the
//! contact layer's collisions and near misses), each vehicle's closest approach to each moving
//! body, NMAC and well clear; and those as the results' columns, written here once for both
//! tables (each table places the groups in its own order).

use std::sync::Arc;

use arrow_array::{ArrayRef, BooleanArray, Float64Array, StringArray, UInt8Array};
use arrow_schema::{DataType, Field, Fields};
use serde::Serialize;

use crate::collision::digest::EventDigest;
use crate::daa::approach::Approaches;
use crate::pipeline::PipelineTotals;
use crate::runs::table::{bools, counts, floats, strings, struct_lists};

/// The closest approach of one vehicle to one moving body.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ApproachRow {
    /// The vehicle (MAVLink system id; 1 for an encounter's ownship).
    pub vehicle: u8,
    /// Its MAVLink component id (1 for an autopilot; a fleet past 250 vehicles numbers them by
    /// component).
    pub component: u8,
    /// The other track's id (`intruder`, `vehicle:2`, `icao:4840D6`, a scene's track).
    pub track: String,
    /// Least separation of the two reference points, metres.
    pub distance_m: f64,
    /// Horizontal separation then, metres.
    pub horizontal_m: f64,
    /// Vertical separation then (other above the vehicle positive), metres.
    pub vertical_m: f64,
    /// When, seconds after the run's start.
    pub t_s: f64,
    /// Ever within 500 ft horizontally and 100 ft vertically at once.
    pub nmac: bool,
    /// Well clear with this track ever lost (false when it is not judged).
    pub lowc: bool,
}

/// What a run's collision pipeline and approaches found. Times are seconds after the run's
/// start.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Measured {
    /// Collision ticks (vehicle samples).
    pub ticks: u64,
    /// Collisions reported.
    pub collisions: u64,
    /// Time of impact of the first.
    pub first_collision_t_s: Option<f64>,
    /// What it hit.
    pub first_collision_obstacle: Option<String>,
    /// Near misses reported.
    pub near_misses: u64,
    /// The closest of them, metres.
    pub closest_near_miss_m: Option<f64>,
    /// Any NMAC with any moving body.
    pub nmac: bool,
    /// The closest approach to any moving body, metres.
    pub cpa_m: Option<f64>,
    /// Its horizontal part.
    pub cpa_horizontal_m: Option<f64>,
    /// Its vertical part.
    pub cpa_vertical_m: Option<f64>,
    /// Its time.
    pub cpa_t_s: Option<f64>,
    /// The body it was with.
    pub cpa_track: Option<String>,
    /// The closest approach to each moving body.
    pub approaches: Vec<ApproachRow>,
    /// Any loss of well clear with any moving body (the volume the run judged with; small UAS,
    /// 2000 ft / 250 ft, by default).
    pub lowc: bool,
    /// When the first began.
    pub lowc_first_t_s: Option<f64>,
    /// Total time without well clear, over every moving body, seconds.
    pub lowc_duration_s: f64,
    /// Least modified tau seen while closing with any moving body, seconds.
    pub min_taumod_s: Option<f64>,
    /// Least horizontal separation within a loss of well clear, metres.
    pub lowc_min_horizontal_m: Option<f64>,
    /// Least vertical separation within a loss of well clear, metres.
    pub lowc_min_vertical_m: Option<f64>,
}

impl Measured {
    /// What a run found: its pipeline's totals, what its events add up to and its closest
    /// approaches; times become seconds after `t0_s`.
    pub fn record(
        &mut self,
        totals: &PipelineTotals,
        digest: &EventDigest,
        approaches: &Approaches,
        t0_s: f64,
    ) {
        self.ticks = totals.ticks;
        self.collisions = totals.collisions;
        self.near_misses = totals.near_misses;
        if let Some((t, obstacle)) = digest.first_collision() {
            self.first_collision_t_s = Some(t - t0_s);
            self.first_collision_obstacle = Some(obstacle.to_owned());
        }
        self.closest_near_miss_m = digest.closest_near_miss_m();
        self.record_approaches(approaches, t0_s);
        self.record_well_clear(approaches, t0_s);
    }

    /// Every approach, the closest of them, and whether any was an NMAC.
    fn record_approaches(&mut self, approaches: &Approaches, t0_s: f64) {
        self.approaches = approaches
            .pairs()
            .into_iter()
            .map(|(vehicle, pair)| ApproachRow {
                vehicle: vehicle.system_id,
                component: vehicle.component_id,
                track: pair.id.to_string(),
                distance_m: pair.approach.distance_m,
                horizontal_m: pair.approach.horizontal_m,
                vertical_m: pair.approach.vertical_m,
                t_s: pair.approach.t_s - t0_s,
                nmac: pair.approach.nmac,
                lowc: !pair.well_clear.episodes.is_empty(),
            })
            .collect();
        self.nmac = self.approaches.iter().any(|a| a.nmac);
        // The closest; the first listed on a tie (the list is in a fixed order).
        let closest =
            self.approaches
                .iter()
                .reduce(|a, b| if b.distance_m < a.distance_m { b } else { a });
        if let Some(c) = closest {
            self.cpa_m = Some(c.distance_m);
            self.cpa_horizontal_m = Some(c.horizontal_m);
            self.cpa_vertical_m = Some(c.vertical_m);
            self.cpa_t_s = Some(c.t_s);
            self.cpa_track = Some(c.track.clone());
        }
    }

    /// Losses of well clear over every pair: whether any, the first, their total length, and
    /// the least modified tau and separations.
    fn record_well_clear(&mut self, approaches: &Approaches, t0_s: f64) {
        let pairs = approaches.pairs();
        let logs = || pairs.iter().map(|(_, pair)| &pair.well_clear);
        let episodes = || logs().flat_map(|l| l.episodes.iter());
        self.lowc = episodes().next().is_some();
        self.lowc_first_t_s = episodes().map(|e| e.start_t_s - t0_s).reduce(f64::min);
        self.lowc_duration_s = logs().map(|l| l.duration_s()).sum();
        self.min_taumod_s = logs().filter_map(|l| l.min_tau_mod_s).reduce(f64::min);
        self.lowc_min_horizontal_m = episodes().map(|e| e.min_horizontal_m).reduce(f64::min);
        self.lowc_min_vertical_m = episodes().map(|e| e.min_vertical_m).reduce(f64::min);
    }
}

/// Named columns of a results table.
pub type Columns = Vec<(&'static str, ArrayRef)>;

/// The contact layer's: `collisions`, `first_collision_t_s`, `first_collision_obstacle`,
/// `near_misses`.
pub fn contact_columns<R>(rows: &[R], m: impl Fn(&R) -> &Measured + Copy) -> Columns {
    vec![
        ("collisions", counts(rows, |r| Some(m(r).collisions))),
        (
            "first_collision_t_s",
            floats(rows, |r| m(r).first_collision_t_s),
        ),
        (
            "first_collision_obstacle",
            strings(rows, |r| m(r).first_collision_obstacle.as_deref()),
        ),
        ("near_misses", counts(rows, |r| Some(m(r).near_misses))),
    ]
}

/// The closest approach to any moving body: `nmac`, `cpa_m`, `cpa_horizontal_m`,
/// `cpa_vertical_m`, `cpa_t_s`, `cpa_track`.
pub fn cpa_columns<R>(rows: &[R], m: impl Fn(&R) -> &Measured + Copy) -> Columns {
    vec![
        ("nmac", bools(rows, |r| Some(m(r).nmac))),
        ("cpa_m", floats(rows, |r| m(r).cpa_m)),
        ("cpa_horizontal_m", floats(rows, |r| m(r).cpa_horizontal_m)),
        ("cpa_vertical_m", floats(rows, |r| m(r).cpa_vertical_m)),
        ("cpa_t_s", floats(rows, |r| m(r).cpa_t_s)),
        ("cpa_track", strings(rows, |r| m(r).cpa_track.as_deref())),
    ]
}

/// Well clear with any moving body: `lowc`, `lowc_first_t_s`, `lowc_duration_s`,
/// `min_taumod_s`.
pub fn lowc_columns<R>(rows: &[R], m: impl Fn(&R) -> &Measured + Copy) -> Columns {
    vec![
        ("lowc", bools(rows, |r| Some(m(r).lowc))),
        ("lowc_first_t_s", floats(rows, |r| m(r).lowc_first_t_s)),
        (
            "lowc_duration_s",
            floats(rows, |r| Some(m(r).lowc_duration_s)),
        ),
        ("min_taumod_s", floats(rows, |r| m(r).min_taumod_s)),
    ]
}

fn approach_fields() -> Fields {
    Fields::from(vec![
        Field::new("vehicle", DataType::UInt8, false),
        Field::new("component", DataType::UInt8, false),
        Field::new("track", DataType::Utf8, false),
        Field::new("distance_m", DataType::Float64, false),
        Field::new("horizontal_m", DataType::Float64, false),
        Field::new("vertical_m", DataType::Float64, false),
        Field::new("t_s", DataType::Float64, false),
        Field::new("nmac", DataType::Boolean, false),
        Field::new("lowc", DataType::Boolean, false),
    ])
}

/// `approaches`: each row's approaches, as a list of structs.
pub fn approaches_column<R>(rows: &[R], m: impl Fn(&R) -> &Measured) -> (&'static str, ArrayRef) {
    let lists: Vec<&[ApproachRow]> = rows.iter().map(|r| m(r).approaches.as_slice()).collect();
    let all: Vec<&ApproachRow> = lists.iter().flat_map(|l| l.iter()).collect();
    let float = |f: fn(&ApproachRow) -> f64| -> ArrayRef {
        Arc::new(all.iter().map(|a| f(a)).collect::<Float64Array>())
    };
    let children: Vec<ArrayRef> = vec![
        Arc::new(all.iter().map(|a| a.vehicle).collect::<UInt8Array>()),
        Arc::new(all.iter().map(|a| a.component).collect::<UInt8Array>()),
        Arc::new(
            all.iter()
                .map(|a| Some(a.track.as_str()))
                .collect::<StringArray>(),
        ),
        float(|a| a.distance_m),
        float(|a| a.horizontal_m),
        float(|a| a.vertical_m),
        float(|a| a.t_s),
        Arc::new(all.iter().map(|a| Some(a.nmac)).collect::<BooleanArray>()),
        Arc::new(all.iter().map(|a| Some(a.lowc)).collect::<BooleanArray>()),
    ];
    let array = struct_lists(approach_fields(), children, lists.iter().map(|l| l.len()));
    ("approaches", array)
}

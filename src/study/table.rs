//! A study's results as Parquet (snappy), one row per study row, in manifest order; each
//! shard one file, written whole or not at all. `obstacles`, `approaches` and `vehicles` are
//! lists of structs; the rest is flat. The file's metadata holds savsim's version and the study's configuration.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, RecordBatch, StringArray, UInt64Array, UInt8Array,
};
use arrow_schema::{DataType, Field, Fields};

use crate::error::Result;
use crate::runs::measured::{
    approaches_column, contact_columns, cpa_columns, lowc_columns, Measured,
};
use crate::runs::table::{counts, floats, strings, struct_lists, Settings};
use crate::study::result::{StudyResult, VehicleResult};

type Rows<'a> = &'a [StudyResult];

fn bools(rows: Rows<'_>, f: impl Fn(&StudyResult) -> bool) -> ArrayRef {
    crate::runs::table::bools(rows, |r| Some(f(r)))
}

fn obstacle_fields() -> Fields {
    Fields::from(vec![
        Field::new("obstacle", DataType::Utf8, false),
        Field::new("closest_m", DataType::Float64, false),
    ])
}

fn obstacles(rows: Rows<'_>) -> ArrayRef {
    let all: Vec<_> = rows.iter().flat_map(|r| &r.obstacles).collect();
    let children: Vec<ArrayRef> = vec![
        Arc::new(
            all.iter()
                .map(|o| Some(o.obstacle.as_str()))
                .collect::<StringArray>(),
        ),
        Arc::new(
            all.iter()
                .map(|o| Some(o.closest_m))
                .collect::<Float64Array>(),
        ),
    ];
    struct_lists(
        obstacle_fields(),
        children,
        rows.iter().map(|r| r.obstacles.len()),
    )
}

fn vehicle_fields() -> Fields {
    let field = |name: &str, kind: DataType, nullable: bool| Field::new(name, kind, nullable);
    Fields::from(vec![
        field("role", DataType::Utf8, false),
        field("system_id", DataType::UInt8, false),
        field("autopilot", DataType::Utf8, false),
        field("legs_completed", DataType::UInt64, false),
        field("plan_completed", DataType::Boolean, false),
        field("modes", DataType::Utf8, false),
        field("avoidance_texts", DataType::Utf8, false),
        field("first_acted_t_s", DataType::Float64, true),
        field("clock_speedup", DataType::Float64, false),
        field("clock_skew_s", DataType::Float64, false),
        field("autopilot_version", DataType::Utf8, true),
        field("track", DataType::Utf8, true),
    ])
}

/// Every vehicle of each row ([`StudyResult::vehicles`]), as a list of structs.
fn vehicles(rows: Rows<'_>) -> ArrayRef {
    let each: Vec<Vec<VehicleResult>> = rows.iter().map(StudyResult::vehicles).collect();
    let all: Vec<&VehicleResult> = each.iter().flatten().collect();
    let text = |f: fn(&VehicleResult) -> Option<String>| -> ArrayRef {
        Arc::new(all.iter().map(|v| f(v)).collect::<StringArray>())
    };
    let float = |f: fn(&VehicleResult) -> Option<f64>| -> ArrayRef {
        Arc::new(all.iter().map(|v| f(v)).collect::<Float64Array>())
    };
    let children: Vec<ArrayRef> = vec![
        text(|v| Some(v.role.clone())),
        Arc::new(
            all.iter()
                .map(|v| Some(v.system_id))
                .collect::<UInt8Array>(),
        ),
        text(|v| Some(v.autopilot.clone())),
        Arc::new(
            all.iter()
                .map(|v| Some(v.legs_completed))
                .collect::<UInt64Array>(),
        ),
        Arc::new(
            all.iter()
                .map(|v| Some(v.plan_completed))
                .collect::<BooleanArray>(),
        ),
        text(|v| Some(v.did.modes.join(","))),
        text(|v| Some(v.did.avoidance_texts.join(" | "))),
        float(|v| v.did.first_acted_t_s),
        float(|v| Some(v.clock_speedup)),
        float(|v| Some(v.clock_skew_s)),
        text(|v| v.did.version.clone()),
        text(|v| v.track.clone()),
    ];
    struct_lists(vehicle_fields(), children, each.iter().map(Vec::len))
}

/// The inputs' columns.
fn input_columns(rows: Rows<'_>) -> Vec<(&'static str, ArrayRef)> {
    let text = |f: fn(&StudyResult) -> Option<&String>| strings(rows, move |r| f(r).cloned());
    vec![
        ("index", counts(rows, |r| Some(r.index))),
        ("row_id", strings(rows, |r| Some(r.row_id.clone()))),
        ("scene", text(|r| r.inputs.scene.as_ref())),
        ("autopilot", strings(rows, |r| Some(r.autopilot.clone()))),
        ("variant", text(|r| r.inputs.variant.as_ref())),
        ("pair", text(|r| r.inputs.pair.as_ref())),
        ("params", text(|r| r.inputs.params.as_ref())),
        ("feed", text(|r| r.inputs.feed.as_ref())),
        ("sensors", text(|r| r.inputs.sensors.as_ref())),
        ("sensor_seed", counts(rows, |r| Some(r.sensor_seed))),
        ("plan", text(|r| r.inputs.plan.as_ref())),
        ("intruder", text(|r| r.inputs.intruder.as_ref())),
        ("intruder_kind", text(|r| r.inputs.intruder_kind.as_ref())),
        ("duration_s", floats(rows, |r| r.inputs.duration_s)),
        ("speedup", floats(rows, |r| Some(r.speedup))),
        ("seed", counts(rows, |r| r.inputs.seed)),
        ("w", floats(rows, |r| r.inputs.w)),
        (
            "intruder_autopilot",
            text(|r| r.inputs.intruder_autopilot.as_ref()),
        ),
        ("intruder_plan", text(|r| r.inputs.intruder_plan.as_ref())),
        (
            "intruder_params",
            text(|r| r.inputs.intruder_params.as_ref()),
        ),
        ("intruder_home", text(|r| r.inputs.intruder_home.as_ref())),
        ("physics", strings(rows, |r| Some(r.physics.clone()))),
        ("frame", strings(rows, |r| r.frame.clone())),
        ("step_ms", floats(rows, |r| r.step_ms)),
        ("wind", text(|r| r.inputs.wind.as_ref())),
    ]
}

/// What was measured and what the autopilot did.
fn result_columns(rows: Rows<'_>) -> Vec<(&'static str, ArrayRef)> {
    fn m(r: &StudyResult) -> &Measured {
        &r.measured
    }
    let mut columns = vec![
        ("outcome", strings(rows, |r| Some(r.outcome.name()))),
        ("error", strings(rows, |r| r.error.clone())),
    ];
    columns.extend(contact_columns(rows, m));
    columns.extend([
        ("closest_obstacle_m", floats(rows, |r| r.closest_obstacle_m)),
        ("obstacles", obstacles(rows)),
        approaches_column(rows, m),
    ]);
    columns.extend(cpa_columns(rows, m));
    columns.push(("vehicle_track", strings(rows, |r| r.track.clone())));
    columns.extend(lowc_columns(rows, m));
    columns.extend(autopilot_columns(rows));
    columns.extend(told_columns(rows));
    columns.extend(other_vehicle_columns(rows));
    columns.extend(estimate_columns(rows));
    columns.extend([
        ("vehicles", vehicles(rows)),
        ("sim_s", floats(rows, |r| Some(r.sim_s))),
        ("wall_s", floats(rows, |r| Some(r.wall_s))),
        (
            "achieved_speedup",
            floats(rows, |r| Some(r.achieved_speedup)),
        ),
    ]);
    columns
}

/// What the autopilot did: when it armed, how far its plan got, its modes, COLLISION
/// messages and avoidance texts, when it first acted, its version.
fn autopilot_columns(rows: Rows<'_>) -> Vec<(&'static str, ArrayRef)> {
    vec![
        ("armed_t_s", floats(rows, |r| r.armed_t_s)),
        ("legs_completed", counts(rows, |r| Some(r.legs_completed))),
        ("plan_completed", bools(rows, |r| r.plan_completed)),
        (
            "modes",
            strings(rows, |r| Some(r.autopilot_did.modes.join(","))),
        ),
        (
            "autopilot_collisions",
            counts(rows, |r| Some(r.autopilot_did.collision_messages)),
        ),
        (
            "avoidance_texts",
            strings(rows, |r| Some(r.autopilot_did.avoidance_texts.join(" | "))),
        ),
        (
            "avoidance_texts_not_kept",
            counts(rows, |r| Some(r.autopilot_did.avoidance_texts_not_kept)),
        ),
        (
            "first_acted_t_s",
            floats(rows, |r| r.autopilot_did.first_acted_t_s),
        ),
        (
            "autopilot_version",
            strings(rows, |r| r.autopilot_did.version.clone()),
        ),
    ]
}

/// With savsim's physics: how far the autopilot's own estimate strayed from the truth; the
/// steps, and where the wall time went (measured).
fn estimate_columns(rows: Rows<'_>) -> Vec<(&'static str, ArrayRef)> {
    vec![
        (
            "estimate_error_h_max_m",
            floats(rows, |r| r.estimate.map(|e| e.horizontal_max_m)),
        ),
        (
            "estimate_error_h_mean_m",
            floats(rows, |r| r.estimate.map(|e| e.horizontal_mean_m)),
        ),
        (
            "estimate_error_v_max_m",
            floats(rows, |r| r.estimate.map(|e| e.vertical_max_m)),
        ),
        (
            "lockstep_steps",
            counts(rows, |r| r.lockstep_times.map(|t| t.steps)),
        ),
        (
            "wall_autopilots_s",
            floats(rows, |r| r.lockstep_times.map(|t| t.autopilots_s)),
        ),
        (
            "wall_pilots_s",
            floats(rows, |r| r.lockstep_times.map(|t| t.pilots_s)),
        ),
        (
            "wall_savsim_s",
            floats(rows, |r| r.lockstep_times.map(|t| t.savsim_s)),
        ),
        (
            "wall_companions_s",
            floats(rows, |r| r.lockstep_times.map(|t| t.companions_s)),
        ),
        ("companion_calls", counts(rows, |r| r.companion_calls)),
        ("companion_commands", counts(rows, |r| r.companion_commands)),
        ("companion_p99_ms", floats(rows, |r| r.companion_p99_ms)),
        ("companion_skipped", counts(rows, |r| r.companion_skipped)),
    ]
}

/// What the feed told the vehicle: its frames, the first report and the closest reported
/// approach, reports received and lost, how late the feed was.
fn told_columns(rows: Rows<'_>) -> Vec<(&'static str, ArrayRef)> {
    vec![
        ("feed_frames", counts(rows, |r| Some(r.feed_frames))),
        (
            "first_detection_s",
            floats(rows, |r| r.told.first_detection_s),
        ),
        (
            "first_detection_range_m",
            floats(rows, |r| r.told.first_detection_range_m),
        ),
        (
            "sensed_closest_m",
            floats(rows, |r| r.told.sensed_closest_m),
        ),
        ("reports_lost", counts(rows, |r| Some(r.told.reports_lost))),
        (
            "reports_received",
            counts(rows, |r| Some(r.told.reports_received)),
        ),
        (
            "feed_latency_p99_us",
            counts(rows, |r| r.feed_latency_p99_us),
        ),
        (
            "feed_latency_max_us",
            counts(rows, |r| r.feed_latency_max_us),
        ),
    ]
}

/// A row of several vehicles: its clocks, who acted first, and the second vehicle's own.
fn other_vehicle_columns(rows: Rows<'_>) -> Vec<(&'static str, ArrayRef)> {
    vec![
        ("clock_skew_s", floats(rows, |r| r.clock_skew_s)),
        ("clock_speedup", floats(rows, |r| r.clock_speedup)),
        (
            "intruder_clock_speedup",
            floats(rows, |r| r.others.first().map(|s| s.clock_speedup)),
        ),
        ("first_to_act", strings(rows, StudyResult::first_to_act)),
        (
            "intruder_track",
            strings(rows, |r| r.others.first().and_then(|s| s.track.clone())),
        ),
        (
            "intruder_legs_completed",
            counts(rows, |r| r.others.first().map(|s| s.legs_completed)),
        ),
        (
            "intruder_plan_completed",
            crate::runs::table::bools(rows, |r| r.others.first().map(|s| s.plan_completed)),
        ),
        (
            "intruder_modes",
            strings(rows, |r| r.others.first().map(|s| s.did.modes.join(","))),
        ),
        (
            "intruder_avoidance_texts",
            strings(rows, |r| {
                r.others.first().map(|s| s.did.avoidance_texts.join(" | "))
            }),
        ),
        (
            "intruder_first_acted_t_s",
            floats(rows, |r| {
                r.others.first().and_then(|s| s.did.first_acted_t_s)
            }),
        ),
        (
            "intruder_autopilot_version",
            strings(rows, |r| {
                r.others.first().and_then(|s| s.did.version.clone())
            }),
        ),
    ]
}

/// The results as one record batch (the full schema when there are no rows).
pub fn record_batch(rows: &[StudyResult]) -> RecordBatch {
    let columns: Vec<(&str, ArrayRef)> = input_columns(rows)
        .into_iter()
        .chain(result_columns(rows))
        .collect();
    crate::runs::table::record_batch(columns, |_| true)
}

/// Write the results to `path` atomically, `settings` in the file's metadata.
pub fn write_atomic(rows: &[StudyResult], settings: &Settings, path: &Path) -> Result<()> {
    crate::runs::table::write_atomic(&record_batch(rows), settings, path)
}

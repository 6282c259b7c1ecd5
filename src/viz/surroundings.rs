//! What is around a vehicle and what it was told, at each tick: the traffic (moving bodies),
//! the feed's readings and ADS-B reports, the lines it said, the tick's counts.

use std::collections::BTreeMap;

use glam::{DVec3, Vec3};
use rerun::components::FillMode;
use rerun::{Arrows3D, Boxes3D, Clear, Color, Points3D, RecordingStream, RecordingStreamResult};

use super::draw::{kind_color, local};
use super::paths;
use super::rows::Rows;
use crate::collision::bodies::BodySource;
use crate::observe::{NoteFrame, TickFrame};
use crate::scene::Scene;

/// The closed-loop feed's readings at a feed frame: what the autopilot was told, green where
/// something was seen (drawn to it), grey where nothing was (drawn to the range's end).
pub(super) fn log_feed(
    rec: &RecordingStream,
    f: &TickFrame,
    position: Vec3,
) -> RecordingStreamResult<()> {
    if f.feed.is_empty() {
        return Ok(());
    }
    let vectors = f.feed.iter().map(|r| {
        (r.dir_enu * r.distance_m.unwrap_or(f.feed_max_m))
            .as_vec3()
            .to_array()
    });
    let colors = f.feed.iter().map(|r| {
        if r.distance_m.is_some() {
            Color::from_rgb(40, 220, 90)
        } else {
            Color::from_unmultiplied_rgba(160, 160, 160, 80)
        }
    });
    rec.log(
        paths::vehicle_part(f.system_id, "feed"),
        &Arrows3D::from_vectors(vectors)
            .with_origins(std::iter::repeat_n(position.to_array(), f.feed.len()))
            .with_colors(colors),
    )
}

/// The ADS-B reports the feed sent at this tick, each where it put its aircraft (orange,
/// labelled), one entity per aircraft: each aircraft's last report stays drawn until its next.
pub(super) fn log_adsb_sent(
    rec: &RecordingStream,
    offset: DVec3,
    f: &TickFrame,
) -> RecordingStreamResult<()> {
    for sent in &f.adsb_sent {
        let (icao, label, p) = (&sent.icao_address, &sent.label, &sent.position_enu_m);
        rec.log(
            paths::vehicle_part(f.system_id, &format!("feed/adsb/{icao:06X}")),
            &Points3D::new([local(offset, *p).to_array()])
                .with_labels([label.as_str()])
                .with_radii([rerun::Radius::new_ui_points(6.0)])
                .with_colors([Color::from_rgb(255, 127, 14)]),
        )?;
    }
    Ok(())
}

/// A line a vehicle said, as a text log on its timelines (a MAVLink severity as rerun's level).
pub(super) fn log_note(
    rec: &RecordingStream,
    rows: &mut Rows,
    n: &NoteFrame,
) -> RecordingStreamResult<()> {
    rows.set_time(n.tick, f64::from(n.time_boot_ms) / 1000.0, n.t_s);
    let level = match n.severity {
        0..=3 => rerun::TextLogLevel::ERROR,
        4 => rerun::TextLogLevel::WARN,
        5 | 6 => rerun::TextLogLevel::INFO,
        _ => rerun::TextLogLevel::DEBUG,
    };
    rows.log(
        rec,
        paths::messages(n.system_id),
        &rerun::TextLog::new(n.text.as_str()).with_level(level),
    )
}

/// Moving obstacles other than vehicles (vehicles are drawn by their own ticks): a pose every
/// tick, and the box in its own frame once, when it appears; those gone since the last tick are
/// cleared.
pub(super) fn log_traffic(
    rec: &RecordingStream,
    rows: &mut Rows,
    shown: &mut BTreeMap<String, bool>,
    scene: &Scene,
    f: &TickFrame,
    offset: DVec3,
) -> RecordingStreamResult<()> {
    let mut seen = BTreeMap::new();
    for (_, name, kind, model, pose) in f
        .dynamic
        .iter()
        .filter(|d| !matches!(d.0.source, BodySource::Vehicle { .. }))
    {
        let path = paths::traffic(name);
        let q = pose.enu_from_body.as_quat();
        rows.pose(
            rec,
            path.clone(),
            local(offset, pose.position_enu_m).to_array(),
            rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]),
        )?;
        if !shown.contains_key(name) {
            let (cuboid, centre) = scene.geometries[*model].box_collider();
            rec.log(
                format!("{path}/box"),
                &Boxes3D::from_centers_and_half_sizes(
                    [centre.to_array()],
                    [cuboid.half_extents.to_array()],
                )
                .with_colors([kind_color(*kind)])
                .with_fill_mode(FillMode::Solid),
            )?;
        }
        seen.insert(name.clone(), true);
    }
    for name in shown.keys() {
        if !seen.contains_key(name) {
            rec.log(paths::traffic(name), &Clear::recursive())?;
        }
    }
    *shown = seen;
    Ok(())
}

/// The tick's cost, the active colliders and triangles (plain columns: cheap every tick).
pub(super) fn log_metrics(
    rec: &RecordingStream,
    rows: &mut Rows,
    f: &TickFrame,
) -> RecordingStreamResult<()> {
    let id = f.system_id;
    rows.scalar(rec, paths::cost(id), f.cost_us)?;
    rows.scalar(
        rec,
        paths::colliders_count(id, "box"),
        f.report.active_box as f64,
    )?;
    rows.scalar(
        rec,
        paths::colliders_count(id, "mesh"),
        f.report.active_mesh as f64,
    )?;
    rows.scalar(rec, paths::triangles(id), f.report.active_triangles as f64)
}

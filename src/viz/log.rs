//! The logger thread: turns each [`TickFrame`] into rerun entities (docs/rerun.md lists them)
//! and keeps the layout ([`blueprint`]) in step with the vehicles and the flown area.

use std::collections::{BTreeMap, VecDeque};

use glam::{DQuat, DVec3, Vec3};
use rerun::components::FillMode;
use rerun::{
    Arrows3D, Clear, Color, Mesh3D, Points3D, RecordingStream, RecordingStreamResult,
    ViewCoordinates,
};

use super::blueprint::{self, Layout, MAX_CHASE_VIEWS};
use super::colliders::{obstacle_name, ColliderView};
use super::draw::{
    box_of_geometry, boxes_of, kind_color, local, pose_of_static, see_through, viz_offset, LocalBox,
};
use super::markers::{Markers, Where, FOCUS_AFTER_S, FOCUS_BEFORE_S};
use super::rows::Rows;
use super::surroundings::{log_adsb_sent, log_feed, log_metrics, log_note, log_traffic};
use super::{paths, VizOptions};
use crate::observe::{ApproachFrame, Frame, TickFrame};
use crate::scene::{Aabb64, Kind, Scene};

/// Static scenes with at most this many triangles are drawn as meshes, larger ones as boxes.
const STATIC_MESH_BUDGET: usize = 500_000;
/// Points per track segment entity (`track/{k}`): each tick re-logs only the open segment.
const TRACK_SEGMENT: usize = 50;
/// Recent positions kept per vehicle to place near-miss markers at their closest time.
const RECENT_LEN: usize = 6000;
/// Vehicle colours, by order of appearance (the first is the pink the render check looks for).
pub const VEHICLE_COLORS: [[u8; 3]; 4] =
    [[255, 80, 200], [255, 170, 0], [0, 200, 255], [150, 255, 60]];

#[derive(Default)]
struct Vehicle {
    color: [u8; 3],
    model: Option<usize>,
    colliders: ColliderView,
    segment: u32,
    open_segment: Vec<[f32; 3]>,
    recent: VecDeque<(f64, Vec3)>,
    node: Option<Aabb64>,
    had_hits: bool,
    /// Which rays hit, as last logged (their colours).
    ray_hits: Option<Vec<bool>>,
    /// Its last tick, and its clock less the samples' clock then, seconds.
    last_tick: u64,
    clock_shift_s: f64,
}

struct State<'s> {
    scene: &'s Scene,
    options: &'s VizOptions,
    leaves: &'s [Aabb64],
    offset: DVec3,
    vehicles: BTreeMap<u8, Vehicle>,
    layout: Layout,
    markers: Markers,
    traffic: BTreeMap<String, bool>,
    rows: Rows,
    /// The first message's time, seconds (labels say "+N s" from it).
    t0_s: f64,
}

/// Why the logger thread stopped short.
#[derive(Debug, thiserror::Error)]
pub enum LoggerError {
    /// Logging to the recording stream failed.
    #[error(transparent)]
    Stream(#[from] rerun::RecordingStreamError),
    /// The stream could not be flushed at the end.
    #[error(transparent)]
    Flush(#[from] rerun::sink::SinkFlushError),
}

/// The thread's body: the scene, then every tick, then the final layout.
pub fn run(
    rec: RecordingStream,
    rx: std::sync::mpsc::Receiver<Frame>,
    scene: &Scene,
    leaves: &[Aabb64],
    options: &VizOptions,
) -> Result<(), LoggerError> {
    let mut state = State {
        scene,
        options,
        leaves,
        offset: viz_offset(scene),
        vehicles: BTreeMap::new(),
        layout: Layout {
            vehicle_time: options.vehicle_clock,
            ..Layout::default()
        },
        markers: Markers::default(),
        traffic: BTreeMap::new(),
        rows: Rows::new(options.live),
        t0_s: 0.0,
    };
    blueprint::send(&rec, &state.layout)?;
    log_scene(&rec, &state)?;
    for msg in rx {
        match msg {
            Frame::Tick(frame) => log_tick(&rec, &mut state, &frame)?,
            Frame::Note(note) => log_note(&rec, &mut state.rows, &note)?,
            Frame::Approaches(list) => log_approaches(&rec, &mut state, &list)?,
        }
    }
    state.rows.flush(&rec)?;
    if state.layout.vehicles.is_empty() {
        // Nothing flew (`scene show`): the overview frames the scene.
        state.layout.overview = scene_area(scene, state.offset);
        state.layout.scene_only = true;
    }
    blueprint::send(&rec, &state.layout)?;
    Ok(rec.flush_blocking()?)
}

/// The static scene's bounds, logged (viz-offset) metres; `None` without obstacles.
fn scene_area(scene: &Scene, offset: DVec3) -> Option<(Vec3, Vec3)> {
    let b = scene.bounds_enu_m();
    (b.min.cmple(b.max).all()).then(|| (local(offset, b.min), local(offset, b.max)))
}

fn log_scene(rec: &RecordingStream, state: &State<'_>) -> RecordingStreamResult<()> {
    rec.log_static(paths::WORLD, &ViewCoordinates::RIGHT_HAND_Z_UP())?;
    super::captures::log_classes(rec)?;
    let scene = state.scene;
    // A scene small enough is drawn with its real shapes; a big one (a generated city of
    // millions of triangles) with boxes.
    let triangles: usize = scene
        .obstacles
        .iter()
        .map(|o| o.geometry.triangle_count())
        .sum();
    let as_meshes = triangles <= STATIC_MESH_BUDGET;
    for kind in Kind::ALL {
        let of_kind = || {
            scene
                .obstacles
                .iter()
                .enumerate()
                .filter(move |(_, o)| o.kind == kind)
        };
        if of_kind().next().is_none() {
            continue;
        }
        let path = format!("{}/{}", paths::OBSTACLES, kind.name());
        if as_meshes {
            let mut positions: Vec<[f32; 3]> = Vec::new();
            let mut indices: Vec<rerun::TriangleIndices> = Vec::new();
            for (i, o) in of_kind() {
                let pose = pose_of_static(scene, i as u32);
                let (vertices, tris) = o.geometry.triangles();
                let base = positions.len() as u32;
                positions.extend(vertices.iter().map(|v| {
                    local(
                        state.offset,
                        pose.position_enu_m + pose.enu_from_body * v.as_dvec3(),
                    )
                    .to_array()
                }));
                indices.extend(tris.iter().map(|t| {
                    rerun::TriangleIndices([base + t[0], base + t[1], base + t[2]].into())
                }));
            }
            rec.log_static(
                path,
                &Mesh3D::new(positions)
                    .with_triangle_indices(indices)
                    .with_albedo_factor(see_through(kind_color(kind), 170).0),
            )?;
        } else {
            let items = of_kind().map(|(i, o)| {
                (
                    box_of_geometry(&o.geometry, &pose_of_static(scene, i as u32)),
                    see_through(kind_color(kind), 170),
                )
            });
            rec.log_static(path, &boxes_of(state.offset, FillMode::Solid, items))?;
        }
    }
    if state.options.whole_octree {
        let leaf_boxes = state.leaves.iter().map(|b| {
            (
                LocalBox::aligned(b),
                Color::from_unmultiplied_rgba(200, 200, 255, 60),
            )
        });
        rec.log_static(
            paths::OCTREE,
            &boxes_of(state.offset, FillMode::MajorWireframe, leaf_boxes),
        )?;
    }
    Ok(())
}

/// A chased vehicle's depth camera seen for the first time gets a view beside the chase
/// views (the layout is sent again).
fn image_appears(
    rec: &RecordingStream,
    layout: &mut Layout,
    c: &crate::observe::Capture,
) -> RecordingStreamResult<()> {
    if !matches!(c.data, crate::observe::CaptureData::Depth { .. })
        || !layout.chased.iter().any(|(id, _)| *id == c.system_id)
    {
        return Ok(());
    }
    let image = paths::sensor_image(c.system_id, &c.device);
    if layout.images.contains(&image) {
        return Ok(());
    }
    layout.images.push(image);
    send_live(rec, layout)
}

/// The layout while the flight goes on: the overview frames a kilometre around what is known.
fn send_live(rec: &RecordingStream, layout: &Layout) -> RecordingStreamResult<()> {
    let mut live = layout.clone();
    live.overview = live
        .overview
        .map(|(min, max)| (min - Vec3::splat(500.0), max + Vec3::splat(500.0)));
    blueprint::send(rec, &live)
}

/// The distance a chase eye keeps from a vehicle of this model: ten model radii, at least 5 m.
fn chase_distance_m(scene: &Scene, model: usize) -> f32 {
    let (cuboid, _) = scene.geometries[model].box_collider();
    (10.0 * cuboid.half_extents.length()).max(5.0)
}

fn grow(area: &mut Option<(Vec3, Vec3)>, p: Vec3) {
    *area = Some(match *area {
        Some((min, max)) => (min.min(p), max.max(p)),
        None => (p, p),
    });
}

fn log_tick(
    rec: &RecordingStream,
    state: &mut State<'_>,
    f: &TickFrame,
) -> RecordingStreamResult<()> {
    let scene = state.scene;
    // One time for the gathered rows and for what is logged directly.
    state
        .rows
        .set_time(f.tick, f64::from(f.time_boot_ms) / 1000.0, f.t_s);
    rec.set_timepoint(state.rows.time().clone());
    let id = f.system_id;
    let position = local(state.offset, f.pose.position_enu_m);
    grow(&mut state.layout.overview, position);
    if !state.vehicles.contains_key(&id) {
        vehicle_appears(rec, state, f)?;
    }
    let Some(v) = state.vehicles.get_mut(&id) else {
        return Ok(());
    };
    v.last_tick = f.tick;
    v.clock_shift_s = f64::from(f.time_boot_ms) / 1000.0 - f.t_s;
    state.t0_s = f.t0_s;
    let rows = &mut state.rows;
    log_body(rec, rows, v, scene, f, position)?;
    log_track(rec, rows, v, f, position)?;
    log_rays(rec, rows, v, f, state.offset, position)?;
    log_feed(rec, f, position)?;
    log_adsb_sent(rec, state.offset, f)?;
    for c in &f.captures {
        super::captures::log_capture(rec, state.offset, c)?;
        image_appears(rec, &mut state.layout, c)?;
    }
    log_node(rec, v, f, state.leaves, state.offset)?;
    // Colliders (what changed), and the beta of each one a ray sees.
    v.colliders.log(rec, scene, state.offset, f)?;
    for &(o, _, beta) in &f.colliders {
        if beta > 0.0 {
            if let Some(name) = obstacle_name(scene, f, o) {
                rows.scalar(rec, paths::beta(id, name), beta)?;
            }
        }
    }
    log_traffic(rec, rows, &mut state.traffic, scene, f, state.offset)?;
    for e in &f.events {
        let normal_m = chase_distance_m(scene, f.model) / 4.0;
        if let Some(focus) = state.markers.on_event(
            rec,
            e,
            f,
            Where {
                offset: state.offset,
                normal_m,
                recent: &v.recent,
                now: position,
            },
        )? {
            // On the vehicle's clock: the same span, seconds of its clock.
            let shift_s = f64::from(f.time_boot_ms) / 1000.0 - f.t_s;
            let focus = if state.layout.vehicle_time {
                (focus.0 + shift_s, focus.1 + shift_s)
            } else {
                focus
            };
            state.layout.focus_s.get_or_insert(focus);
        }
    }
    log_metrics(rec, rows, f)
}

/// A vehicle seen for the first time: its colour, and a chase view of its own (the layout
/// sent again) if there is room.
fn vehicle_appears(
    rec: &RecordingStream,
    state: &mut State<'_>,
    f: &TickFrame,
) -> RecordingStreamResult<()> {
    let id = f.system_id;
    let n = state.vehicles.len();
    state.layout.vehicles.push(id);
    state.vehicles.insert(
        id,
        Vehicle {
            color: VEHICLE_COLORS[n % VEHICLE_COLORS.len()],
            ..Vehicle::default()
        },
    );
    if state.layout.chased.len() >= MAX_CHASE_VIEWS {
        // No view of its own: the layout (which resets a live viewer's eyes) stays until the
        // end, when the overview learns to leave out this vehicle's rays and colliders too.
        return Ok(());
    }
    state
        .layout
        .chased
        .push((id, chase_distance_m(state.scene, f.model)));
    send_live(rec, &state.layout)
}

/// The body's pose, its model and axes (once per model), and the chase frame (position and
/// heading only).
fn log_body(
    rec: &RecordingStream,
    rows: &mut Rows,
    v: &mut Vehicle,
    scene: &Scene,
    f: &TickFrame,
    position: Vec3,
) -> RecordingStreamResult<()> {
    let id = f.system_id;
    let q = f.pose.enu_from_body.as_quat();
    rows.pose(
        rec,
        paths::body(id),
        position.to_array(),
        rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]),
    )?;
    let forward = f.pose.enu_from_body * DVec3::X;
    let heading = DQuat::from_rotation_z(forward.y.atan2(forward.x)).as_quat();
    rows.pose(
        rec,
        paths::chase(id),
        position.to_array(),
        rerun::Quaternion::from_xyzw([heading.x, heading.y, heading.z, heading.w]),
    )?;
    if v.model == Some(f.model) {
        return Ok(());
    }
    let model = &scene.geometries[f.model];
    let (vertices, indices) = model.triangles();
    rec.log_static(
        format!("{}/model", paths::body(id)),
        &Mesh3D::new(vertices.iter().map(|v| v.to_array()))
            .with_triangle_indices(
                indices
                    .into_iter()
                    .map(|t| rerun::TriangleIndices(t.into())),
            )
            .with_albedo_factor(Color::from_rgb(v.color[0], v.color[1], v.color[2]).0),
    )?;
    let axis_m = (3.0 * model.box_collider().0.half_extents.length()).max(1.0);
    rec.log_static(
        format!("{}/axes", paths::body(id)),
        &Arrows3D::from_vectors([[axis_m, 0.0, 0.0], [0.0, axis_m, 0.0], [0.0, 0.0, axis_m]])
            .with_colors([
                Color::from_rgb(255, 0, 0),
                Color::from_rgb(0, 255, 0),
                Color::from_rgb(0, 0, 255),
            ]),
    )?;
    v.model = Some(f.model);
    Ok(())
}

/// The track: one open segment re-logged per tick; closed segments stay as they were.
fn log_track(
    rec: &RecordingStream,
    rows: &mut Rows,
    v: &mut Vehicle,
    f: &TickFrame,
    position: Vec3,
) -> RecordingStreamResult<()> {
    if v.open_segment.len() > TRACK_SEGMENT {
        let last = v.open_segment[v.open_segment.len() - 1];
        v.open_segment.clear();
        v.open_segment.push(last);
        v.segment += 1;
    }
    v.open_segment.push(position.to_array());
    if v.recent.len() == RECENT_LEN {
        v.recent.pop_front();
    }
    v.recent.push_back((f.t_s, position));
    let color = Color::from_rgb(
        v.color[0] / 2 + 40,
        v.color[1] / 2 + 40,
        v.color[2] / 2 + 40,
    );
    rows.strip(
        rec,
        paths::track_segment(f.system_id, v.segment),
        &v.open_segment,
        color,
    )
}

/// The six rays and their hits. Colours (hit or miss) and widths only when they change.
fn log_rays(
    rec: &RecordingStream,
    rows: &mut Rows,
    v: &mut Vehicle,
    f: &TickFrame,
    offset: DVec3,
    position: Vec3,
) -> RecordingStreamResult<()> {
    let id = f.system_id;
    let mut vectors = Vec::new();
    let mut colors = Vec::new();
    let mut hits = Vec::new();
    for &(dir, hit) in &f.rays {
        let length = hit.unwrap_or(f.ray_length_m);
        vectors.push((dir * length).as_vec3().to_array());
        colors.push(if hit.is_some() {
            Color::from_rgb(255, 60, 60)
        } else {
            Color::from_unmultiplied_rgba(160, 160, 160, 120)
        });
        if let Some(d) = hit {
            hits.push(local(offset, f.pose.position_enu_m + dir * d).to_array());
        }
    }
    let path = paths::vehicle_part(id, "rays");
    let hit_pattern: Vec<bool> = f.rays.iter().map(|r| r.1.is_some()).collect();
    if v.ray_hits.as_deref() != Some(&hit_pattern[..]) {
        rows.log(
            rec,
            path.clone(),
            &Arrows3D::update_fields()
                .with_radii([-1.0])
                .with_colors(colors),
        )?;
        v.ray_hits = Some(hit_pattern);
    }
    let origins = vec![position.to_array(); vectors.len()];
    rows.arrows(rec, path, &vectors, &origins)?;
    if !hits.is_empty() || v.had_hits {
        v.had_hits = !hits.is_empty();
        rows.log(
            rec,
            paths::vehicle_part(id, "rays/hits"),
            &Points3D::new(hits)
                .with_radii([-4.0])
                .with_colors([Color::from_rgb(255, 60, 60)]),
        )?;
    }
    Ok(())
}

/// Each vehicle's closest approach to each moving body, at the moment it happened: where the
/// vehicle was (cyan; orange-red with the NMAC volume, 500 ft wide and 100 ft above and
/// below, when the two came within NMAC), labelled with the separations. Only where the
/// vehicle's kept positions reach back to that moment. Without a collision, the time panel
/// selects the closest of them.
fn log_approaches(
    rec: &RecordingStream,
    state: &mut State<'_>,
    list: &[ApproachFrame],
) -> RecordingStreamResult<()> {
    let mut closest: Option<(f64, f64)> = None;
    for a in list {
        let Some(v) = state.vehicles.get(&a.system_id) else {
            continue;
        };
        let nearest = v
            .recent
            .iter()
            .min_by(|x, y| (x.0 - a.t_s).abs().total_cmp(&(y.0 - a.t_s).abs()));
        let Some(&(t_s, at)) = nearest.filter(|(t, _)| (t - a.t_s).abs() <= 1.0) else {
            continue;
        };
        let vehicle_s = t_s + v.clock_shift_s;
        state.rows.set_time(v.last_tick, vehicle_s, t_s);
        let label = format!(
            "CPA v{} {} {:.0} m ({:.0} m / {:.0} m){} +{:.1} s",
            a.system_id,
            a.track,
            a.distance_m,
            a.horizontal_m,
            a.vertical_m.abs(),
            if a.nmac { " NMAC" } else { "" },
            (a.t_s - state.t0_s).max(0.0)
        );
        let colour = if a.nmac {
            Color::from_rgb(255, 80, 30)
        } else {
            Color::from_rgb(0, 210, 230)
        };
        let path = paths::closest_approach(a.system_id, &a.track);
        state.rows.log(
            rec,
            path.clone(),
            &Points3D::new([at.to_array()])
                .with_radii([-8.0])
                .with_colors([colour])
                .with_labels([label])
                .with_show_labels(true),
        )?;
        if a.nmac {
            use crate::daa::approach::{NMAC_HORIZONTAL_M, NMAC_VERTICAL_M};
            state.rows.log(
                rec,
                format!("{path}/nmac"),
                &rerun::Cylinders3D::from_lengths_and_radii(
                    [2.0 * NMAC_VERTICAL_M as f32],
                    [NMAC_HORIZONTAL_M as f32],
                )
                .with_centers([at.to_array()])
                .with_colors([Color::from_unmultiplied_rgba(255, 80, 30, 160)])
                .with_fill_mode(FillMode::MajorWireframe),
            )?;
        }
        let on_panel = if state.layout.vehicle_time {
            vehicle_s
        } else {
            t_s
        };
        if closest.is_none_or(|(d, _)| a.distance_m < d) {
            closest = Some((a.distance_m, on_panel));
        }
    }
    if let (None, Some((_, t))) = (state.layout.focus_s, closest) {
        state.layout.focus_s = Some((t - FOCUS_BEFORE_S, t + FOCUS_AFTER_S));
    }
    Ok(())
}

/// The current node and the leaves that touch it, logged when the node changes.
fn log_node(
    rec: &RecordingStream,
    v: &mut Vehicle,
    f: &TickFrame,
    leaves: &[Aabb64],
    offset: DVec3,
) -> RecordingStreamResult<()> {
    if f.node == v.node {
        return Ok(());
    }
    v.node = f.node;
    let id = f.system_id;
    let Some(n) = f.node else {
        return rec.log(paths::vehicle_part(id, "node"), &Clear::recursive());
    };
    rec.log(
        paths::vehicle_part(id, "node"),
        &boxes_of(
            offset,
            FillMode::MajorWireframe,
            std::iter::once((LocalBox::aligned(&n), Color::from_rgb(255, 220, 0))),
        ),
    )?;
    let touching = Aabb64 {
        min: n.min - DVec3::splat(0.01),
        max: n.max + DVec3::splat(0.01),
    };
    let neighbours = leaves
        .iter()
        .filter(|b| **b != n && b.intersects(&touching))
        .map(|b| {
            (
                LocalBox::aligned(b),
                Color::from_unmultiplied_rgba(200, 200, 255, 90),
            )
        });
    rec.log(
        paths::vehicle_part(id, "node/neighbours"),
        &boxes_of(offset, FillMode::MajorWireframe, neighbours),
    )
}

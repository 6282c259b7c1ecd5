//! The rerun logger: streams what the collision core does so a flight can be scrubbed in the
//! rerun viewer (entity paths in [`paths`], documented in docs/rerun.md).
//!
//! The core never waits for it: the session sends [`VizMsg`]s over a bounded channel to a
//! dedicated thread that owns the `RecordingStream` (rerun's time cursor is per thread); a full
//! channel drops the message and counts it. Positions are logged in the scene's ENU metres
//! minus a fixed offset (the scene's centre, rounded, when that is far from the origin), so f32
//! stays precise; the 3D view is declared Z up.

pub mod paths;

use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;

use glam::{DQuat, DVec3, Vec3};
use rerun::blueprint::{
    components::PlayState, Blueprint, BlueprintActivation, ContainerLike, Horizontal,
    Spatial3DView, TimePanel, TimeSeriesView, Vertical,
};
use rerun::{
    Arrows3D, Boxes3D, Clear, Color, LineStrips3D, Mesh3D, Points3D, RecordingStream,
    RecordingStreamBuilder, Scalars, Transform3D, ViewCoordinates,
};

use crate::collision::events::{Event, EventKind};
use crate::collision::pipeline::{BodyKey, BodyPose, ObstacleRef, TickReport, RAY_AXES_FRD};
use crate::collision::ColliderKind;
use crate::error::{Error, Result};
use crate::scene::{Aabb64, Kind, Scene};

/// Where the recording goes (`--rerun`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RerunTarget {
    /// `save=PATH`: an .rrd file.
    Save(PathBuf),
    /// `connect` or `connect=URL`: a running viewer (default rerun+http://127.0.0.1:9876/proxy).
    Connect(Option<String>),
    /// `spawn`: start a viewer (the `rerun` binary on PATH) and stream to it.
    Spawn,
}

impl FromStr for RerunTarget {
    type Err = Error;

    /// ```
    /// use savsim::viz::RerunTarget;
    /// assert_eq!("save=out.rrd".parse::<RerunTarget>().unwrap(), RerunTarget::Save("out.rrd".into()));
    /// assert_eq!("connect".parse::<RerunTarget>().unwrap(), RerunTarget::Connect(None));
    /// assert!("print".parse::<RerunTarget>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        match s.split_once('=') {
            Some(("save", path)) if !path.is_empty() => Ok(RerunTarget::Save(path.into())),
            Some(("connect", url)) if !url.is_empty() => Ok(RerunTarget::Connect(Some(url.into()))),
            None if s == "connect" => Ok(RerunTarget::Connect(None)),
            None if s == "spawn" => Ok(RerunTarget::Spawn),
            _ => Err(Error::Usage(format!(
                "--rerun {s:?}: use save=OUT.rrd, connect, connect=URL or spawn"
            ))),
        }
    }
}

/// Open the recording stream a target names.
pub fn open(target: &RerunTarget) -> Result<RecordingStream> {
    let builder = RecordingStreamBuilder::new("savsim");
    match target {
        RerunTarget::Save(path) => builder.save(path),
        RerunTarget::Connect(None) => builder.connect_grpc(),
        RerunTarget::Connect(Some(url)) => builder.connect_grpc_opts(url.clone()),
        RerunTarget::Spawn => builder.spawn(),
    }
    .map_err(|e| Error::Usage(format!("--rerun: {e}")))
}

/// One vehicle's tick, as the logger needs it.
#[derive(Debug, Clone)]
pub struct TickFrame {
    /// Tick number over the run (all vehicles).
    pub tick: u64,
    /// Receive/tlog time, UNIX seconds.
    pub t_s: f64,
    /// Vehicle clock, ms.
    pub time_boot_ms: u32,
    /// Vehicle system id.
    pub system_id: u8,
    /// Pose now.
    pub pose: BodyPose,
    /// Geometry index of the vehicle's model.
    pub model: usize,
    /// Each ray's hit distance (None: no hit within the ray length), FRD order.
    pub rays_m: [Option<f64>; 6],
    /// Ray length, metres.
    pub ray_length_m: f64,
    /// The vehicle's octree leaf.
    pub node: Option<Aabb64>,
    /// Obstacles with a collider: which, and beta.
    pub colliders: Vec<(ObstacleRef, ColliderKind, f64)>,
    /// Moving obstacles this tick: key, id, kind, model, pose.
    pub dynamic: Vec<(BodyKey, String, Kind, usize, BodyPose)>,
    /// Collisions and near misses reported at this tick.
    pub events: Vec<Event>,
    /// The pipeline's counts for the tick.
    pub report: TickReport,
    /// What the tick cost, microseconds.
    pub cost_us: f64,
}

/// What goes to the logger thread.
#[derive(Debug)]
pub enum VizMsg {
    /// A vehicle's tick.
    Tick(Box<TickFrame>),
}

/// The running logger.
pub struct Logger {
    tx: Option<SyncSender<VizMsg>>,
    dropped: Arc<AtomicU64>,
    sent: u64,
    thread: Option<JoinHandle<Result<(), String>>>,
}

/// Messages the channel holds before dropping.
const QUEUE_LEN: usize = 4096;
/// Static scenes with at most this many triangles are drawn as meshes, larger ones as boxes.
const STATIC_MESH_BUDGET: usize = 500_000;
/// Track points kept per vehicle.
const TRACK_LEN: usize = 2000;

impl Logger {
    /// Start the logger thread on a stream (see [`open`]; tests pass a memory stream); the
    /// scene is logged first.
    pub fn with_stream(
        rec: RecordingStream,
        scene: Arc<Scene>,
        octree_leaves: Vec<Aabb64>,
    ) -> Result<Self> {
        let (tx, rx) = sync_channel(QUEUE_LEN);
        let dropped = Arc::new(AtomicU64::new(0));
        let thread = std::thread::Builder::new()
            .name("savsim-rerun".into())
            .spawn(move || run(rec, rx, &scene, &octree_leaves))
            .map_err(|e| Error::Usage(format!("--rerun: cannot start the logger thread: {e}")))?;
        Ok(Self {
            tx: Some(tx),
            dropped,
            sent: 0,
            thread: Some(thread),
        })
    }

    /// Queue a message; never blocks. A full queue drops it (counted).
    pub fn send(&mut self, msg: VizMsg) {
        let Some(tx) = &self.tx else { return };
        match tx.try_send(msg) {
            Ok(()) => self.sent += 1,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Messages dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Messages queued so far.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Stop: the thread logs what is queued, flushes, and ends.
    pub fn finish(&mut self) -> Result<()> {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(()))) | None => Ok(()),
            Some(Ok(Err(e))) => Err(Error::Usage(format!("rerun logger: {e}"))),
            Some(Err(_)) => Err(Error::Usage("rerun logger: the thread panicked".into())),
        }
    }
}

impl Drop for Logger {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

/// Colour of a kind of obstacle.
pub fn kind_color(kind: Kind) -> Color {
    match kind {
        Kind::Building => Color::from_rgb(150, 150, 160),
        Kind::Mountain => Color::from_rgb(120, 100, 70),
        Kind::Tree => Color::from_rgb(40, 140, 60),
        Kind::A320 | Kind::B737 => Color::from_rgb(230, 230, 240),
        Kind::Dji => Color::from_rgb(60, 60, 60),
        Kind::Airship | Kind::Balloon => Color::from_rgb(230, 120, 40),
    }
}

/// Colour of a collider by its beta: blue (0) through yellow (50, the mesh threshold) to red
/// (100 and more).
pub fn beta_color(beta: f64) -> Color {
    let u = (beta / 100.0).clamp(0.0, 1.0) as f32;
    let (r, g, b) = if u < 0.5 {
        let v = u * 2.0;
        (v, v, 1.0 - v)
    } else {
        let v = (u - 0.5) * 2.0;
        (1.0, 1.0 - v, 0.0)
    };
    Color::from_rgb((r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8)
}

/// The offset subtracted from scene ENU positions before they become f32: zero near the
/// origin, else the scene's centre rounded to a kilometre.
pub fn viz_offset(scene: &Scene) -> DVec3 {
    let centre = if scene.obstacles.is_empty() {
        DVec3::ZERO
    } else {
        scene.bounds_enu_m().centre()
    };
    if centre.length() < 10_000.0 {
        DVec3::ZERO
    } else {
        (centre / 1000.0).round() * 1000.0
    }
}

struct State<'s> {
    scene: &'s Scene,
    offset: DVec3,
    colliders: BTreeMap<u8, BTreeMap<ObstacleRef, (ColliderKind, String)>>,
    tracks: BTreeMap<u8, VecDeque<Vec3>>,
    models_logged: BTreeMap<u8, usize>,
    collisions: Vec<Vec3>,
    near_misses: Vec<Vec3>,
    traffic: BTreeMap<String, bool>,
}

impl State<'_> {
    fn local(&self, p: DVec3) -> Vec3 {
        (p - self.offset).as_vec3()
    }
}

fn run(
    rec: RecordingStream,
    rx: Receiver<VizMsg>,
    scene: &Scene,
    leaves: &[Aabb64],
) -> Result<(), String> {
    let mut state = State {
        scene,
        offset: viz_offset(scene),
        colliders: BTreeMap::new(),
        tracks: BTreeMap::new(),
        models_logged: BTreeMap::new(),
        collisions: Vec::new(),
        near_misses: Vec::new(),
        traffic: BTreeMap::new(),
    };
    log_scene(&rec, &state, leaves).map_err(|e| e.to_string())?;
    for msg in rx {
        match msg {
            VizMsg::Tick(frame) => log_tick(&rec, &mut state, &frame).map_err(|e| e.to_string())?,
        }
    }
    rec.flush_blocking().map_err(|e| e.to_string())
}

fn boxes_of(state: &State<'_>, items: impl Iterator<Item = (Aabb64Local, Color)>) -> Boxes3D {
    let mut centres = Vec::new();
    let mut halves = Vec::new();
    let mut rotations = Vec::new();
    let mut colors = Vec::new();
    for (b, c) in items {
        centres.push(state.local(b.centre_enu_m).to_array());
        halves.push(b.half_m.to_array());
        let q = b.rotation.as_quat();
        rotations.push(rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]));
        colors.push(c);
    }
    Boxes3D::from_centers_and_half_sizes(centres, halves)
        .with_quaternions(rotations)
        .with_colors(colors)
}

/// A box in the scene: centre, half sizes, rotation.
struct Aabb64Local {
    centre_enu_m: DVec3,
    half_m: Vec3,
    rotation: DQuat,
}

fn box_of_geometry(geometry: &crate::scene::geometry::Geometry, pose: &BodyPose) -> Aabb64Local {
    let (cuboid, centre) = geometry.box_collider();
    Aabb64Local {
        centre_enu_m: pose.position_enu_m + pose.enu_from_body * centre.as_dvec3(),
        half_m: cuboid.half_extents,
        rotation: pose.enu_from_body,
    }
}

fn mesh_of_geometry(
    state: &State<'_>,
    geometry: &crate::scene::geometry::Geometry,
    pose: &BodyPose,
    color: Color,
) -> Mesh3D {
    let (vertices, indices) = geometry.triangles();
    let positions: Vec<[f32; 3]> = vertices
        .iter()
        .map(|v| {
            state
                .local(pose.position_enu_m + pose.enu_from_body * v.as_dvec3())
                .to_array()
        })
        .collect();
    Mesh3D::new(positions)
        .with_triangle_indices(
            indices
                .into_iter()
                .map(|t| rerun::TriangleIndices(t.into())),
        )
        .with_albedo_factor(color.0)
}

fn pose_of_static(scene: &Scene, i: u32) -> BodyPose {
    let o = &scene.obstacles[i as usize];
    BodyPose {
        position_enu_m: o.placement.position_enu_m,
        enu_from_body: o.placement.enu_from_local,
    }
}

/// The default layout: the 3D world large, the metrics beside it.
fn blueprint() -> Blueprint {
    let series = |name: &str, origin: &str| -> ContainerLike {
        TimeSeriesView::new(name)
            .with_origin(origin)
            .with_contents([format!("{origin}/**")])
            .into()
    };
    Blueprint::new(
        Horizontal::new([
            Spatial3DView::new("world").with_origin("/world").into(),
            Vertical::new([
                series("tick cost (µs)", "/metrics/cost_us"),
                series("active colliders", "/metrics/colliders"),
                series("active triangles", "/metrics/triangles"),
                series("beta", "/metrics/beta"),
            ])
            .into(),
        ])
        .with_column_shares([3.0, 1.0]),
    )
    .with_time_panel(
        TimePanel::new()
            .with_timeline("tlog_time")
            .with_play_state(PlayState::Following),
    )
}

fn log_scene(
    rec: &RecordingStream,
    state: &State<'_>,
    leaves: &[Aabb64],
) -> rerun::RecordingStreamResult<()> {
    blueprint().send(rec, BlueprintActivation::default())?;
    rec.log_static(paths::WORLD, &ViewCoordinates::RIGHT_HAND_Z_UP())?;
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
                    state
                        .local(pose.position_enu_m + pose.enu_from_body * v.as_dvec3())
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
                    .with_albedo_factor(kind_color(kind).0),
            )?;
        } else {
            let items = of_kind().map(|(i, o)| {
                (
                    box_of_geometry(&o.geometry, &pose_of_static(scene, i as u32)),
                    kind_color(kind),
                )
            });
            rec.log_static(path, &boxes_of(state, items))?;
        }
    }
    let leaf_boxes = leaves.iter().map(|b| {
        (
            Aabb64Local {
                centre_enu_m: b.centre(),
                half_m: ((b.max - b.min) * 0.5).as_vec3(),
                rotation: DQuat::IDENTITY,
            },
            Color::from_unmultiplied_rgba(200, 200, 255, 60),
        )
    });
    rec.log_static(paths::OCTREE, &boxes_of(state, leaf_boxes))?;
    Ok(())
}

fn obstacle_id(scene: &Scene, frame: &TickFrame, o: ObstacleRef) -> Option<String> {
    match o {
        ObstacleRef::Static(i) => scene.obstacles.get(i as usize).map(|s| s.id.clone()),
        ObstacleRef::Dynamic(key) => frame
            .dynamic
            .iter()
            .find(|d| d.0 == key)
            .map(|d| d.1.clone()),
    }
}

/// Every marker so far at `path`, as points.
fn log_markers(
    rec: &RecordingStream,
    path: &str,
    points: &[Vec3],
    radius: f32,
    color: Color,
) -> rerun::RecordingStreamResult<()> {
    rec.log(
        path,
        &Points3D::new(points.iter().map(|p| p.to_array()))
            .with_radii([radius])
            .with_colors([color]),
    )
}

fn log_tick(
    rec: &RecordingStream,
    state: &mut State<'_>,
    f: &TickFrame,
) -> rerun::RecordingStreamResult<()> {
    let scene = state.scene;
    rec.set_time_sequence("tick", f.tick as i64);
    rec.set_duration_secs("vehicle_time", f64::from(f.time_boot_ms) / 1000.0);
    rec.set_timestamp_secs_since_epoch("tlog_time", f.t_s);
    let id = f.system_id;

    // Body, its model (once), axes.
    let position = state.local(f.pose.position_enu_m);
    let q = f.pose.enu_from_body.as_quat();
    rec.log(
        paths::body(id),
        &Transform3D::from_translation_rotation(
            position.to_array(),
            rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]),
        ),
    )?;
    if state.models_logged.get(&id) != Some(&f.model) {
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
                .with_albedo_factor(Color::from_rgb(255, 80, 200).0),
        )?;
        rec.log_static(
            format!("{}/axes", paths::body(id)),
            &Arrows3D::from_vectors([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]])
                .with_colors([
                    Color::from_rgb(255, 0, 0),
                    Color::from_rgb(0, 255, 0),
                    Color::from_rgb(0, 0, 255),
                ]),
        )?;
        state.models_logged.insert(id, f.model);
    }

    // Track.
    let track = state.tracks.entry(id).or_default();
    if track.len() == TRACK_LEN {
        track.pop_front();
    }
    track.push_back(position);
    rec.log(
        paths::vehicle_part(id, "track"),
        &LineStrips3D::new([track.iter().map(|p| p.to_array()).collect::<Vec<_>>()])
            .with_colors([Color::from_rgb(255, 80, 200)]),
    )?;

    // Rays and their hits.
    let mut vectors = Vec::new();
    let mut colors = Vec::new();
    let mut hits = Vec::new();
    for (axis, hit) in RAY_AXES_FRD.iter().zip(f.rays_m) {
        let dir = f.pose.enu_from_body * axis.as_dvec3();
        let length = hit.unwrap_or(f.ray_length_m);
        vectors.push((dir * length).as_vec3().to_array());
        colors.push(if hit.is_some() {
            Color::from_rgb(255, 60, 60)
        } else {
            Color::from_unmultiplied_rgba(160, 160, 160, 120)
        });
        if let Some(d) = hit {
            hits.push(state.local(f.pose.position_enu_m + dir * d).to_array());
        }
    }
    rec.log(
        paths::vehicle_part(id, "rays"),
        &Arrows3D::from_vectors(vectors)
            .with_origins(vec![position.to_array(); 6])
            .with_colors(colors),
    )?;
    rec.log(
        paths::vehicle_part(id, "rays/hits"),
        &Points3D::new(hits).with_radii([0.8]),
    )?;

    // The current node.
    match f.node {
        Some(n) => rec.log(
            paths::vehicle_part(id, "node"),
            &boxes_of(
                state,
                std::iter::once((
                    Aabb64Local {
                        centre_enu_m: n.centre(),
                        half_m: ((n.max - n.min) * 0.5).as_vec3(),
                        rotation: DQuat::IDENTITY,
                    },
                    Color::from_rgb(255, 220, 0),
                )),
            ),
        )?,
        None => rec.log(paths::vehicle_part(id, "node"), &Clear::flat())?,
    }

    // Colliders: log what changed; a collider swapped out is cleared.
    let previous = state.colliders.remove(&id).unwrap_or_default();
    let mut now: BTreeMap<ObstacleRef, (ColliderKind, String)> = BTreeMap::new();
    for &(o, kind, beta) in &f.colliders {
        let Some(name) = obstacle_id(scene, f, o) else {
            continue;
        };
        let moving = matches!(o, ObstacleRef::Dynamic(_));
        let changed = previous.get(&o).is_none_or(|(k, _)| *k != kind);
        if changed || moving {
            let (geometry, pose) = match o {
                ObstacleRef::Static(i) => (
                    &*scene.obstacles[i as usize].geometry,
                    pose_of_static(scene, i),
                ),
                ObstacleRef::Dynamic(key) => {
                    let Some(d) = f.dynamic.iter().find(|d| d.0 == key) else {
                        continue;
                    };
                    (&*scene.geometries[d.3], d.4)
                }
            };
            let path = paths::collider(id, &name);
            match kind {
                ColliderKind::Box => rec.log(
                    path,
                    &boxes_of(
                        state,
                        std::iter::once((box_of_geometry(geometry, &pose), beta_color(beta))),
                    ),
                )?,
                ColliderKind::Mesh => rec.log(
                    path,
                    &mesh_of_geometry(state, geometry, &pose, beta_color(beta)),
                )?,
                ColliderKind::None => rec.log(path, &Clear::flat())?,
            }
        }
        if beta > 0.0 {
            rec.log(paths::beta(id, &name), &Scalars::single(beta))?;
        }
        now.insert(o, (kind, name));
    }
    for (o, (_, name)) in &previous {
        if !now.contains_key(o) {
            rec.log(paths::collider(id, name), &Clear::flat())?;
        }
    }
    state.colliders.insert(id, now);

    // Traffic.
    let mut seen = BTreeMap::new();
    for (_, name, kind, model, pose) in &f.dynamic {
        let b = box_of_geometry(&scene.geometries[*model], pose);
        rec.log(
            paths::traffic(name),
            &boxes_of(state, std::iter::once((b, kind_color(*kind)))),
        )?;
        seen.insert(name.clone(), true);
    }
    for name in state.traffic.keys() {
        if !seen.contains_key(name) {
            rec.log(paths::traffic(name), &Clear::flat())?;
        }
    }
    state.traffic = seen;

    // Collision and near-miss markers.
    for e in &f.events {
        match &e.kind {
            EventKind::Collision { point_enu_m, .. } => {
                let p = state.local(DVec3::from(*point_enu_m));
                state.collisions.push(p);
                log_markers(
                    rec,
                    paths::COLLISIONS,
                    &state.collisions,
                    2.0,
                    Color::from_rgb(255, 0, 0),
                )?;
            }
            EventKind::NearMiss { .. } => {
                state.near_misses.push(position);
                log_markers(
                    rec,
                    paths::NEAR_MISSES,
                    &state.near_misses,
                    1.5,
                    Color::from_rgb(255, 160, 0),
                )?;
            }
            _ => {}
        }
    }

    // Scalars.
    rec.log(paths::cost(id), &Scalars::single(f.cost_us))?;
    rec.log(
        paths::colliders_count(id, "box"),
        &Scalars::single(f.report.active_box as f64),
    )?;
    rec.log(
        paths::colliders_count(id, "mesh"),
        &Scalars::single(f.report.active_mesh as f64),
    )?;
    rec.log(
        paths::triangles(id),
        &Scalars::single(f.report.active_triangles as f64),
    )?;
    Ok(())
}

//! The recording's default layout (a rerun blueprint): one chase view per vehicle (up to
//! [`MAX_CHASE_VIEWS`]) whose eye rides with the vehicle, a top-down overview of the flown area
//! (of the scene when nothing flew), and the time series below when something flew. Written
//! with rerun's blueprint archetypes directly, because the SDK's layout builder cannot set a
//! view's eye (`EyeControls3D`).

use glam::Vec3;
use rerun::blueprint::components::{
    AbsoluteTimeRange, ContainerKind, IncludedContent, PanelState, PlayState, QueryExpression,
    RootContainer, ViewClass,
};
use rerun::datatypes::{TimeInt, Uuid};
use rerun::external::re_log_types::{BlueprintActivationCommand, RecordingId};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, EyeControls3D, PanelBlueprint, TimePanelBlueprint, ViewBlueprint,
    ViewContents, ViewportBlueprint,
};
use rerun::log::LogMsg;
use rerun::{RecordingStream, RecordingStreamBuilder, RecordingStreamResult};

use super::paths;

/// Vehicles that get a chase view of their own; later ones are in the overview only.
pub const MAX_CHASE_VIEWS: usize = 4;

/// What the layout shows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Layout {
    /// Every vehicle seen (system ids, in order of appearance).
    pub vehicles: Vec<u8>,
    /// Vehicles with a chase view (system ids, in order of appearance), and each one's chase
    /// distance, metres (from its model's size).
    pub chased: Vec<(u8, f32)>,
    /// The area the overview frames, logged (viz-offset) metres: min and max corners. `None`
    /// before the first position.
    pub overview: Option<(Vec3, Vec3)>,
    /// A span of the time panel's timeline (seconds) to select: the first collision.
    pub focus_s: Option<(f64, f64)>,
    /// The time panel shows `vehicle_time` (the vehicle's clock), else `tlog_time`.
    pub vehicle_time: bool,
    /// The overview frames the scene alone (nothing flew): closely, not with a flight's margin.
    pub scene_only: bool,
    /// The depth cameras of the chased vehicles: each image's entity (its pinhole), which gets
    /// a 2D view beside the chase views.
    pub images: Vec<String>,
}

/// Send `layout` as the recording's active and default blueprint.
pub fn send(rec: &RecordingStream, layout: &Layout) -> RecordingStreamResult<()> {
    let app = rec
        .store_info()
        .map_or_else(|| "savsim".into(), |i| i.application_id().clone());
    let (bp, storage) = RecordingStreamBuilder::new(app)
        .recording_id(RecordingId::random())
        .blueprint()
        .memory()?;
    bp.set_time_sequence("blueprint", 0);
    let mut w = Writer { rec: &bp };
    w.layout(layout)?;
    let msgs = storage.take();
    let Some(blueprint_id) = msgs.iter().find_map(|m| match m {
        LogMsg::SetStoreInfo(info) => Some(info.info.store_id.clone()),
        _ => None,
    }) else {
        return Ok(());
    };
    rec.send_blueprint(
        msgs,
        BlueprintActivationCommand {
            blueprint_id,
            make_active: true,
            make_default: true,
        },
    );
    Ok(())
}

/// The chase eye in the chase frame (x forward along the heading, y left, z up): behind,
/// above and a little to the right of the vehicle (not on the plane it flies in, where
/// axis-aligned edges such as the octree's would pass through the eye), looking at it.
pub fn chase_eye(distance_m: f32) -> EyeControls3D {
    EyeControls3D::new()
        .with_position([-0.8 * distance_m, -0.25 * distance_m, 0.5 * distance_m])
        .with_look_target([0.0, 0.0, 0.0])
        .with_eye_up([0.0, 0.0, 1.0])
}

/// The overview eye: straight down on the centre of `area` (north up), high enough that the
/// whole area fits a 55-degree field of view with a `margin` (2 around a flight: it also keeps
/// tall buildings from looming; 1.1 around a scene alone).
pub fn overview_eye(area: (Vec3, Vec3), margin: f32) -> EyeControls3D {
    let (min, max) = area;
    let centre = (min + max) * 0.5;
    let height = eye_height_m(area, margin);
    let eye = centre + Vec3::new(0.0, -0.02 * height, max.z - centre.z + height);
    EyeControls3D::new()
        .with_position(eye.to_array())
        .with_look_target(centre.to_array())
        .with_eye_up([0.0, 1.0, 0.0])
}

/// How high above the area's top the overview eye is, metres.
fn eye_height_m((min, max): (Vec3, Vec3), margin: f32) -> f32 {
    let half = ((max - min) * 0.5).max(Vec3::splat(50.0));
    // tan(27.5 deg) = 0.52; the width counts as the view is wider than it is tall only up to
    // about 1.5.
    (half.x.max(half.y * 1.5) / 0.52 * margin / 1.5).max(300.0)
}

struct Writer<'a> {
    rec: &'a RecordingStream,
}

impl Writer<'_> {
    /// A container's or view's id, from its role ("overview", "chase 3", ...). The viewer keeps
    /// per-view state by id across blueprints, so a role keeps its id, and a view its class,
    /// every time the layout is sent again.
    fn id(role: &str) -> Uuid {
        let fnv = |seed: u64| {
            role.bytes().fold(seed, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
            })
        };
        let v =
            (u128::from(fnv(0xcbf2_9ce4_8422_2325)) << 64) | u128::from(fnv(0x5a75_5a75_5a75_5a75));
        // Shaped as a version-4 uuid.
        let v = (v & !(0xf000_u128 << 64) & !(0xc000_u128 << 48))
            | (0x4000_u128 << 64)
            | (0x8000_u128 << 48);
        Uuid {
            bytes: v.to_be_bytes(),
        }
    }

    fn view(
        &mut self,
        class: &str,
        name: &str,
        origin: &str,
        contents: &[String],
        eye: Option<EyeControls3D>,
    ) -> RecordingStreamResult<String> {
        let path = format!("view/{}", uuid_text(Self::id(name)));
        self.rec.log(
            format!("{path}/ViewContents"),
            &ViewContents::new(contents.iter().map(|q| QueryExpression(q.as_str().into()))),
        )?;
        self.rec.log(
            path.as_str(),
            &ViewBlueprint::new(ViewClass(class.into()))
                .with_display_name(name)
                .with_space_origin(origin),
        )?;
        if let Some(eye) = eye {
            self.rec.log(format!("{path}/EyeControls3D"), &eye)?;
        }
        Ok(path)
    }

    fn container(
        &mut self,
        role: &str,
        kind: ContainerKind,
        children: Vec<String>,
        shares: &[f32],
    ) -> RecordingStreamResult<(String, Uuid)> {
        let id = Self::id(role);
        let path = format!("container/{}", uuid_text(id));
        let mut arch = ContainerBlueprint::new(kind).with_contents(
            children
                .into_iter()
                .map(|c| IncludedContent(c.as_str().into())),
        );
        arch = match kind {
            ContainerKind::Horizontal => arch.with_col_shares(shares.iter().copied()),
            ContainerKind::Vertical => arch.with_row_shares(shares.iter().copied()),
            _ => arch,
        };
        if kind == ContainerKind::Grid {
            arch = arch.with_grid_columns(if shares.len() > 1 { 2_u32 } else { 1 });
        }
        self.rec.log(path.as_str(), &arch)?;
        Ok((path, id))
    }

    fn series(&mut self, name: &str, origin: &str) -> RecordingStreamResult<String> {
        self.view("TimeSeries", name, origin, &[format!("{origin}/**")], None)
    }

    /// The row below: tick cost, active colliders, beta, and what the vehicles said.
    fn series_row(&mut self) -> RecordingStreamResult<String> {
        let series = vec![
            self.series("tick cost (µs)", &format!("/{}/cost_us", paths::METRICS))?,
            self.series(
                "active colliders",
                &format!("/{}/colliders", paths::METRICS),
            )?,
            self.series("beta", &format!("/{}/beta", paths::METRICS))?,
            self.view(
                "TextLog",
                "what the vehicles said",
                &format!("/{}", paths::MESSAGES),
                &[format!("/{}/**", paths::MESSAGES)],
                None,
            )?,
        ];
        let (row, _) = self.container(
            "series",
            ContainerKind::Horizontal,
            series,
            &[1.0, 1.0, 1.0, 1.5],
        )?;
        Ok(row)
    }

    fn layout(&mut self, layout: &Layout) -> RecordingStreamResult<()> {
        let mut chases = Vec::new();
        for &(id, distance_m) in layout.chased.iter().take(MAX_CHASE_VIEWS) {
            chases.push(self.view(
                "3D",
                &format!("vehicle {id} (chase)"),
                &paths::chase(id),
                // What the vehicle senses: everything but the static scene, which its colliders
                // stand for near it (so nothing hides the vehicle when it is inside a building).
                &[
                    format!("/{}/**", paths::WORLD),
                    format!("- /{}/**", paths::OBSTACLES),
                ],
                Some(chase_eye(distance_m)),
            )?);
        }
        // The overview: the scene, tracks, vehicles and markers; not what each vehicle senses.
        let mut contents = vec![format!("/{}/**", paths::WORLD)];
        for &id in &layout.vehicles {
            for part in ["colliders", "rays", "node"] {
                contents.push(format!("- /{}/**", paths::vehicle_part(id, part)));
            }
        }
        let overview = self.view(
            "3D",
            "overview",
            &format!("/{}", paths::WORLD),
            &contents,
            layout
                .overview
                .map(|a| overview_eye(a, if layout.scene_only { 1.1 } else { 2.0 })),
        )?;
        let mut top = Vec::new();
        match chases.len() {
            0 => {}
            1 => top.push(chases.remove(0)),
            n => {
                let shares = vec![1.0; n];
                top.push(
                    self.container("chases", ContainerKind::Grid, chases, &shares)?
                        .0,
                );
            }
        }
        if !layout.images.is_empty() {
            let mut views = Vec::new();
            for image in &layout.images {
                let name = image
                    .trim_end_matches("/image")
                    .trim_start_matches("world/vehicles/")
                    .replace("/sensors/", " ");
                views.push(self.view(
                    "2D",
                    &format!("vehicle {name}"),
                    &format!("/{image}"),
                    &[format!("/{image}/**")],
                    None,
                )?);
            }
            let shares = vec![1.0; views.len()];
            top.push(
                self.container("images", ContainerKind::Vertical, views, &shares)?
                    .0,
            );
        }
        top.push(overview);
        let top_shares = vec![1.0; top.len()];
        let (top, _) = self.container("top", ContainerKind::Horizontal, top, &top_shares)?;
        // The time series only when something flies (a scene alone has none to draw).
        let (rows, shares) = if layout.vehicles.is_empty() {
            (vec![top], vec![1.0])
        } else {
            (vec![top, self.series_row()?], vec![3.0, 1.0])
        };
        let (_, root) = self.container("root", ContainerKind::Vertical, rows, &shares)?;
        self.rec.log(
            "viewport",
            &ViewportBlueprint::new()
                .with_root_container(RootContainer(root))
                .with_auto_layout(false)
                .with_auto_views(false),
        )?;
        for panel in ["blueprint_panel", "selection_panel"] {
            self.rec.log(
                panel,
                &PanelBlueprint::new().with_state(PanelState::Collapsed),
            )?;
        }
        let timeline = if layout.vehicle_time {
            "vehicle_time"
        } else {
            "tlog_time"
        };
        let mut time = TimePanelBlueprint::new()
            .with_state(PanelState::Collapsed)
            .with_timeline(timeline);
        // The blueprint cannot place the time cursor: the viewer follows the end of the data
        // (where the overview still shows every collision marker), and the first collision's
        // span is selected on the time panel, to be played with the loop button.
        if let Some((from_s, to_s)) = layout.focus_s {
            time =
                time.with_time_selection(AbsoluteTimeRange(rerun::datatypes::AbsoluteTimeRange {
                    min: TimeInt((from_s * 1e9) as i64),
                    max: TimeInt((to_s * 1e9) as i64),
                }));
        }
        time = time.with_play_state(PlayState::Following);
        self.rec.log("time_panel", &time)
    }
}

/// A uuid as rerun spells it in blueprint paths: 8-4-4-4-12 lowercase hex.
fn uuid_text(id: Uuid) -> String {
    let hex: String = id.bytes.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "{}-{}-{}-{}-{}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uuids_are_spelled_as_rerun_parses_them() {
        let text = uuid_text(Uuid {
            bytes: 0x5a75_0000_0000_4000_8000_0000_0000_0001_u128.to_be_bytes(),
        });
        assert_eq!(text, "5a750000-0000-4000-8000-000000000001");
    }

    #[test]
    fn a_scene_alone_is_framed_closer_than_a_flight() {
        let area = (
            Vec3::new(-1000.0, -1000.0, 0.0),
            Vec3::new(1000.0, 1000.0, 50.0),
        );
        // 1000 * 1.5 / 0.52 * margin / 1.5.
        assert!((eye_height_m(area, 1.1) - 2115.4).abs() < 0.1);
        assert!((eye_height_m(area, 2.0) - 3846.2).abs() < 0.1);
    }

    #[test]
    fn the_time_panel_shows_the_runs_clock() {
        let sent = |vehicle_time: bool| {
            let (rec, storage) = rerun::RecordingStreamBuilder::new("t").memory().unwrap();
            let layout = Layout {
                vehicle_time,
                ..Layout::default()
            };
            send(&rec, &layout).unwrap();
            rec.flush_blocking().unwrap();
            format!("{:?}", storage.take())
        };
        let (vehicle, tlog) = (sent(true), sent(false));
        assert!(vehicle.contains("vehicle_time") && !vehicle.contains("tlog_time"));
        assert!(tlog.contains("tlog_time") && !tlog.contains("vehicle_time"));
    }

    #[test]
    fn a_role_keeps_its_id_and_roles_differ() {
        assert_eq!(Writer::id("overview"), Writer::id("overview"));
        assert_ne!(Writer::id("overview"), Writer::id("vehicle 1 (chase)"));
        let text = uuid_text(Writer::id("overview"));
        assert_eq!(&text[14..15], "4", "{text}");
        assert!("89ab".contains(&text[19..20]), "{text}");
    }
}

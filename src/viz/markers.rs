//! Collision, near-miss and loss-of-well-clear markers: every one so far, labelled, a fixed
//! size on screen so that they read in the chase views and the overview alike; and the
//! well-clear volume around the vehicle where each loss happened.

use std::collections::VecDeque;

use glam::{DVec3, Vec3};
use rerun::components::FillMode;
use rerun::{Arrows3D, Color, Cylinders3D, Points3D, RecordingStream, RecordingStreamResult};

use super::draw::local;
use super::paths;
use crate::collision::events::{Event, EventKind};
use crate::observe::TickFrame;

/// The time selection around the first collision: seconds before and after.
pub(super) const FOCUS_BEFORE_S: f64 = 4.0;
pub(super) const FOCUS_AFTER_S: f64 = 2.0;

struct Marker {
    at: Vec3,
    label: String,
    normal: Vec3,
}

/// Where an event's marker goes: the logged frame's offset, the normal's length, the
/// vehicle's recent logged positions (time, position) and its position now.
pub struct Where<'a> {
    /// Scene ENU minus logged coordinates.
    pub offset: DVec3,
    /// Length of a collision's normal arrow, metres.
    pub normal_m: f32,
    /// The vehicle's recent logged positions.
    pub recent: &'a VecDeque<(f64, Vec3)>,
    /// Its logged position now.
    pub now: Vec3,
}

/// Every marker so far.
#[derive(Default)]
pub struct Markers {
    collisions: Vec<Marker>,
    near_misses: Vec<Marker>,
    well_clear: Vec<Marker>,
    /// The well-clear volume at each loss: its centre, radius and height, metres.
    volumes: Vec<(Vec3, f32, f32)>,
}

impl Markers {
    /// Mark an event of vehicle `f.system_id`: a collision at its contact point with its normal
    /// (`at.normal_m` long), a near miss or a loss of well clear where the vehicle was then
    /// (found in `at.recent`: (time, logged position); `at.now` if that is no longer kept).
    /// Returns the span of `tlog_time` to select for a collision.
    pub fn on_event(
        &mut self,
        rec: &RecordingStream,
        e: &Event,
        f: &TickFrame,
        at: Where<'_>,
    ) -> RecordingStreamResult<Option<(f64, f64)>> {
        let id = f.system_id;
        match &e.kind {
            EventKind::Collision {
                obstacle,
                point_enu_m,
                normal_enu,
                time_of_impact,
                ..
            } => {
                self.collisions.push(Marker {
                    at: local(at.offset, DVec3::from(*point_enu_m)),
                    label: format!(
                        "COLLISION v{id} {obstacle} +{:.2} s",
                        (time_of_impact - f.t0_s).max(0.0)
                    ),
                    normal: DVec3::from(*normal_enu).as_vec3(),
                });
                self.log_collisions(rec, at.normal_m)?;
                Ok(Some((
                    time_of_impact - FOCUS_BEFORE_S,
                    time_of_impact + FOCUS_AFTER_S,
                )))
            }
            EventKind::NearMiss {
                obstacle,
                closest_m,
                closest_t,
            } => {
                self.near_misses.push(Marker {
                    at: at.position_at(*closest_t),
                    label: format!("near miss v{id} {obstacle} {closest_m:.1} m"),
                    normal: Vec3::ZERO,
                });
                log_points(
                    rec,
                    paths::NEAR_MISSES,
                    &self.near_misses,
                    6.0,
                    [255, 160, 0],
                    false,
                )?;
                Ok(None)
            }
            EventKind::WellClearLost {
                track,
                lost_t,
                horizontal_m,
                vertical_m,
            } => {
                self.well_clear.push(Marker {
                    at: at.position_at(*lost_t),
                    label: format!(
                        "LoWC v{id} {track} {horizontal_m:.0} m / {vertical_m:.0} m +{:.1} s",
                        (lost_t - f.t0_s).max(0.0)
                    ),
                    normal: Vec3::ZERO,
                });
                log_points(
                    rec,
                    paths::WELL_CLEAR,
                    &self.well_clear,
                    8.0,
                    [255, 220, 0],
                    true,
                )?;
                if let Some((dthr_m, zthr_m)) = f.well_clear_m {
                    let centre = at.position_at(*lost_t);
                    self.volumes
                        .push((centre, dthr_m as f32, 2.0 * zthr_m as f32));
                    self.log_volumes(rec)?;
                }
                Ok(None)
            }
            _ => Ok(None),
        }
    }

    /// The well-clear volume (DTHR wide, ZTHR above and below) around the vehicle at every
    /// loss so far: yellow wireframe cylinders.
    fn log_volumes(&self, rec: &RecordingStream) -> RecordingStreamResult<()> {
        rec.log(
            paths::WELL_CLEAR_VOLUMES,
            &Cylinders3D::from_lengths_and_radii(
                self.volumes.iter().map(|v| v.2),
                self.volumes.iter().map(|v| v.1),
            )
            .with_centers(self.volumes.iter().map(|v| v.0.to_array()))
            .with_colors([Color::from_unmultiplied_rgba(255, 220, 0, 160)])
            .with_fill_mode(FillMode::MajorWireframe),
        )
    }

    /// Every collision so far: its point, labelled, and its normal as an arrow `normal_m`
    /// long.
    fn log_collisions(&self, rec: &RecordingStream, normal_m: f32) -> RecordingStreamResult<()> {
        log_points(
            rec,
            paths::COLLISIONS,
            &self.collisions,
            10.0,
            [255, 0, 0],
            true,
        )?;
        rec.log(
            paths::COLLISION_NORMALS,
            &Arrows3D::from_vectors(
                self.collisions
                    .iter()
                    .map(|m| (m.normal * normal_m).to_array()),
            )
            .with_origins(self.collisions.iter().map(|m| m.at.to_array()))
            .with_colors([Color::from_rgb(255, 0, 0)]),
        )
    }
}

impl Where<'_> {
    /// The vehicle's logged position nearest `t_s` among the recent ones (now, if none is
    /// kept).
    fn position_at(&self, t_s: f64) -> Vec3 {
        self.recent
            .iter()
            .min_by(|a, b| (a.0 - t_s).abs().total_cmp(&(b.0 - t_s).abs()))
            .map_or(self.now, |r| r.1)
    }
}

/// Markers as points `radius_ui` points wide, labels on screen or on hover only.
fn log_points(
    rec: &RecordingStream,
    path: &str,
    markers: &[Marker],
    radius_ui: f32,
    [r, g, b]: [u8; 3],
    show_labels: bool,
) -> RecordingStreamResult<()> {
    rec.log(
        path,
        &Points3D::new(markers.iter().map(|m| m.at.to_array()))
            .with_radii([-radius_ui])
            .with_colors([Color::from_rgb(r, g, b)])
            .with_labels(markers.iter().map(|m| m.label.as_str()))
            .with_show_labels(show_labels),
    )
}

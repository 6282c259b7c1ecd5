//! A range device's beams cast against the world: all at once from the sample's pose, or, for
//! a spinning lidar, its turn read as it is swept: each column of beams from where the vehicle
//! was, and how it was turned, when the head pointed along it, not the whole turn at the
//! reading's instant. A fast or turning vehicle's scan is then distorted as a real one is (a
//! wall ahead read half a turn earlier is farther by half a turn's travel); what is cast is
//! the same rays as at one instant, in fans of [`COLUMNS_PER_FAN`] neighbouring columns, each
//! from the vehicle's pose at its middle column's time (the sample's pose carried back along
//! its velocity and body rates, `TrackSample::pose_carried`). The other bodies stay at their
//! poses at the sample: their own motion over the turn is not spread.

use glam::{DQuat, DVec3};
use savsim_core::pipeline::ObstacleRef;
use savsim_core::sensors::device::{Device, Model};
use savsim_core::sensors::range::Beam;

use super::FrameInput;
use crate::pipeline::{Pipeline, Rays};

/// Columns in each fan a turn is cast in: a row's stretch of them is one of the exact cast's
/// chunks of neighbouring rays (`collision::fan`), so the turn costs what one fan of its rays
/// does. A fan spans 32 columns' time (1.8 ms of a VLP-16's 10 Hz turn, 4 ms of an RPLIDAR's):
/// a column's pose is off its own by at most half of that.
const COLUMNS_PER_FAN: usize = 32;

/// A turn to read: the device's beams, how they sit on the vehicle, and when.
struct Turn<'a> {
    /// Its beams, row after row of `columns` each, every beam with as many rays.
    beams: &'a [Beam],
    /// Columns in a row, in the order they are swept.
    columns: usize,
    /// The device's frame to the body's FRD, and its place in FRD, metres.
    mount: (DQuat, DVec3),
    /// How long a turn takes, and how long before the sample it ended (the reading's
    /// instant), seconds.
    turn_s: f64,
    end_before_sample_s: f64,
    /// How far its rays reach, metres.
    max_m: f64,
}

/// What a cast reuses from reading to reading (no allocation once grown): the rays'
/// directions, and a fan's hits.
#[derive(Debug, Clone, Default)]
pub(super) struct CastScratch {
    dirs: Vec<DVec3>,
    hits: Vec<Option<(ObstacleRef, f64)>>,
}

/// Device `device`'s rays at instant `k` (its `beams`), into `hits` (its rays in the beams'
/// order, one after the other): over its turn when it spins (`turn_columns`, checked with
/// [`fits`]), else all at once from the sample's pose. Nothing for a device that is not a
/// range device.
pub(super) fn cast_beams(
    device: &Device,
    turn_columns: Option<usize>,
    (k, beams): (u64, &[Beam]),
    pipeline: &mut Pipeline,
    input: &FrameInput<'_>,
    scratch: &mut CastScratch,
    hits: &mut [Option<(ObstacleRef, f64)>],
) {
    let Model::Range(model) = &device.model else {
        return;
    };
    let current = input.current;
    let mount = mount_rotation(device.mount.yaw_deg, device.mount.pitch_deg);
    let mount_frd_m = DVec3::from_array(device.mount.position_frd_m);
    if let Some(columns) = turn_columns {
        let sample_s = f64::from(current.time_boot_ms) / 1000.0;
        let spun = Turn {
            beams,
            columns,
            mount: (mount, mount_frd_m),
            turn_s: 1.0 / device.rate_hz,
            end_before_sample_s: (sample_s - k as f64 / device.rate_hz).max(0.0),
            max_m: model.range_m[1],
        };
        return cast_turn(pipeline, input, &spun, scratch, hits);
    }
    let enu_from_frd = current.attitude.enu_from_frd;
    scratch.dirs.clear();
    scratch.dirs.extend(
        beams
            .iter()
            .flat_map(|b| b.iter().map(|d| enu_from_frd * (mount * *d))),
    );
    let rays = Rays {
        origin_enu_m: current.position_enu_m + enu_from_frd * mount_frd_m,
        dirs_enu: &scratch.dirs,
        max_m: model.range_m[1],
    };
    let own = input.key.source();
    pipeline.cast_exact_hits(input.scene, own, input.dynamic, rays, hits);
}

/// Whether `beams` can be read as a turn of `columns` columns: whole rows, every beam with as
/// many rays.
pub(super) fn fits(beams: &[Beam], columns: usize) -> bool {
    let rays = beams.first().map_or(0, |b| b.len());
    columns > 0
        && !beams.is_empty()
        && beams.len().is_multiple_of(columns)
        && beams.iter().all(|b| b.len() == rays)
}

/// Every ray of `turn` cast from the pose of its column's time: `hits[i]` what ray `i` (in
/// the beams' order, their rays one after the other) met, and how far.
fn cast_turn(
    pipeline: &mut Pipeline,
    input: &FrameInput<'_>,
    turn: &Turn<'_>,
    scratch: &mut CastScratch,
    hits: &mut [Option<(ObstacleRef, f64)>],
) {
    let n = turn.columns;
    let rays = turn.beams.first().map_or(0, |b| b.len());
    let rows = turn.beams.len() / n;
    let (mount, mount_frd_m) = turn.mount;
    for first in (0..n).step_by(COLUMNS_PER_FAN) {
        let end = (first + COLUMNS_PER_FAN).min(n);
        let middle = (first + end) as f64 / 2.0 / n as f64;
        let back_s = turn.end_before_sample_s + turn.turn_s * (1.0 - middle);
        let (position_enu_m, enu_from_frd) = input.current.pose_carried(-back_s);
        let enu_from_device = enu_from_frd * mount;
        scratch.dirs.clear();
        for row in 0..rows {
            let columns = &turn.beams[row * n + first..row * n + end];
            let dirs = columns.iter().flat_map(|b| b.iter());
            scratch.dirs.extend(dirs.map(|d| enu_from_device * *d));
        }
        scratch.hits.clear();
        scratch.hits.resize(scratch.dirs.len(), None);
        let fan = Rays {
            origin_enu_m: position_enu_m + enu_from_frd * mount_frd_m,
            dirs_enu: &scratch.dirs,
            max_m: turn.max_m,
        };
        let own = input.key.source();
        pipeline.cast_exact_hits(input.scene, own, input.dynamic, fan, &mut scratch.hits);
        // Back in the beams' order: each row's stretch of the fan is a stretch of the turn.
        let per_row = (end - first) * rays;
        for (row, fanned) in scratch.hits.chunks_exact(per_row).enumerate() {
            let at = (row * n + first) * rays;
            if let Some(out) = hits.get_mut(at..at + per_row) {
                out.copy_from_slice(fanned);
            }
        }
    }
}

/// The rotation from a device's frame (x boresight, y right, z down) to the body's FRD for a
/// mount yawed `yaw_deg` clockwise and pitched `pitch_deg` up.
pub(super) fn mount_rotation(yaw_deg: f64, pitch_deg: f64) -> DQuat {
    // Yaw about the body's down axis (clockwise seen from above), then pitch about the
    // device's right axis: a positive rotation about y turns x towards -z, up in FRD.
    DQuat::from_rotation_z(yaw_deg.to_radians()) * DQuat::from_rotation_y(pitch_deg.to_radians())
}

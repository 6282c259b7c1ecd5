//! The modelled devices' whole readings, as a viewer shows them: a depth camera's depth image
//! and segmentation under its pinhole (drawn in 3D where the camera was and looked, and as
//! images of their own), a lidar's returns as points coloured by what they hit. Each device at
//! `world/vehicles/{sysid}/sensors/{device}` (docs/rerun.md).

use glam::DVec3;
use rerun::datatypes::ChannelDatatype;
use rerun::{
    AnnotationContext, Color, DepthImage, Pinhole, Points3D, RecordingStream,
    RecordingStreamResult, SegmentationImage, Transform3D,
};

use savsim_core::sensors::image::SegmentClass;

use super::draw::local;
use super::paths;
use crate::observe::{Capture, CaptureData};

/// Each class's colour in the segmentation and the points.
fn class_color(class: SegmentClass) -> [u8; 3] {
    match class {
        SegmentClass::Nothing => [0, 0, 0],
        SegmentClass::Building => [150, 150, 170],
        SegmentClass::Terrain => [120, 170, 90],
        SegmentClass::Tree => [40, 130, 60],
        SegmentClass::Vehicle => [60, 140, 255],
        SegmentClass::Aircraft => [255, 120, 40],
    }
}

/// The classes' legend, logged once at the root of the sensors.
pub(super) fn log_classes(rec: &RecordingStream) -> RecordingStreamResult<()> {
    rec.log_static(
        paths::WORLD,
        &AnnotationContext::new(SegmentClass::ALL.map(|c| {
            let [r, g, b] = class_color(c);
            (c as u16, c.name(), rerun::Rgba32::from_rgb(r, g, b))
        })),
    )
}

/// A capture of this tick, where it was made.
pub(super) fn log_capture(
    rec: &RecordingStream,
    offset: DVec3,
    c: &Capture,
) -> RecordingStreamResult<()> {
    let path = paths::sensor(c.system_id, &c.device);
    let q = c.enu_from_device.as_quat();
    rec.log(
        path.as_str(),
        &Transform3D::from_translation_rotation(
            local(offset, c.origin_enu_m).to_array(),
            rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]),
        ),
    )?;
    match &c.data {
        CaptureData::Depth { image, fov_deg } => {
            let size = [image.width_px, image.height_px];
            let focal = savsim_core::sensors::range::focal_px;
            let image_path = paths::sensor_image(c.system_id, &c.device);
            rec.log(
                image_path.as_str(),
                &Pinhole::from_focal_length_and_resolution(
                    [
                        focal(size[0], fov_deg[0]) as f32,
                        focal(size[1], fov_deg[1]) as f32,
                    ],
                    [size[0] as f32, size[1] as f32],
                )
                .with_camera_xyz(rerun::components::ViewCoordinates::FRD)
                .with_image_plane_distance(1.0),
            )?;
            // The viewer draws NaN and infinite depths as nothing: 0 is its "no depth".
            let depth: Vec<u8> = image
                .depth_m
                .iter()
                .flat_map(|d| if d.is_finite() { *d } else { 0.0 }.to_le_bytes())
                .collect();
            rec.log(
                format!("{image_path}/depth"),
                &DepthImage::from_data_type_and_bytes(depth, size, ChannelDatatype::F32)
                    .with_meter(1.0),
            )?;
            rec.log(
                format!("{image_path}/class"),
                &SegmentationImage::new(
                    image.class.clone(),
                    rerun::components::ImageFormat::segmentation(size, ChannelDatatype::U8),
                )
                .with_opacity(0.5),
            )?;
        }
        CaptureData::Points(cloud) => {
            let colors = cloud.class.iter().map(|&k| {
                let class = SegmentClass::ALL
                    .get(usize::from(k))
                    .copied()
                    .unwrap_or_default();
                let [r, g, b] = class_color(class);
                Color::from_rgb(r, g, b)
            });
            rec.log(
                format!("{path}/points"),
                &Points3D::new(cloud.points_m.iter().copied())
                    .with_colors(colors)
                    .with_radii([0.05]),
            )?;
        }
    }
    Ok(())
}

//! What an image device or a lidar gave at one of its instants, whole: a depth image and its
//! segmentation, or a point cloud, with where the device was and where it looked. Made for
//! those who watch a run (the viewer) when they ask for it; the autopilot is sent the range
//! picture alone (`super::devices`).

use glam::{DQuat, DVec3};

use savsim_core::sensors::image::{DepthImage, PointCloud};

/// One device's reading at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// The device's name.
    pub device: String,
    /// The vehicle's system id.
    pub system_id: u8,
    /// The device's instant on the vehicle's clock, seconds.
    pub instant_s: f64,
    /// Where the device was, scene ENU metres.
    pub origin_enu_m: DVec3,
    /// The rotation from the device's frame (x boresight, y right, z down) to ENU.
    pub enu_from_device: DQuat,
    /// What it gave.
    pub data: CaptureData,
}

/// An image or a cloud.
#[derive(Debug, Clone, PartialEq)]
pub enum CaptureData {
    /// A pinhole depth camera's image and segmentation, and its field of view (across,
    /// down; degrees).
    Depth {
        /// The image.
        image: DepthImage,
        /// Its field of view, edge to edge, degrees.
        fov_deg: [f64; 2],
    },
    /// A lidar's (or a rangefinder's) returns.
    Points(PointCloud),
}

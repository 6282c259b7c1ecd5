//! What an image device and a lidar give a planner or a viewer, made from a reading: a depth
//! image (each pixel's depth along the optical axis, its errors included) with its
//! segmentation (what each pixel's ray truly meets: the obstacle's id and class), or a point
//! cloud (each return where the device measured it, in the device's frame, with the segment
//! of what its ray met).
//!
//! Depth follows the convention of depth images in robotics: metres as `f32`, `NaN` for a
//! pixel without a reading (invalid, nearer than the device reads, a lost reading) and `+inf`
//! for nothing within its range. The segmentation is the truth, without errors: the id and
//! class of the nearest obstacle on the pixel's ray within the device's range (0 and
//! [`SegmentClass::Nothing`] when none), whatever the depth reads.

use glam::DVec3;

use crate::sensors::range::{Beam, BeamReading, BeamTruth};

/// What a pixel or a point sees, by class (the numbers are those of the segmentation
/// image's class layer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[repr(u8)]
pub enum SegmentClass {
    /// Nothing within range.
    #[default]
    Nothing = 0,
    /// A building (or any static obstacle that is not terrain or a tree).
    Building = 1,
    /// Terrain: a mountain or a height field.
    Terrain = 2,
    /// A tree.
    Tree = 3,
    /// Another vehicle of the run (a MAVLink vehicle).
    Vehicle = 4,
    /// Other traffic: a scene's moving obstacle or an ADS-B aircraft.
    Aircraft = 5,
}

impl SegmentClass {
    /// Every class, by number.
    pub const ALL: [SegmentClass; 6] = [
        SegmentClass::Nothing,
        SegmentClass::Building,
        SegmentClass::Terrain,
        SegmentClass::Tree,
        SegmentClass::Vehicle,
        SegmentClass::Aircraft,
    ];

    /// Its name, as in the class layer's legend.
    pub fn name(self) -> &'static str {
        match self {
            SegmentClass::Nothing => "nothing",
            SegmentClass::Building => "building",
            SegmentClass::Terrain => "terrain",
            SegmentClass::Tree => "tree",
            SegmentClass::Vehicle => "vehicle",
            SegmentClass::Aircraft => "aircraft",
        }
    }
}

/// What one ray truly meets: a segment id (0: nothing; see docs/sensors.md for how ids are
/// made) and its class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Segment {
    /// The obstacle's id in the segmentation (0: nothing).
    pub id: u32,
    /// Its class.
    pub class: SegmentClass,
}

/// A depth image and its segmentation, row by row from the top left.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DepthImage {
    /// Pixels across.
    pub width_px: u32,
    /// Pixels down.
    pub height_px: u32,
    /// Depth along the optical axis, metres (`NaN`: no reading; `+inf`: nothing in range).
    pub depth_m: Vec<f32>,
    /// The segment id each pixel's ray meets (0: nothing).
    pub segment_id: Vec<u32>,
    /// Its class ([`SegmentClass`] as a number).
    pub class: Vec<u8>,
}

/// A lidar's returns: each where it was measured, in the device's frame (x along its
/// boresight, y right, z down; metres), with what its ray truly met.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Each return's position, device frame, metres.
    pub points_m: Vec<[f32; 3]>,
    /// The segment id its ray met.
    pub segment_id: Vec<u32>,
    /// Its class ([`SegmentClass`] as a number).
    pub class: Vec<u8>,
}

impl DepthImage {
    /// Fill this `w` x `h` image from a reading: `readings[i]` and `truths[i]` of pixel `i`
    /// (its ray's axial cosine turns a range into a depth), and `segments[i]`, what its ray
    /// met. The buffers are reused.
    ///
    /// ```
    /// use savsim_core::sensors::image::{DepthImage, Segment, SegmentClass};
    /// use savsim_core::sensors::range::{BeamReading, BeamTruth};
    /// let truths = [BeamTruth { distance_m: Some(2.0), axial_cos: 0.5 }; 2];
    /// let readings = [BeamReading::Range(2.0), BeamReading::NoData];
    /// let wall = Segment { id: 7, class: SegmentClass::Building };
    /// let mut image = DepthImage::default();
    /// image.fill(2, 1, &readings, &truths, &[wall, wall]);
    /// assert_eq!(image.depth_m[0], 1.0);
    /// assert!(image.depth_m[1].is_nan());
    /// assert_eq!((image.segment_id[1], image.class[1]), (7, 1));
    /// ```
    pub fn fill(
        &mut self,
        w: u32,
        h: u32,
        readings: &[BeamReading],
        truths: &[BeamTruth],
        segments: &[Segment],
    ) {
        self.width_px = w;
        self.height_px = h;
        self.depth_m.clear();
        self.depth_m
            .extend(readings.iter().zip(truths).map(|(r, t)| match r {
                BeamReading::Range(d) => (d * t.axial_cos) as f32,
                BeamReading::Clear => f32::INFINITY,
                BeamReading::NoData => f32::NAN,
            }));
        fill_segments(&mut self.segment_id, &mut self.class, segments);
    }
}

impl PointCloud {
    /// Fill this cloud from a reading: a point for each beam that returned, along its centre
    /// ray (`beams[i]`'s first) at the range it read, with the segment its rays met.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::sensors::image::{PointCloud, Segment};
    /// use savsim_core::sensors::range::{Beam, BeamReading};
    /// let beams = [Beam::from_elem(DVec3::X, 1), Beam::from_elem(DVec3::Y, 1)];
    /// let readings = [BeamReading::Range(3.0), BeamReading::Clear];
    /// let mut cloud = PointCloud::default();
    /// cloud.fill(&beams, &readings, &[Segment::default(); 2]);
    /// assert_eq!(cloud.points_m, [[3.0, 0.0, 0.0]]);
    /// ```
    pub fn fill(&mut self, beams: &[Beam], readings: &[BeamReading], segments: &[Segment]) {
        self.points_m.clear();
        self.segment_id.clear();
        self.class.clear();
        for ((beam, reading), segment) in beams.iter().zip(readings).zip(segments) {
            let (BeamReading::Range(d), Some(dir)) = (reading, beam.first()) else {
                continue;
            };
            let p: DVec3 = *dir * *d;
            self.points_m.push(p.as_vec3().to_array());
            self.segment_id.push(segment.id);
            self.class.push(segment.class as u8);
        }
    }
}

fn fill_segments(ids: &mut Vec<u32>, classes: &mut Vec<u8>, segments: &[Segment]) {
    ids.clear();
    ids.extend(segments.iter().map(|s| s.id));
    classes.clear();
    classes.extend(segments.iter().map(|s| s.class as u8));
}

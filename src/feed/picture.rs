//! A range picture of the modelled devices: the 72 bins, up and down, each a return, clear,
//! or no data; how the devices' readings combine into one, and the messages and viewer
//! readings made from it.

use glam::DVec3;

use savsim_core::sensors::range::BeamReading;

use super::sectors::{Levelled, BIN0_DEG, BINS, BINS_PER_SECTOR};
use super::wire::{self, Range};
use super::{Frame, ORIENTATION_DOWN, ORIENTATION_UP};

/// A picture of the bins, up and down from one range reading (or several combined).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Picture {
    pub(super) bins: [BeamReading; BINS],
    pub(super) up: BeamReading,
    pub(super) down: BeamReading,
}

impl Default for Picture {
    fn default() -> Self {
        Self {
            bins: [BeamReading::NoData; BINS],
            up: BeamReading::NoData,
            down: BeamReading::NoData,
        }
    }
}

/// The nearer of two cells: a return beats clear, which beats no data.
pub(super) fn nearer(a: BeamReading, b: BeamReading) -> BeamReading {
    use BeamReading::{Clear, NoData, Range};
    match (a, b) {
        (Range(x), Range(y)) => Range(x.min(y)),
        (Range(x), _) | (_, Range(x)) => Range(x),
        (Clear, _) | (_, Clear) => Clear,
        (NoData, NoData) => NoData,
    }
}

impl Picture {
    pub(super) fn take(&mut self, other: &Picture) {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            *a = nearer(*a, *b);
        }
        self.up = nearer(self.up, other.up);
        self.down = nearer(self.down, other.down);
    }
}

/// The bin of a bearing (degrees clockwise from the nose).
pub(super) fn bin_of(bearing_deg: f64) -> usize {
    let j = ((bearing_deg - BIN0_DEG) / super::sectors::BIN_DEG).round() as i64;
    j.rem_euclid(BINS as i64) as usize
}

/// The messages of a frame from a picture: proximity sectors (and up), OBSTACLE_DISTANCE, the
/// rangefinder, each as configured; nothing for a sector or rangefinder with no data.
pub(super) fn send_picture(
    picture: &Picture,
    range: Range,
    config: &super::FeedConfig,
    f: &mut Frame<'_, '_>,
) {
    let kinds = config.kinds;
    let as_distance = |c: BeamReading| match c {
        BeamReading::Range(d) => Some(Some(d)),
        BeamReading::Clear => Some(None),
        BeamReading::NoData => None,
    };
    if kinds.proximity {
        for (id, &o) in config.orientations.iter().enumerate() {
            let cell = if o == ORIENTATION_UP {
                picture.up
            } else {
                let first = usize::from(o) * BINS_PER_SECTOR;
                picture.bins[first..first + BINS_PER_SECTOR]
                    .iter()
                    .fold(BeamReading::NoData, |a, b| nearer(a, *b))
            };
            if let Some(distance_m) = as_distance(cell) {
                f.push(wire::distance_sensor(
                    f.stamp,
                    range,
                    distance_m,
                    o,
                    config.sensor_type,
                    id as u8,
                ));
            }
        }
    }
    if kinds.obstacle_distance {
        f.push(wire::obstacle_distance_cells(
            f.stamp,
            range,
            &picture.bins,
            config.sensor_type,
        ));
    }
    if kinds.rangefinder {
        if let Some(distance_m) = as_distance(picture.down) {
            let id = config.orientations.len() as u8;
            f.push(wire::distance_sensor(
                f.stamp,
                range,
                distance_m,
                ORIENTATION_DOWN,
                config.sensor_type,
                id,
            ));
        }
    }
}

/// What the viewer draws of a picture: each bin with a return or clear, along its centre line.
pub(super) fn readings_of<'a>(
    picture: &'a Picture,
    f: &Frame<'_, '_>,
) -> impl Iterator<Item = super::Reading> + 'a {
    let current = f.input.current;
    let down_enu = (current.attitude.enu_from_frd * DVec3::Z).normalize_or(-f.up_enu);
    let levelled = Levelled::new(current.attitude.forward_enu(), down_enu, f.up_enu);
    picture
        .bins
        .iter()
        .enumerate()
        .filter_map(move |(j, cell)| {
            let dir_enu = levelled?.direction(BIN0_DEG + j as f64 * super::sectors::BIN_DEG);
            match cell {
                BeamReading::Range(d) => Some(super::Reading {
                    dir_enu,
                    distance_m: Some(*d),
                }),
                BeamReading::Clear => Some(super::Reading {
                    dir_enu,
                    distance_m: None,
                }),
                BeamReading::NoData => None,
            }
        })
}

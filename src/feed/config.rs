//! What a feed sends and how: the kinds of message, the settings and their checks, and the
//! sensors it sends from.

use serde::Serialize;

use super::sectors::SECTORS;
use super::wire::Range;
use super::ORIENTATION_UP;
use crate::scene::Scene;

/// What the feed sends.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FeedKinds {
    /// DISTANCE_SENSOR per horizontal sector (and up): ArduPilot's MAVLink proximity.
    pub proximity: bool,
    /// DISTANCE_SENSOR down: ArduPilot's MAVLink rangefinder, PX4's distance sensor.
    pub rangefinder: bool,
    /// OBSTACLE_DISTANCE, 72 bins: PX4's collision prevention, ArduPilot's proximity.
    pub obstacle_distance: bool,
    /// ADSB_VEHICLE for the other aircraft: ArduPilot's and PX4's traffic avoidance.
    pub adsb: bool,
    /// COLLISION for savsim's own threats.
    pub collision: bool,
}

impl FeedKinds {
    /// Parse `proximity,rangefinder,obstacle-distance,adsb,collision` (any subset).
    ///
    /// ```
    /// use savsim::feed::FeedKinds;
    /// let k = FeedKinds::parse("proximity,adsb").unwrap();
    /// assert!(k.proximity && k.adsb && !k.rangefinder);
    /// assert!(FeedKinds::parse("proximity,obstacle-distance").is_err());
    /// assert!(FeedKinds::parse("lidar").is_err());
    /// ```
    pub fn parse(list: &str) -> Result<Self, FeedError> {
        let mut k = FeedKinds::default();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "proximity" => k.proximity = true,
                "rangefinder" => k.rangefinder = true,
                "obstacle-distance" => k.obstacle_distance = true,
                "adsb" => k.adsb = true,
                "collision" => k.collision = true,
                other => return Err(FeedError::Unknown(other.into())),
            }
        }
        if k.proximity && k.obstacle_distance {
            // ArduPilot's MAVLink proximity keeps one picture: each message clears the other's.
            return Err(FeedError::ProximityAndObstacleDistance);
        }
        Ok(k)
    }

    /// True when anything is sent.
    pub fn any(&self) -> bool {
        self.proximity || self.rangefinder || self.obstacle_distance || self.adsb || self.collision
    }

    /// True when the horizontal bins are cast.
    pub(super) fn needs_bins(&self) -> bool {
        self.proximity || self.obstacle_distance
    }
}

/// How the feed behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedConfig {
    /// What is sent.
    pub kinds: FeedKinds,
    /// Frames per second of the vehicle's clock (the autopilot's timeouts run on it).
    pub hz: f64,
    /// The range sensors' limits.
    pub range: Range,
    /// The proximity orientations sent: 0..7 (sectors), 24 (up).
    pub orientations: Vec<u8>,
    /// MAV_DISTANCE_SENSOR type of every reading (0 laser).
    pub sensor_type: u8,
    /// ADSB_VEHICLE reports per aircraft per second (vehicle's clock).
    pub adsb_hz: f64,
    /// Aircraft farther than this from the vehicle are not reported as ADS-B (where they are
    /// reported at: their truth, or a modelled device's report), metres. Default 2000,
    /// ArduCopter's ADSB_LIST_RADIUS (ArduPlane's is 10000).
    pub adsb_radius_m: f64,
    /// COLLISION: report aircraft whose closest approach comes within this horizontally,
    /// metres...
    pub collision_horizontal_m: f64,
    /// ... and this vertically, metres...
    pub collision_vertical_m: f64,
    /// ... within this many seconds.
    pub collision_horizon_s: f64,
    /// The vehicle's sensors: `ideal` (the exact feed) or modelled devices.
    pub sensors: savsim_core::sensors::suite::Suite,
    /// The seed of the devices' errors.
    pub sensor_seed: u64,
}

impl Default for FeedConfig {
    fn default() -> Self {
        Self {
            kinds: FeedKinds::default(),
            hz: 20.0,
            range: Range {
                min_m: 0.2,
                max_m: 40.0,
            },
            orientations: (0..SECTORS as u8).chain([ORIENTATION_UP]).collect(),
            sensor_type: 0,
            adsb_hz: 2.0,
            adsb_radius_m: 2000.0,
            collision_horizontal_m: 150.0,
            collision_vertical_m: 30.0,
            collision_horizon_s: 30.0,
            sensors: savsim_core::sensors::suite::Suite::Ideal,
            sensor_seed: 0,
        }
    }
}

impl FeedConfig {
    /// Check the settings; the error names what is wrong.
    pub fn validate(&self) -> Result<(), FeedError> {
        use savsim_core::bounds::{positive, within};
        positive("--feed-hz", self.hz, 1000.0)?;
        positive("the ADS-B rate", self.adsb_hz, 100.0)?;
        within("--feed-adsb-radius-m", self.adsb_radius_m, 0.0, 1e6)?;
        let Range { min_m, max_m } = self.range;
        if !(min_m.is_finite() && max_m.is_finite() && 0.0 <= min_m && min_m < max_m) {
            return Err(FeedError::RangeOrder { min_m, max_m });
        }
        if max_m > 650.0 {
            return Err(FeedError::RangeTooLong { max_m });
        }
        if let Some(&o) = self
            .orientations
            .iter()
            .find(|&&o| !(o < SECTORS as u8 || o == ORIENTATION_UP))
        {
            return Err(FeedError::Orientation(o));
        }
        Ok(())
    }
}

/// The sensors a run's feed sends from: those `list` names (`ideal`, presets with settings,
/// files of `[[sensor]]` tables, read within `crate::files`' bound), else the scene's
/// `[[sensor]]` tables, else `ideal`.
pub fn sensors_for(
    list: Option<&str>,
    scene: Option<&Scene>,
) -> crate::error::Result<savsim_core::sensors::suite::Suite> {
    use savsim_core::sensors::suite::Suite;
    let usage = |e: savsim_core::sensors::suite::SuiteError| {
        crate::error::Error::Usage(format!("--sensors: {e}"))
    };
    match (list, scene) {
        (Some(list), _) => Suite::parse(list, |path| {
            crate::files::read_text(std::path::Path::new(path), 1 << 20).map_err(|e| e.to_string())
        })
        .map_err(usage),
        (None, Some(scene)) if !scene.sensors.is_empty() => {
            Suite::from_specs(&scene.sensors).map_err(usage)
        }
        _ => Ok(Suite::Ideal),
    }
}

/// Feed settings that are not valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeedError {
    /// A rate or a radius out of range.
    #[error(transparent)]
    OutOfRange(#[from] savsim_core::bounds::OutOfRange),
    /// A range sensor's limits in the wrong order.
    #[error("the feed's range must be 0 <= min < max, not {min_m} .. {max_m} m")]
    RangeOrder {
        /// Its minimum, metres.
        min_m: f64,
        /// Its maximum, metres.
        max_m: f64,
    },
    /// A maximum range DISTANCE_SENSOR cannot carry.
    #[error("the feed's max range {max_m} m does not fit DISTANCE_SENSOR's centimetres")]
    RangeTooLong {
        /// The maximum, metres.
        max_m: f64,
    },
    /// A proximity orientation that is not one.
    #[error("proximity orientation {0}: 0..7 (45-degree sectors) or 24 (up); 25 (down) is `rangefinder`")]
    Orientation(u8),
    /// A feed that is not one.
    #[error("unknown feed `{0}` (proximity, rangefinder, obstacle-distance, adsb, collision)")]
    Unknown(String),
    /// Two feeds that cannot go together.
    #[error("`proximity` and `obstacle-distance` feed the same ArduPilot proximity backend and clear each other's picture: choose one")]
    ProximityAndObstacleDistance,
}

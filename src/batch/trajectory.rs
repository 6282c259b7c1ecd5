//! A track from a trajectory file in the CSV form MIT LL's encounter tools read and write
//! (em-pairing-uncor-importancesampling's `Example_Trajectory_Encounters/*.csv`): a header
//! naming at least `Time` (seconds), `lat`, `lon` (degrees) and `alt_MSL_ft`; other columns
//! (`ID`, `alt_AGL_ft`, `speed_kts`, `heading_deg`, `dh_fpm`) are not used. Each row is placed
//! in the scene's ENU frame by WGS84, `alt_MSL_ft` as its height; the clock starts at the first
//! row's time.

use std::path::Path;

use crate::batch::error::{TrackError, TrajectoryError};
use crate::geo::{Geodetic, LocalTangentPlane};
use crate::scene::{Scene, Waypoint};
use savsim_core::bounds::MAX_SAMPLES;

/// Metres in a foot.
const FT_M: f64 = 0.3048;

/// Whether a track is given as a trajectory file (rather than waypoints or a tlog).
pub fn is_trajectory_path(track: &str) -> bool {
    track.trim_end().to_ascii_lowercase().ends_with(".csv")
}

/// The track of a trajectory file, in `scene`'s ENU frame.
pub fn track_from_trajectory(path: &Path, scene: &Scene) -> Result<Vec<Waypoint>, TrackError> {
    read(path, scene).map_err(|source| TrackError::Trajectory {
        path: path.to_owned(),
        source,
    })
}

fn read(path: &Path, scene: &Scene) -> Result<Vec<Waypoint>, TrajectoryError> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(TrajectoryError::Open)?;
    let headers = reader.headers().map_err(TrajectoryError::Open)?.clone();
    let column = |wanted: &'static str| {
        headers
            .iter()
            .position(|h| h.eq_ignore_ascii_case(wanted))
            .ok_or(TrajectoryError::NoColumn(wanted))
    };
    let at = [
        column("Time")?,
        column("lat")?,
        column("lon")?,
        column("alt_MSL_ft")?,
    ];
    let plane = LocalTangentPlane::new(scene.origin);
    let mut track: Vec<Waypoint> = Vec::new();
    let mut t0 = None;
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let record = record.map_err(|source| TrajectoryError::Row { line, source })?;
        if track.len() as f64 >= MAX_SAMPLES {
            return Err(TrajectoryError::TooLong);
        }
        let value = |k: usize| {
            record
                .get(at[k])
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or(TrajectoryError::NotANumber {
                    line,
                    column: at[k] + 1,
                })
        };
        let (t, lat_deg, lon_deg, alt_ft) = (value(0)?, value(1)?, value(2)?, value(3)?);
        if lat_deg.abs() > 90.0 || lon_deg.abs() > 360.0 || alt_ft.abs() > 1e7 {
            return Err(TrajectoryError::NotAPlace {
                line,
                lat_deg,
                lon_deg,
                alt_ft,
            });
        }
        let t_s = t - *t0.get_or_insert(t);
        if track.last().is_some_and(|w| t_s <= w.t_s) {
            return Err(TrajectoryError::TimeNotAfter(line));
        }
        let enu = plane.enu_m_from_geodetic(&Geodetic {
            lat_deg,
            lon_deg,
            alt_m: alt_ft * FT_M,
        });
        track.push(Waypoint {
            t_s,
            position_enu_m: enu.to_array(),
        });
    }
    if track.is_empty() {
        return Err(TrajectoryError::Empty);
    }
    Ok(track)
}

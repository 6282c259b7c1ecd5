//! Why a manifest row could not run (its `error` cell), and why one of its tracks (waypoints,
//! a tlog, a trajectory file, a DAIDALUS state file) could not be read: every error of a batch
//! row, so that what reads a track imports this and this imports none of them.

use std::path::PathBuf;

use crate::daa::well_clear::SETTING_HELP;
use crate::runs::scenes::SceneLookup;
use crate::runs::waypoints::WaypointError;
use savsim_core::bounds::{OutOfRange, MAX_SAMPLES};

/// Why a row could not run. Its text is the row's `error` cell.
#[derive(Debug, thiserror::Error)]
pub enum RowError {
    /// A number outside its range (`w`, `duration_s`, `rate_hz`).
    #[error(transparent)]
    OutOfRange(#[from] OutOfRange),
    /// The row's scene did not load (the error is shared by every row naming it).
    #[error(transparent)]
    Scene(SceneLookup),
    /// A `mode` savsim does not have.
    #[error("mode {0:?}: give one of none, box, mesh, paper, exact, reference")]
    Mode(String),
    /// An `intruder_kind` that is not an obstacle kind.
    #[error("intruder_kind {0:?}: not a kind")]
    IntruderKind(String),
    /// A `well_clear` that names no volume.
    #[error("well_clear {0:?}: {SETTING_HELP}")]
    WellClear(String),
    /// Neither a tlog, nor an encounter, nor a DAIDALUS file; or more than one.
    #[error("give either `tlog`, or both `own` and `intruder`, or `daa`")]
    Columns,
    /// A length and rate that make more samples than a row may have.
    #[error("duration_s {duration_s} x rate_hz {rate_hz}: at most {MAX_SAMPLES} samples a row")]
    TooManySamples {
        /// The row's length, seconds.
        duration_s: f64,
        /// Its rate, Hz.
        rate_hz: f64,
    },
    /// The ownship's track.
    #[error("own: {0}")]
    Own(TrackError),
    /// The intruder's track.
    #[error("intruder: {0}")]
    Intruder(TrackError),
    /// The DAIDALUS state file.
    #[error(transparent)]
    Daa(#[from] DaaTracksError),
    /// The replay or its session (a tlog that cannot be read, a session that cannot start).
    #[error(transparent)]
    Run(#[from] crate::error::Error),
    /// The row's `daa_conf` that cannot be read.
    #[error("daa_conf {path}: {source}")]
    DaaConfRead {
        /// The file, as the row names it.
        path: String,
        /// What the system said.
        source: std::io::Error,
    },
    /// The row's `daa_conf` that is not a DAIDALUS configuration.
    #[error("daa_conf {path}: {source}")]
    DaaConf {
        /// The file, as the row names it.
        path: String,
        /// What is wrong with it.
        source: crate::daa::conf::ConfError,
    },
    /// The row's `sensors` that cannot be used (exact ADS-B stands for `ideal`).
    #[error(transparent)]
    Sensors(#[from] crate::sensors::suite::SuiteError),
    /// The row's `sensed_daa` that cannot be written.
    #[error("sensed_daa {path}: {source}")]
    SensedFile {
        /// The file, as the row names it.
        path: String,
        /// What the system said.
        source: std::io::Error,
    },
    /// A panic caught while running the row: a bug.
    #[error("internal error, please report it: {0}")]
    Internal(String),
    /// The row's recording could not be kept where it goes (`--rerun-rows`).
    #[error("recording: {}: {source}", path.display())]
    RecordingFile {
        /// Where.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// An intruder of the row has the name of a track of its scene: no recording can show both.
    #[error("recording: the scene has a track named {0} already")]
    RecordingTrack(String),
}

/// Why a track (waypoints, a tlog or a trajectory file) could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// A waypoint list.
    #[error(transparent)]
    Waypoints(#[from] WaypointError),
    /// A tlog that could not be opened or read.
    #[error("{}: {source}", path.display())]
    Tlog {
        /// The file.
        path: PathBuf,
        /// What the OS or the reader said.
        source: std::io::Error,
    },
    /// A tlog with no position of a vehicle in it.
    #[error("{}: no vehicle position in it", .0.display())]
    NoPosition(PathBuf),
    /// A trajectory file.
    #[error("{}: {source}", path.display())]
    Trajectory {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        source: TrajectoryError,
    },
    /// A track with no waypoint.
    #[error("no waypoints")]
    Empty,
}

/// Why a trajectory file could not be read (the path is added by [`TrackError`]).
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// The file could not be opened, or its header read.
    #[error("{0}")]
    Open(csv::Error),
    /// A column the track needs is not in the header.
    #[error("no `{0}` column (needs Time, lat, lon, alt_MSL_ft)")]
    NoColumn(&'static str),
    /// A row that could not be read.
    #[error("line {line}: {source}")]
    Row {
        /// The line, from 1 (the header is line 1).
        line: usize,
        /// What the CSV reader said.
        source: csv::Error,
    },
    /// More rows than a track may have.
    #[error("more than {MAX_SAMPLES:e} rows")]
    TooLong,
    /// A cell that is not a finite number.
    #[error("line {line}: column {column}: not a number")]
    NotANumber {
        /// The line, from 1.
        line: usize,
        /// The column, from 1.
        column: usize,
    },
    /// A latitude, longitude or altitude no place has.
    #[error("line {line}: {lat_deg}, {lon_deg}, {alt_ft} ft: not a place")]
    NotAPlace {
        /// The line, from 1.
        line: usize,
        /// Its latitude, degrees.
        lat_deg: f64,
        /// Its longitude, degrees.
        lon_deg: f64,
        /// Its altitude, feet.
        alt_ft: f64,
    },
    /// A time not after the one before.
    #[error("line {0}: times must increase")]
    TimeNotAfter(usize),
    /// A header and nothing else.
    #[error("no rows")]
    Empty,
}

/// Why a DAIDALUS state file gave no encounter.
#[derive(Debug, thiserror::Error)]
pub enum DaaTracksError {
    /// The file could not be read (its path is in the error).
    #[error(transparent)]
    Read(Box<crate::error::Error>),
    /// The file is not a state file.
    #[error("{}: {source}", path.display())]
    Parse {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong with it.
        source: crate::daa::scenario::ScenarioError,
    },
    /// Fewer than two aircraft.
    #[error("{}: an encounter needs an ownship and at least one intruder", .0.display())]
    NoPair(std::path::PathBuf),
}

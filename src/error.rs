//! savsim's typed errors. The binary maps them to exit codes (see `main.rs`).

use std::io;
use std::path::PathBuf;

/// Everything that can stop a savsim command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    File {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: io::Error,
    },
    /// A network link failed.
    #[error("{what}: {source}")]
    Net {
        /// What was being done.
        what: String,
        /// What the OS said.
        source: io::Error,
    },
    /// A `--connect` address that savsim cannot use.
    #[error("bad connection address {address:?}: {reason}")]
    Address {
        /// The address as given.
        address: String,
        /// Why it is unusable.
        reason: String,
    },
    /// A scene file that cannot be used.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// A number outside the range its input allows.
    #[error(transparent)]
    OutOfRange(#[from] savsim_core::bounds::OutOfRange),
    /// A DAIDALUS configuration or state file that cannot be read.
    #[error("{path}: {message}")]
    Daa {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// An autopilot log that cannot be read at all.
    #[error("{path}: {source}")]
    Log {
        /// The file.
        path: PathBuf,
        /// Why.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A command-line value that parses but makes no sense.
    #[error("{0}")]
    Usage(String),
    /// A run that could not go on or finish (stopped by a signal, threads that could not
    /// start, a child run that failed): exit code 1, never the usage code.
    #[error("{0}")]
    Runtime(String),
    /// The feed was asked for vehicles that share one endpoint (behind one router address):
    /// its messages carry no target, so each would read the other's sectors.
    #[error(
        "the feed is refused: vehicles {vehicles} are heard on one endpoint ({endpoint}), and \
         DISTANCE_SENSOR, OBSTACLE_DISTANCE and ADSB_VEHICLE name no target, so each vehicle \
         would take the others' readings as its own. Give each vehicle its own link: one \
         --connect per SITL (its own port), or one router output per vehicle (MAVProxy: a \
         separate instance per SITL; mavlink-router: an endpoint per SITL with a filter on its \
         system id); or run without --feed to mirror them only"
    )]
    SharedEndpoint {
        /// The vehicles, as `1/1 and 2/1`.
        vehicles: String,
        /// Where they were heard.
        endpoint: String,
    },
    /// The companion (`--companion`, a row's `companion`) failed: its process, its link, or
    /// what it answered (the companion's own error, said).
    #[error("{0}")]
    Companion(String),
}

impl Error {
    /// A file error for `path`.
    pub fn file(path: impl Into<PathBuf>, source: io::Error) -> Self {
        Error::File {
            path: path.into(),
            source,
        }
    }
}

/// savsim's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

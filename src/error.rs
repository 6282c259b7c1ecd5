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
        source: crate::ingest::ulog::UlogError,
    },
    /// A command-line value that parses but makes no sense.
    #[error("{0}")]
    Usage(String),
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

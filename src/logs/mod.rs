//! Flight logs read from files: tlogs (MAVLink frames with receive times; read with resync, and
//! written), PX4 ULog and ArduPilot DataFlash logs (read generically from their own format
//! records), and what those two hold as the reports savsim uses, in time order. Every byte here
//! comes from a file the user gave: the readers bound what they allocate and skip what is
//! corrupt (the fuzz targets read them).
//!
//! - [`tlog`]: tlog records: a streaming reader with resync, a writer.
//! - [`ulog`], [`dataflash`]: PX4 ULog and ArduPilot DataFlash files, read generically.
//! - [`flightlog`]: those logs to the same reports, in time order (they skip the framer).

pub mod dataflash;
pub mod flightlog;
pub mod tlog;
pub mod ulog;

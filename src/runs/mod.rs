//! What `batch` and `study` share: many runs from one manifest, cut into shards, each shard
//! one Parquet file written whole with savsim's version and the run's settings, and summarized
//! into rates and risk ratios. Neither command imports the other; both import this.
//!
//! - [`manifest`]: reading a manifest's rows (CSV, TOML, JSON) of either command.
//! - [`scenes`]: the scenes a manifest names, each loaded once per process.
//! - [`shard`]: which rows a process runs, and its file.
//! - [`table`]: rows as Arrow columns, a shard's Parquet file (written atomically, with
//!   metadata), and reading a directory of shards back.
//! - [`summary`]: outcome counts, rates and risk ratios per variant, as text and JSON.

pub mod manifest;
pub mod scenes;
pub mod shard;
pub mod summary;
pub mod table;

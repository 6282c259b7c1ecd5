//! What `batch` and `study` share: many runs from one manifest, cut into shards, each shard
//! one Parquet file written whole with savsim's version and the run's settings, and summarized
//! into rates and risk ratios. Neither command imports the other; both import this.
//!
//! - [`manifest`]: reading a manifest's rows (CSV, TOML, JSON) of either command.
//! - [`measured`]: what savsim measures of a run (contacts, approaches, well clear) and its
//!   columns, the same in both results.
//! - [`scenes`]: the scenes a manifest names, each loaded once per process.
//! - [`shard`]: which rows a process runs, and its file.
//! - [`table`]: rows as Arrow columns, a shard's Parquet file (written atomically, with
//!   metadata), and reading a directory of shards back.
//! - [`summary`]: outcome counts, rates and risk ratios per variant, as text and JSON.
//! - [`report`]: the same as one self-contained HTML page with charts and the rows.
//! - [`recordings`]: which rows are kept as rerun recordings (`--rerun-rows`).
//! - [`seeds`]: the seed a row's sensor errors are drawn with.
//! - [`waypoints`]: tracks written as text, `t_s e_m n_m u_m; ...`.

pub mod manifest;
pub mod measured;
pub mod model_tracks;
pub mod recordings;
pub mod report;
pub mod scenes;
pub mod seeds;
pub mod shard;
pub mod summary;
pub mod table;
pub mod waypoints;

/// Row `index`'s name for its files and folders: its index, then its id's letters, digits,
/// `-`, `_` and `#` (anything else `_`), so that no id names a path outside the run's.
///
/// ```
/// assert_eq!(savsim::runs::row_name(7, "../a b"), "000007-___a_b");
/// ```
pub fn row_name(index: u64, id: &str) -> String {
    let id: String = id
        .chars()
        .take(64)
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_#".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("{index:06}-{id}")
}

/// What a caught panic said (its `&str` or `String` payload; empty for any other).
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_default()
}

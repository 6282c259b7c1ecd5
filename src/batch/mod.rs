//! `savsim batch`: many runs (tlogs over scenes, and encounters) on every core, one row each,
//! written to Parquet by shard.
//!
//! - [`manifest`]: the runs, from CSV, TOML or JSON.
//! - [`run`](mod@run): one run, its failure kept as its row's error.
//! - [`encounter`]: an ownship and an intruder track through the collision pipeline.
//! - [`sensed`]: alerting on the states the ownship's sensors report (`daa_conf`, `sensors`).
//! - [`error`]: why a row, or one of its tracks, could not run.
//! - [`row`]: what a run's row holds.
//! - [`table`]: rows as Arrow and Parquet.
//! - [`record`]: rows as rerun recordings (`--rerun-rows`).

//! - [`gen`]: generated encounters, their truth known by construction.
//! - [`command`]: `savsim batch` on the command line.
//!
//! Results do not depend on how the runs are spread: each run has its own pipeline and
//! session, rows come back in manifest order, and only the measured costs differ between two
//! runs of one manifest.

pub mod command;
pub mod encounter;
pub mod error;
pub mod gen;
pub mod gen_model;
pub mod gen_pairing;
pub mod manifest;
pub mod record;
pub mod row;
pub mod run;
pub mod sensed;
pub mod summarize;
pub mod table;
pub mod trajectory;

use rayon::prelude::*;

use crate::error::{Error, Result};
use manifest::Run;
use row::RunRow;

/// Run `runs` (rows `first_index..` of a manifest) on `jobs` threads (all cores when `None`),
/// each recorded after it ran when `recorder` keeps it, calling `on_done` after each; rows
/// in manifest order.
pub fn run_rows(
    runs: &[Run],
    first_index: usize,
    jobs: Option<usize>,
    recorder: Option<record::Recorder<'_>>,
    on_done: impl Fn(&RunRow) + Sync,
) -> Result<Vec<RunRow>> {
    let scenes = run::Scenes::for_runs(runs);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.unwrap_or(0))
        .thread_name(|i| format!("savsim-batch-{i}"))
        .build()
        .map_err(|e| Error::Runtime(format!("batch: cannot start the threads: {e}")))?;
    Ok(pool.install(|| {
        runs.par_iter()
            .enumerate()
            .map(|(i, r)| {
                let row = run::run_one(first_index + i, r, &scenes);
                if let Some(said) = recorder.and_then(|rec| rec.after(r, &row, &scenes)) {
                    eprintln!("{said}");
                }
                on_done(&row);
                row
            })
            .collect()
    }))
}

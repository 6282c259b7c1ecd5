//! `savsim study`: closed-loop studies. Each row starts its own SITL autopilot, flies its
//! plan through savsim's scene with savsim's feed as the vehicle's sensors, and is scored;
//! rows run `--jobs` at a time, each job on its own SITL instance (its own ports).
//!
//! - [`manifest`]: the rows, from CSV, TOML or JSON.
//! - [`plan`]: a row's flight plan and parameters.
//! - [`sitl`]: starting and stopping one SITL; [`sitl_lockstep`]: an ArduCopter in lockstep.
//! - [`pilot`]: the ground station that flies the plan, on the vehicle's clock.
//! - [`row`]: one row (its SITLs' own physics, or in lockstep), its failure kept as its
//!   row's error.
//! - [`result`]: what a row's result holds; [`table`]: results as Parquet.
//! - [`summarize`]: risk ratios from a study's shards; [`gen`]: obstacle-approach pairs.
//! - [`converge`]: `--until-converged`, pairs in rounds until the ratios are known.
//! - [`netns`]: a study in a network namespace of its own.
//! - [`command`]: `savsim study` on the command line.

pub mod command;
pub mod converge;
pub mod gen;
pub mod manifest;
pub mod netns;
pub mod pilot;
pub mod plan;
pub mod result;
pub mod row;
pub mod sitl;
pub mod sitl_lockstep;
pub mod summarize;
pub mod table;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use manifest::StudyRow;
use result::StudyResult;
use row::Setup;

/// Run `rows` (each with its index in the manifest) `jobs` at a time, job `k` on SITL
/// instance `k`, calling `on_done` after each; results in the order of `rows`.
pub fn run_rows(
    rows: &[(usize, &StudyRow)],
    jobs: usize,
    setup: &Setup,
    on_done: &(dyn Fn(&StudyResult) + Sync),
) -> Vec<StudyResult> {
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<Option<StudyResult>>> = Mutex::new(vec![None; rows.len()]);
    std::thread::scope(|scope| {
        for job in 0..jobs.clamp(1, rows.len().max(1)) {
            let (next, done) = (&next, &done);
            scope.spawn(move || loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(index, row)) = rows.get(i) else {
                    return;
                };
                let result = row::run_row(index, row, job as u16, setup);
                on_done(&result);
                if let Ok(mut done) = done.lock() {
                    done[i] = Some(result);
                }
            });
        }
    });
    done.into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.unwrap_or_else(|| StudyResult::of_inputs(rows[i].0, rows[i].1)))
        .collect()
}

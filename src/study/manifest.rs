//! A study's rows, read from CSV, TOML (`[[run]]`) or JSON like `batch`'s manifests; unknown
//! columns are errors. A row's meaning (its plan, parameters, feed, intruder) is checked when
//! it runs, so that one bad row becomes a row with its error and the rest still run.
//!
//! ```
//! let csv = "id,scene,autopilot,variant,pair,params,feed,plan\n\
//!            a-1,box.toml,arducopter,mitigated,a,PRX1_TYPE=2;AVOID_ENABLE=3,proximity,takeoff 20;velocity 0 5 0 20\n";
//! let rows = savsim::study::manifest::parse_csv(csv.as_bytes()).unwrap();
//! assert_eq!(rows[0].feed.as_deref(), Some("proximity"));
//! assert!(savsim::study::manifest::parse_csv(b"id,colour\na,red\n").is_err());
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::Result;

/// One row of a study, as the manifest wrote it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyRow {
    /// Name in the results (default: `row-<index>`).
    pub id: Option<String>,
    /// A scene file (default: open air around the default home).
    pub scene: Option<String>,
    /// `arducopter` (default) or `px4`.
    pub autopilot: Option<String>,
    /// The variant the row flies (`nominal`, `mitigated`...).
    pub variant: Option<String>,
    /// The encounter the row is one variant of.
    pub pair: Option<String>,
    /// Autopilot parameters, `NAME=VALUE;...`, set before arming.
    pub params: Option<String>,
    /// The feed, as `--feed` (`proximity`, `obstacle-distance`, `adsb`...); none by default.
    pub feed: Option<String>,
    /// The vehicle's sensors the feed sends from, as `--sensors` (`ideal` by default, or the
    /// scene's `[[sensor]]` tables).
    pub sensors: Option<String>,
    /// The seed of the sensors' errors (default: made from `seed` and the row's `pair`, else
    /// its id: [`crate::runs::seeds`]).
    pub sensor_seed: Option<u64>,
    /// The flight plan (`study::plan`).
    pub plan: Option<String>,
    /// An intruder's track, waypoints `"t_s e_m n_m u_m; ..."` in the scene's ENU frame, `t_s`
    /// seconds of the vehicle's clock from its boot.
    pub intruder: Option<String>,
    /// The intruder's kind (default `dji`).
    pub intruder_kind: Option<String>,
    /// The row's length, seconds of the vehicle's clock from its boot (default 120).
    pub duration_s: Option<f64>,
    /// The SITL speedup (default: `--speedup`, else 1).
    pub speedup: Option<f64>,
    /// A generator's seed, carried to the results; the base the row's sensor errors are drawn
    /// from when it has no `sensor_seed` (default 1).
    pub seed: Option<u64>,
    /// Fly the row this many times (default 1), as `ID#0`, `ID#1`, ...
    pub repeat: Option<u32>,
    /// End the row at its first collision (default true).
    pub stop_on_collision: Option<bool>,
    /// The encounter's importance weight (default 1).
    pub w: Option<f64>,
    /// A second vehicle flown by its own autopilot (`arducopter` or `px4`) on its own SITL
    /// instance, instead of a scripted `intruder`: it flies `intruder_plan` with
    /// `intruder_params`, and the row's feed tells each vehicle of the other. A third follows a
    /// `|` (`arducopter|px4`), and so do its entries in the columns below (one entry there is
    /// for both).
    pub intruder_autopilot: Option<String>,
    /// The second vehicle's flight plan (`study::plan`; `until T` legs are on the row's
    /// clock, the first vehicle's).
    pub intruder_plan: Option<String>,
    /// The second vehicle's parameters, `NAME=VALUE;...`.
    pub intruder_params: Option<String>,
    /// The second vehicle's home, `E N` metres from the scene's origin (default `0 0`, the
    /// first vehicle's), on the scene's ground there.
    pub intruder_home: Option<String>,
    /// Who flies the vehicles: `autopilot` (each SITL its own physics, in wall time; the
    /// default) or `savsim` (lockstep: savsim's dynamics, every autopilot waiting for savsim's
    /// clock; docs/lockstep.md).
    pub physics: Option<String>,
    /// With `physics = savsim`: the vehicles' frame, a preset (`arducopter-quad`,
    /// `arducopter-quad-x`, `iris`) or a TOML file; default `arducopter-quad`.
    pub frame: Option<String>,
    /// With `physics = savsim`: the physics step, milliseconds (default 2.5).
    pub step_ms: Option<f64>,
    /// With `physics = savsim`: a constant wind, `E N U` m/s where the air goes, scene frame
    /// (default none).
    pub wind: Option<String>,
    /// With `physics = savsim`: a planner of your own flying the vehicle as its companion
    /// computer: its command line, started with `SAVSIM_COMPANION` set (docs/companion.md).
    pub companion: Option<String>,
    /// The companion's instants a second of the vehicle's clock (default 10).
    pub companion_hz: Option<f64>,
    /// Its modelled compute time: its commands reach the autopilot this long after its
    /// instant, seconds of the vehicle's clock (default 0).
    pub companion_latency_s: Option<f64>,
}

impl StudyRow {
    /// The row's id: its own, or `row-<index>`.
    pub fn id_or(&self, index: usize) -> String {
        self.id.clone().unwrap_or_else(|| format!("row-{index}"))
    }

    /// The encounter the row is a variant of: its `pair`, else its id.
    pub fn pair_or(&self, index: usize) -> String {
        self.pair.clone().unwrap_or_else(|| self.id_or(index))
    }

    /// The seed of the row's sensor errors: its `sensor_seed`, else one made from its `seed`
    /// and its encounter ([`crate::runs::seeds`]).
    ///
    /// ```
    /// use savsim::study::manifest::StudyRow;
    /// let row = |pair: &str, variant: &str| StudyRow {
    ///     pair: Some(pair.into()), variant: Some(variant.into()), seed: Some(11),
    ///     ..StudyRow::default()
    /// };
    /// // The variants of a pair share one; two pairs do not.
    /// assert_eq!(row("a", "nominal").sensor_seed_or(0), row("a", "mitigated").sensor_seed_or(1));
    /// assert_ne!(row("a", "nominal").sensor_seed_or(0), row("b", "nominal").sensor_seed_or(0));
    /// let own = StudyRow { sensor_seed: Some(3), ..row("a", "nominal") };
    /// assert_eq!(own.sensor_seed_or(0), 3);
    /// ```
    pub fn sensor_seed_or(&self, index: usize) -> u64 {
        crate::runs::seeds::sensor_seed(self.sensor_seed, self.seed, &self.pair_or(index))
    }

    /// The same row with its scene path made relative to `base` (a manifest's directory).
    pub fn anchored(mut self, base: &Path) -> Self {
        if let Some(path) = self.scene.as_mut().filter(|p| !p.is_empty()) {
            if Path::new(path.as_str()).is_relative() {
                *path = base.join(&*path).to_string_lossy().into_owned();
            }
        }
        self
    }
}

/// Read a study manifest (`.csv`, `.toml` or `.json`); scene paths become relative to its
/// directory; rows with `repeat` are expanded (`ID#k`).
pub fn load(path: &Path) -> Result<Vec<StudyRow>> {
    let (rows, base): (Vec<StudyRow>, PathBuf) = crate::runs::manifest::read_rows(path)?;
    expand(rows.into_iter().map(|r| r.anchored(&base)).collect())
        .map_err(|e| crate::error::Error::Usage(format!("{}: {e}", path.display())))
}

/// Rows from CSV with a header row; an empty cell is an absent value (not expanded).
pub fn parse_csv(bytes: &[u8]) -> std::result::Result<Vec<StudyRow>, csv::Error> {
    crate::runs::manifest::csv_rows(bytes)
}

/// Most times a row may be flown (`repeat`).
pub const MAX_REPEAT: u32 = 10_000;
/// Most rows a manifest may expand to.
pub const MAX_EXPANDED_ROWS: usize = 1_000_000;

/// Why a manifest's rows cannot be expanded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ExpandError {
    /// A `repeat` over [`MAX_REPEAT`].
    #[error("row {row} ({id}): repeat {repeat}: give at most {MAX_REPEAT}")]
    Repeat {
        /// The row, from 1.
        row: usize,
        /// Its id.
        id: String,
        /// Its repeat.
        repeat: u32,
    },
    /// More rows than [`MAX_EXPANDED_ROWS`] in all.
    #[error("the manifest expands to more than {MAX_EXPANDED_ROWS} rows")]
    TooMany,
}

/// Each row `repeat` times, as `ID#0`, `ID#1`, ...; a row without `repeat` (or with 1) once,
/// as it is; a row with `repeat = 0` not at all. A repeat over [`MAX_REPEAT`], or more than
/// [`MAX_EXPANDED_ROWS`] rows in all, is an error (nothing is flown).
///
/// ```
/// use savsim::study::manifest::{expand, StudyRow};
/// let row = StudyRow { id: Some("a".into()), repeat: Some(2), ..StudyRow::default() };
/// let ids: Vec<_> = expand(vec![row]).unwrap().into_iter().map(|r| r.id.unwrap()).collect();
/// assert_eq!(ids, ["a#0", "a#1"]);
/// let many = StudyRow { repeat: Some(10_001), ..StudyRow::default() };
/// assert!(expand(vec![many]).is_err());
/// ```
pub fn expand(rows: Vec<StudyRow>) -> std::result::Result<Vec<StudyRow>, ExpandError> {
    let mut total = 0usize;
    for (index, row) in rows.iter().enumerate() {
        let repeat = row.repeat.unwrap_or(1);
        if repeat > MAX_REPEAT {
            return Err(ExpandError::Repeat {
                row: index + 1,
                id: row.id_or(index),
                repeat,
            });
        }
        total += repeat as usize;
        if total > MAX_EXPANDED_ROWS {
            return Err(ExpandError::TooMany);
        }
    }
    let mut out = Vec::with_capacity(total);
    for (index, row) in rows.into_iter().enumerate() {
        match row.repeat {
            None | Some(1) => out.push(row),
            Some(n) => {
                let id = row.id_or(index);
                for k in 0..n {
                    out.push(StudyRow {
                        id: Some(format!("{id}#{k}")),
                        pair: row.pair.as_ref().map(|p| format!("{p}#{k}")),
                        ..row.clone()
                    });
                }
            }
        }
    }
    Ok(out)
}

/// Write rows as CSV (what `study gen` writes).
pub fn write_csv(
    rows: &[StudyRow],
    out: impl std::io::Write,
) -> std::result::Result<(), csv::Error> {
    crate::runs::manifest::write_csv(rows, out)
}

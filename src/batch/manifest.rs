//! A manifest: the runs of a batch, read from CSV, TOML or JSON.
//!
//! Every column is optional and read as written; what a run means is checked when it runs, so
//! that one bad row becomes a row with its error and the rest still run. Only a file that
//! cannot be read as a table at all is an error here.
//!
//! ```
//! let csv = "id,tlog,scene,mode\nsquare,flights/a.tlog,city.toml,exact\n";
//! let runs = savsim::batch::manifest::parse_csv(csv.as_bytes()).unwrap();
//! assert_eq!(runs[0].tlog.as_deref(), Some("flights/a.tlog"));
//! assert_eq!(runs[0].mode.as_deref(), Some("exact"));
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::Result;

/// One run, as the manifest wrote it.
///
/// A run is a **tlog** (`tlog`, with an optional `scene`) or an **encounter** (`own` and
/// `intruder` tracks, each waypoints `"t_s e_m n_m u_m; ..."` in the scene's ENU frame or a
/// `.tlog` path, over a `scene` or open air). Relative paths are relative to the manifest.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Run {
    /// Name in the results (default: `run-<row number>`).
    pub id: Option<String>,
    /// A flight log to replay: a tlog, a PX4 ULog or an ArduPilot DataFlash log (told apart by
    /// their first bytes).
    pub tlog: Option<String>,
    /// A scene file (default: open air around ArduPilot SITL's default home).
    pub scene: Option<String>,
    /// Collision mode (default `exact`).
    pub mode: Option<String>,
    /// Ownship track of an encounter.
    pub own: Option<String>,
    /// Intruder track of an encounter.
    pub intruder: Option<String>,
    /// The intruder's kind (default `dji`): its threat class and model.
    pub intruder_kind: Option<String>,
    /// Ownship sample rate of an encounter, Hz (default 10).
    pub rate_hz: Option<f64>,
    /// Encounter length, seconds (default: the ownship track's).
    pub duration_s: Option<f64>,
    /// The closest approach the encounter was built with, metres (carried to the results).
    pub expect_cpa_m: Option<f64>,
    /// Its horizontal part, metres.
    pub expect_cpa_horizontal_m: Option<f64>,
    /// Its vertical part (intruder above ownship positive), metres.
    pub expect_cpa_vertical_m: Option<f64>,
    /// When it happens, seconds after the start.
    pub expect_cpa_t_s: Option<f64>,
    /// Whether the encounter was built to be an NMAC.
    pub expect_nmac: Option<bool>,
    /// A model encounter's time of closest approach by construction, seconds after the start.
    pub tca_s: Option<f64>,
    /// Its horizontal miss distance at that time, metres.
    pub hmd_at_tca_m: Option<f64>,
    /// Its vertical miss distance then (intruder above positive), metres.
    pub vmd_at_tca_m: Option<f64>,
    /// The well-clear volume losses are judged with: `small-uas` (default: 2000 ft, 250 ft),
    /// `phase-1`, `phase-2`, `non-coop` (DO-365), `DTHR_M,ZTHR_M,TTHR_S,TCOA_S`, or `none`
    /// (not judged: `lowc` false and its other columns empty).
    pub well_clear: Option<String>,
    /// The variant the row flies (`nominal`, `mitigated`...): `batch summarize` compares
    /// variants over the rows of one `pair`.
    pub variant: Option<String>,
    /// The encounter the row is one variant of.
    pub pair: Option<String>,
    /// The encounter's importance weight (default 1).
    pub w: Option<f64>,
    /// A DAIDALUS state file (`.daa`) flown as an encounter: its first aircraft the ownship,
    /// every other an intruder. (The columns after `expect_nmac` came later: a CSV written
    /// with the earlier ones still reads.)
    pub daa: Option<String>,
    /// The ownship's surveillance (and navigation) devices, as `--sensors`: its DAA system
    /// alerts on the intruders as they report them (with `daa_conf`).
    pub sensors: Option<String>,
    /// The seed of the sensors' errors (default: made from `seed` and the row's `pair`, else
    /// its id: [`crate::runs::seeds`]).
    pub sensor_seed: Option<u64>,
    /// A DAIDALUS configuration (`.conf`): the alert levels raised on the sensed states
    /// (`sensors`; exact states without).
    pub daa_conf: Option<String>,
    /// Write the sensed states here as a DAIDALUS state file (with `daa_conf`).
    pub sensed_daa: Option<String>,
    /// A generator's seed, carried to the results; the base the row's sensor errors are drawn
    /// from when it has no `sensor_seed` (default 1).
    pub seed: Option<u64>,
}

impl Run {
    /// The run's id: its own, or `run-<index>`.
    pub fn id_or(&self, index: usize) -> String {
        self.id.clone().unwrap_or_else(|| format!("run-{index}"))
    }

    /// The encounter the run is a variant of: its `pair`, else its id.
    pub fn pair_or(&self, index: usize) -> String {
        self.pair.clone().unwrap_or_else(|| self.id_or(index))
    }

    /// The seed of the run's sensor errors: its `sensor_seed`, else one made from its `seed`
    /// and its encounter ([`crate::runs::seeds`]).
    ///
    /// ```
    /// use savsim::batch::manifest::Run;
    /// let run = |id: &str, pair: Option<&str>| Run {
    ///     id: Some(id.into()), pair: pair.map(Into::into), ..Run::default()
    /// };
    /// // Two variants of pair p share one; runs without a pair draw by their ids.
    /// assert_eq!(run("a", Some("p")).sensor_seed_or(0), run("b", Some("p")).sensor_seed_or(1));
    /// assert_ne!(run("a", None).sensor_seed_or(0), run("b", None).sensor_seed_or(1));
    /// ```
    pub fn sensor_seed_or(&self, index: usize) -> u64 {
        crate::runs::seeds::sensor_seed(self.sensor_seed, self.seed, &self.pair_or(index))
    }

    /// The same run with its file paths made relative to `base` (a manifest's directory).
    /// A waypoint track is left as it is.
    pub fn anchored(mut self, base: &Path) -> Self {
        let anchor = |p: &mut Option<String>| {
            if let Some(path) = p.as_mut().filter(|p| !p.is_empty()) {
                if Path::new(path.as_str()).is_relative() {
                    *path = base.join(&*path).to_string_lossy().into_owned();
                }
            }
        };
        anchor(&mut self.tlog);
        anchor(&mut self.daa);
        anchor(&mut self.scene);
        anchor(&mut self.daa_conf);
        anchor(&mut self.sensed_daa);
        for track in [&mut self.own, &mut self.intruder] {
            if track
                .as_deref()
                .is_some_and(|t| is_tlog_path(t) || crate::batch::trajectory::is_trajectory_path(t))
            {
                anchor(track);
            }
        }
        self
    }
}

/// Whether a track is given as a tlog path (rather than waypoints).
pub fn is_tlog_path(track: &str) -> bool {
    track.trim_end().to_ascii_lowercase().ends_with(".tlog")
}

/// Read a manifest file (`.csv`, `.toml` or `.json` by its extension); paths in it become
/// relative to its directory.
pub fn load(path: &Path) -> Result<Vec<Run>> {
    let (runs, base) = crate::runs::manifest::read_rows::<Run>(path)?;
    Ok(runs.into_iter().map(|r| r.anchored(&base)).collect())
}

/// Runs from CSV with a header row; an empty cell is an absent value.
pub fn parse_csv(bytes: &[u8]) -> std::result::Result<Vec<Run>, csv::Error> {
    crate::runs::manifest::csv_rows(bytes)
}

/// Runs from a JSON array of objects (what the Python package sends).
pub fn parse_json(text: &str) -> std::result::Result<Vec<Run>, serde_json::Error> {
    serde_json::from_str(text)
}

/// Write runs as CSV (what `gen-encounters` writes).
pub fn write_csv(runs: &[Run], out: impl std::io::Write) -> std::result::Result<(), csv::Error> {
    crate::runs::manifest::write_csv(runs, out)
}

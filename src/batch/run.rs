//! Running one row of a manifest: a tlog replayed over its scene, or an encounter flown; any
//! failure (a bad path, scene, mode or track, even a bug) becomes the row's `error`.

use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use crate::batch::encounter::{self, Encounter};
use crate::batch::error::{RowError, TrackError};
use crate::batch::manifest::{is_tlog_path, Run};
use crate::batch::row::RunRow;
use crate::batch::trajectory::{is_trajectory_path, track_from_trajectory};
use crate::codec::stats::IngestStats;
use crate::daa::approach::Approaches;
use crate::daa::well_clear::Volume;
use crate::pipeline::{CollisionConfig, Mode, Pipeline};
use crate::replay::{replay, Speed};
use crate::runs::scenes::SceneCache;
use crate::scene::{Kind, Scene, Waypoint};
use crate::session::Session;
use savsim_core::bounds::{positive, MAX_DURATION_S, MAX_RATE_HZ, MAX_SAMPLES};

/// Default ownship sample rate of an encounter, Hz.
pub const DEFAULT_RATE_HZ: f64 = 10.0;

/// Every scene a manifest names, each loaded once and shared by its runs (a scene that does
/// not load is kept as its error, for its rows), and each scene's pipeline per mode, built by
/// the first run that needs it: every run flies a clone, sharing its octree's build, exact
/// shapes and meshes.
pub struct Scenes {
    scenes: SceneCache,
    /// One pipeline per scene and mode, built once by the first row that needs it (the map's
    /// lock is held only to find the cell; rows of other scenes build theirs meanwhile).
    pipelines: Mutex<HashMap<(String, Mode), PipelineCell>>,
}

/// A pipeline built once, on first use.
type PipelineCell = Arc<OnceLock<Pipeline>>;

impl Scenes {
    /// Load the scenes of `runs`.
    pub fn for_runs(runs: &[Run]) -> Self {
        Self {
            scenes: SceneCache::load(runs.iter().filter_map(|r| r.scene.as_deref())),
            pipelines: Mutex::new(HashMap::new()),
        }
    }

    /// A pipeline for `scene` (the one at `path`) in `config`, as new: a clone of the one built
    /// for that scene and mode.
    fn pipeline(&self, path: Option<&str>, scene: &Scene, config: CollisionConfig) -> Pipeline {
        let key = (path.unwrap_or_default().to_owned(), config.mode);
        let cell = {
            let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
            pipelines.entry(key).or_default().clone()
        };
        cell.get_or_init(|| Pipeline::new(scene, config)).clone()
    }

    fn get(&self, path: Option<&str>) -> Result<Arc<Scene>, RowError> {
        self.scenes.get(path).map_err(RowError::Scene)
    }
}

/// The mode a row asks for (`exact` when it says nothing).
pub(crate) fn mode_of(run: &Run) -> Result<Mode, RowError> {
    match run.mode.as_deref().filter(|m| !m.is_empty()) {
        None => Ok(Mode::Exact),
        Some(m) => Mode::from_name(m).ok_or_else(|| RowError::Mode(m.to_owned())),
    }
}

/// Run row `index` of a manifest.
pub fn run_one(index: usize, run: &Run, scenes: &Scenes) -> RunRow {
    let started = Instant::now();
    let mode = mode_of(run);
    let mut row = RunRow::of_inputs(
        index,
        run,
        mode.as_ref()
            .map_or(run.mode.as_deref().unwrap_or(""), |m| m.name()),
    );
    let outcome = mode.and_then(|mode| {
        std::panic::catch_unwind(AssertUnwindSafe(|| execute(run, mode, scenes, &mut row)))
            .unwrap_or_else(|panic| Err(RowError::Internal(crate::runs::panic_message(&*panic))))
    });
    if let Err(e) = outcome {
        // Nothing half-done stays in a failed row: its inputs and the error.
        row = RunRow {
            error: Some(e.to_string()),
            ..RunRow::of_inputs(index, run, &row.mode)
        };
    }
    row.wall_s = started.elapsed().as_secs_f64();
    row
}

fn execute(run: &Run, mode: Mode, scenes: &Scenes, row: &mut RunRow) -> Result<(), RowError> {
    let (scene, pipeline, flight) = prepare(run, mode, scenes, row)?;
    match flight {
        Flight::Tlog(path) => replay_tlog(&path, scene, pipeline, well_clear(run)?, row),
        Flight::Encounter(encounter) => fly_encounter(run, &scene, pipeline, &encounter, row),
    }
}

/// What a row flies: a tlog replayed, or an encounter's tracks.
pub enum Flight {
    /// A tlog, replayed as fast as it reads.
    Tlog(std::path::PathBuf),
    /// An ownship track and its intruders, sampled.
    Encounter(Encounter),
}

/// A row checked and made ready to fly: its scene, a pipeline in its mode, what it flies
/// (what reading its tracks cost is counted in `row`).
pub(crate) fn prepare(
    run: &Run,
    mode: Mode,
    scenes: &Scenes,
    row: &mut RunRow,
) -> Result<(Arc<Scene>, Pipeline, Flight), RowError> {
    if let Some(w) = run.w {
        savsim_core::bounds::within("w", w, 0.0, 1e300)?;
    }
    let scene = scenes.get(run.scene.as_deref())?;
    let config = CollisionConfig {
        mode,
        ..CollisionConfig::default()
    };
    let pipeline = scenes.pipeline(run.scene.as_deref(), &scene, config);
    let flight = match (&run.tlog, &run.own, &run.intruder, &run.daa) {
        (Some(tlog), None, None, None) => Flight::Tlog(Path::new(tlog).to_path_buf()),
        (None, Some(own), Some(intruder), None) => {
            let mut stats = IngestStats::default();
            let own = track(own, &scene, &mut stats).map_err(RowError::Own)?;
            let intruder = track(intruder, &scene, &mut stats).map_err(RowError::Intruder)?;
            row.record_ingest(&stats);
            let intruders = vec![(Arc::from("intruder"), intruder)];
            Flight::Encounter(encounter_of(run, own, intruders)?)
        }
        (None, None, None, Some(daa)) => {
            let tracks = encounter::tracks_from_daa(Path::new(daa), &scene)?;
            Flight::Encounter(encounter_of(run, tracks.own, tracks.intruders)?)
        }
        _ => return Err(RowError::Columns),
    };
    Ok((scene, pipeline, flight))
}

/// An encounter row's flight: its length, rate, intruder kind and well-clear volume from the
/// row.
fn encounter_of(
    run: &Run,
    own: Vec<Waypoint>,
    intruders: Vec<(Arc<str>, Vec<Waypoint>)>,
) -> Result<Encounter, RowError> {
    let duration_s = match run.duration_s {
        Some(d) => positive("duration_s", d, MAX_DURATION_S)?,
        None => own.last().map_or(0.0, |w| w.t_s),
    };
    let rate_hz = positive(
        "rate_hz",
        run.rate_hz.unwrap_or(DEFAULT_RATE_HZ),
        MAX_RATE_HZ,
    )?;
    if duration_s * rate_hz > MAX_SAMPLES {
        return Err(RowError::TooManySamples {
            duration_s,
            rate_hz,
        });
    }
    Ok(Encounter {
        own,
        intruders,
        intruder_kind: match run.intruder_kind.as_deref().filter(|k| !k.is_empty()) {
            None => Kind::Dji,
            Some(k) => Kind::from_name(k).ok_or_else(|| RowError::IntruderKind(k.to_owned()))?,
        },
        rate_hz,
        duration_s,
        well_clear: well_clear(run)?,
    })
}

/// Fly an encounter row, with its sensed DAA system when it names one.
fn fly_encounter(
    run: &Run,
    scene: &Scene,
    pipeline: Pipeline,
    encounter: &Encounter,
    row: &mut RunRow,
) -> Result<(), RowError> {
    let mut sensed = sensed_daa(run, row.sensor_seed, scene)?;
    let flown = encounter::fly(scene, pipeline, encounter, &mut sensed);
    row.record_run(
        flown.pipeline.totals(),
        &flown.digest,
        &flown.approaches,
        &flown.tick_costs,
        0.0,
    );
    if let Some(daa) = sensed {
        let (found, file) = daa.finish();
        row.sensed = Some(found);
        if let (Some(text), Some(path)) = (file, run.sensed_daa.as_deref()) {
            std::fs::write(path, text).map_err(|source| RowError::SensedFile {
                path: path.to_owned(),
                source,
            })?;
        }
    }
    Ok(())
}

/// The row's DAA system on sensed states, when it names a `daa_conf`: its devices (`ideal`:
/// exact ADS-B), their errors drawn with `sensor_seed`.
fn sensed_daa(run: &Run, sensor_seed: u64, scene: &Scene) -> Result<encounter::Sensed, RowError> {
    let Some(conf) = run.daa_conf.as_deref().filter(|c| !c.is_empty()) else {
        return Ok(None);
    };
    let path = || conf.to_owned();
    let text = crate::files::read_text(Path::new(conf), 1 << 20).map_err(|source| {
        RowError::DaaConfRead {
            path: path(),
            source,
        }
    })?;
    let config = crate::daa::conf::Config::parse(&text).map_err(|source| RowError::DaaConf {
        path: path(),
        source,
    })?;
    let suite = crate::feed::sensors_for(run.sensors.as_deref(), Some(scene))?;
    let devices = match suite {
        crate::sensors::suite::Suite::Ideal => {
            crate::sensors::suite::Suite::parse("ideal-adsb", |_| Err(String::new()))?
                .devices()
                .to_vec()
        }
        s => s.devices().to_vec(),
    };
    Ok(Some(crate::batch::sensed::SensedDaa::new(
        config,
        &devices,
        sensor_seed,
        run.sensed_daa.is_some(),
    )))
}

/// A track given as waypoints, a tlog path or a trajectory file.
fn track(text: &str, scene: &Scene, stats: &mut IngestStats) -> Result<Vec<Waypoint>, TrackError> {
    let track = if is_tlog_path(text) {
        let (track, tlog_stats) = encounter::track_from_tlog(Path::new(text.trim()), scene)?;
        stats.merge(&tlog_stats);
        track
    } else if is_trajectory_path(text) {
        track_from_trajectory(Path::new(text.trim()), scene)?
    } else {
        crate::runs::waypoints::parse_waypoints(text)?
    };
    if track.is_empty() {
        return Err(TrackError::Empty);
    }
    Ok(track)
}

/// The row's well-clear volume (small UAS when it names none; `None` for `none`).
pub(crate) fn well_clear(run: &Run) -> Result<Option<Volume>, RowError> {
    let name = run
        .well_clear
        .as_deref()
        .map(str::trim)
        .filter(|w| !w.is_empty());
    crate::daa::well_clear::setting(name.unwrap_or("small-uas"))
        .ok_or_else(|| RowError::WellClear(name.unwrap_or("").to_owned()))
}

fn replay_tlog(
    path: &Path,
    scene: Arc<Scene>,
    pipeline: Pipeline,
    volume: Option<Volume>,
    row: &mut RunRow,
) -> Result<(), RowError> {
    let mut session = Session::with_pipeline(scene, pipeline, None)?;
    session.set_approaches(Approaches::with_volume(volume));
    let never = AtomicBool::new(false);
    replay(path, Speed::Max, false, None, &mut session, &never)?;
    session.finish()?;
    let t0_s = session.stats().time_span_s.map_or(0.0, |(first, _)| first);
    row.record_ingest(session.stats());
    if let Some(p) = session.pipeline() {
        row.record_run(
            p.totals(),
            session.digest(),
            session.approaches(),
            session.tick_costs(),
            t0_s,
        );
    }
    Ok(())
}

//! A row's session: its scene (with the scripted intruder), on the first vehicle's clock,
//! small-UAS well clear, the feed from the row's sensors, recorded when asked; run on a thread
//! of its own through the live runner, stopped whatever way the row ends.

use super::check::Checked;
use super::{input, RowError, Setup, FEED_HZ};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::daa::approach::Approaches;
use crate::daa::well_clear::Volume;
use crate::feed::{FeedConfig, FeedKinds};
use crate::geo::{Geodetic, LocalTangentPlane};
use crate::links::sockets::Link;
use crate::live::{run_links, LiveOptions, LiveRun};
use crate::pipeline::CollisionConfig;
use crate::scene::Scene;
use crate::session::Session;
use crate::study::manifest::StudyRow;
use crate::study::result::StudyResult;
use crate::world::SenderId;

/// The session for a row: its scene, on the vehicle's clock, small-UAS well clear, its feed
/// from its sensors, their errors drawn with `sensor_seed`.
pub(super) fn session_for(
    row: &StudyRow,
    sensor_seed: u64,
    scene: Arc<Scene>,
    feed: Option<FeedKinds>,
    own: SenderId,
) -> Result<Session, RowError> {
    let sensors = crate::feed::sensors_for(row.sensors.as_deref(), Some(&scene))
        .map_err(|e| input("sensors", e.to_string()))?;
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None)?;
    // The row's clock is its first vehicle's; the others' are mapped onto it.
    session.use_vehicle_clock_of(Some(own.system_id));
    session.set_approaches(Approaches::with_volume(Some(Volume::SMALL_UAS)));
    if let Some(kinds) = feed {
        session.start_feed(FeedConfig {
            kinds,
            hz: FEED_HZ,
            sensors,
            sensor_seed,
            ..FeedConfig::default()
        })?;
    }
    Ok(session)
}

/// The file in a row's folder its recording is written to while it flies.
pub const RECORDING: &str = "row.rrd";

/// The row's folder under the study's work folder; its session recorded there when the study
/// records this row.
pub(super) fn row_folder(
    session: &mut Session,
    setup: &Setup,
    result: &StudyResult,
) -> Result<PathBuf, RowError> {
    let dir = setup
        .work
        .join(crate::runs::row_name(result.index, &result.row_id));
    let records = setup.record_rows.as_ref();
    if records.is_some_and(|c| c.records(&result.row_id)) {
        record_to(session, &dir)?;
    }
    Ok(dir)
}

/// Record the row's session for the rerun viewer, to [`RECORDING`] in `dir` (made).
fn record_to(session: &mut Session, dir: &Path) -> Result<(), RowError> {
    std::fs::create_dir_all(dir).map_err(|source| RowError::Folder {
        path: dir.to_path_buf(),
        source,
    })?;
    Ok(crate::runs::recordings::record_to(
        session,
        &dir.join(RECORDING),
    )?)
}

/// The row's scene, with its intruder as a scripted track `intruder`.
pub(super) fn scene_for(
    row: &StudyRow,
    checked: &Checked,
    setup: &Setup,
) -> Result<Arc<Scene>, RowError> {
    let scene = setup.scene(row.scene.as_deref())?;
    let Some((kind, waypoints)) = &checked.intruder else {
        return Ok(scene);
    };
    let mut with = (*scene).clone();
    if !with.push_track("intruder", *kind, waypoints.clone()) {
        return Err(input(
            "intruder",
            "the scene has a track named intruder already",
        ));
    }
    Ok(Arc::new(with))
}

/// Home: `en_m` east and north of the scene's origin, on its ground there.
pub fn home_of(scene: &Scene, [e_m, n_m]: [f64; 2]) -> Geodetic {
    let ground_m = scene.ground_height_enu_m(e_m, n_m).unwrap_or(0.0);
    LocalTangentPlane::new(scene.origin).geodetic_from_enu_m(glam::DVec3::new(e_m, n_m, ground_m))
}

/// A row's session on its own thread (with the row's network runtime), stopped and joined
/// when dropped: no exit from a row leaves the thread, its runtime or its socket behind.
pub(super) struct SessionThread {
    pub(super) thread: Option<std::thread::JoinHandle<crate::error::Result<LiveRun>>>,
    pub(super) shutdown: Arc<AtomicBool>,
}

impl SessionThread {
    pub(super) fn spawn(
        runtime: tokio::runtime::Runtime,
        links: Vec<Link>,
        options: LiveOptions,
        session: Session,
    ) -> Result<Self, RowError> {
        let shutdown = Arc::new(AtomicBool::new(false));
        let thread = {
            let shutdown = shutdown.clone();
            std::thread::Builder::new()
                .name("savsim-study-session".into())
                .spawn(move || {
                    let handle = runtime.handle().clone();
                    let run = run_links(&handle, links, &options, session, None, shutdown);
                    drop(runtime);
                    run
                })
                .map_err(|_| RowError::SessionThread)?
        };
        Ok(Self {
            thread: Some(thread),
            shutdown,
        })
    }

    /// Stop the session and take its run.
    pub(super) fn finish(mut self) -> Result<LiveRun, RowError> {
        self.shutdown.store(true, Ordering::Relaxed);
        let run = self.thread.take().ok_or(RowError::SessionThread)?.join();
        Ok(run.map_err(|_| RowError::SessionThread)??)
    }
}

impl Drop for SessionThread {
    fn drop(&mut self) {
        self.shutdown.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

//! Figures drawn from a run (closest approaches, the first collision, outcomes) come from every
//! event, never from a capped list of them: the session keeps the first 1000 notable events
//! for its printed report and counts the rest.

use glam::DVec3;
use savsim::batch::manifest::Run;
use savsim::batch::row::RunRow;
use savsim::collision::events::EventKind;
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use savsim::study::manifest::StudyRow;
use savsim::study::result::StudyResult;

use crate::common::{feed, position_frames, scene_at};

/// 1200 passes 3 m from a building's west face, then one at 1 m: the closest near miss is the
/// last, past the 1000 events the session keeps for its report.
#[test]
fn the_closest_near_miss_past_the_first_thousand_events_is_reported() {
    let origin = Geodetic {
        lat_deg: 47.0,
        lon_deg: 8.0,
        alt_m: 400.0,
    };
    let scene = scene_at(
        origin,
        "[[obstacle]]\nid = \"block\"\nkind = \"building\"\nshape = { box = [10.0, 10.0, 10.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    let plane = LocalTangentPlane::new(origin);
    let mut session = Session::new(
        Some(std::sync::Arc::new(scene)),
        CollisionConfig::default(),
        None,
    )
    .unwrap();
    let (mut seq, mut t_ms) = (0u8, 1000u32);
    let mut at = |session: &mut Session, x_m: f64| {
        let frames = position_frames(
            &plane,
            1,
            &mut seq,
            t_ms,
            DVec3::new(x_m, 0.0, 5.0),
            DVec3::ZERO,
        );
        feed(session, f64::from(t_ms) / 1000.0, &frames);
        t_ms += 1000;
    };
    for _ in 0..1200 {
        at(&mut session, -25.0);
        at(&mut session, -8.0);
    }
    at(&mut session, -25.0);
    at(&mut session, -6.0);
    at(&mut session, -25.0);
    session.finish().unwrap();

    let kept_min = session
        .notable()
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::NearMiss { closest_m, .. } => Some(*closest_m),
            _ => None,
        })
        .fold(f64::INFINITY, f64::min);
    let digest = session.digest();
    assert_eq!(session.notable().len(), 1000);
    assert_eq!(session.notable_not_kept(), 201);
    assert_eq!(digest.near_misses(), 1201);
    let closest = digest.closest_near_miss_m().unwrap();
    assert!(
        closest < kept_min - 1.5,
        "closest {closest} m, the kept events' {kept_min} m"
    );
    assert_eq!(digest.closest_m("block"), Some(closest));

    // A batch row and a study row read their figures from the digest.
    let p = session.pipeline().unwrap();
    let mut row = RunRow::of_inputs(0, &Run::default(), "exact");
    row.record_run(
        p.totals(),
        digest,
        session.approaches(),
        session.tick_costs(),
        0.0,
    );
    assert_eq!(row.measured.closest_near_miss_m, Some(closest));
    let mut result = StudyResult::of_inputs(0, &StudyRow::default());
    result.record_obstacles(digest);
    assert_eq!(result.closest_obstacle_m, Some(closest));
}

/// A batch shard's file says how it was made: savsim's version, the command, the manifest, the
/// shard and the jobs, as a study's does.
#[test]
fn a_batch_shard_carries_savsims_version_and_its_settings() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(
        &manifest,
        "id,own,intruder\na,0 0 0 50; 60 600 0 50,0 600 0 50; 60 0 0 50\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let ran = crate::cli::savsim()
        .args(["batch", "--jobs", "1", "--shard", "0/1", "--out"])
        .arg(&out)
        .arg(&manifest)
        .output()
        .unwrap();
    crate::common::assert_ran(&ran);
    let settings =
        savsim::runs::table::read_settings(&out.join("part-00000-of-00001.parquet")).unwrap();
    let get = |k: &str| {
        settings
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.as_str())
    };
    assert_eq!(get("savsim_version"), Some(env!("CARGO_PKG_VERSION")));
    assert_eq!(get("command"), Some("batch"));
    assert_eq!(get("manifest"), manifest.to_str());
    assert_eq!(get("shard"), Some("0/1"));
    assert_eq!(get("jobs"), Some("1"));
}

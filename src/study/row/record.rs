//! A flown row's result: what each vehicle did (its modes, avoidance, track, clock), scored
//! with what savsim measured.

use super::check::Flier;
use super::RowError;
use std::path::Path;

/// What one vehicle flew: how far, what it said, and the row's clock less its own (s).
pub(super) type FlownBy = (Flown, Heard, f64);

use crate::codec::notes::{arducopter_mode_name, px4_mode_name};
use crate::live::LiveRun;
use crate::session::Session;
use crate::study::pilot::fly::Flown;
use crate::study::pilot::heard::Heard;
use crate::study::pilot::mode;
use crate::study::result::{AutopilotDid, StudyResult, VehicleResult};
use crate::world::SenderId;

/// A vehicle's part of the row after its first (`by`: what it flew and heard, and the row's
/// clock less its own).
pub(super) fn record_other(
    result: &mut StudyResult,
    session: &Session,
    id: SenderId,
    (flown, heard, offset_s): &FlownBy,
    flier: &Flier,
) {
    let mut did = did(heard, flown, flier.px4);
    did.first_acted_t_s = did.first_acted_t_s.map(|t| t + offset_s);
    let seen = session.world().seen.get(&id);
    result.others.push(VehicleResult {
        role: crate::study::result::role(result.others.len() + 1),
        system_id: id.system_id,
        autopilot: if flier.px4 { "px4" } else { "arducopter" }.into(),
        track: heard.track_text_shifted(*offset_s),
        legs_completed: flown.legs_completed as u64,
        plan_completed: flown.legs_completed == flier.legs.len(),
        did,
        clock_speedup: seen.map_or(0.0, |s| s.clock_speedup),
        clock_skew_s: seen.map_or(0.0, |s| s.clock_skew_s),
        estimate: None,
    });
}

/// In a row of several: the first vehicle's clock's speedup, and the largest skew of another's
/// from it.
pub(super) fn record_clocks(result: &mut StudyResult, session: &Session) {
    if result.others.is_empty() {
        return;
    }
    let world = session.world();
    result.clock_speedup = world
        .timeline_reference()
        .and_then(|r| world.seen.get(&r))
        .map(|s| s.clock_speedup);
    result.clock_skew_s = result
        .others
        .iter()
        .map(|o| o.clock_skew_s)
        .reduce(f64::max);
}

/// What a live run adds to a row: its ending and the feed's latency.
pub(super) fn record_live(result: &mut StudyResult, run: &mut LiveRun) -> Result<(), RowError> {
    match std::mem::replace(&mut run.ended, Ok(())) {
        Err(crate::error::Error::Companion(e)) => return Err(RowError::Planner(e)),
        ended => ended?,
    }
    let feed_latency = run.report.feed.as_ref().and_then(|f| f.latency);
    result.feed_latency_p99_us = feed_latency.map(|l| l.p99_us);
    result.feed_latency_max_us = feed_latency.map(|l| l.max_us);
    Ok(())
}

/// Fill in what the session measured and what the autopilot did.
pub(super) fn record(
    result: &mut StudyResult,
    dir: &Path,
    session: &mut Session,
    (flown, heard): (&Flown, &Heard),
    px4: bool,
    legs: usize,
) -> Result<(), RowError> {
    session.finish()?;
    let session = &*session;
    // The session's own summary beside SITL's files (kept with --keep-work).
    let _ = crate::session::write_json_atomic(
        &dir.join("summary.json"),
        &session.summary("study", &result.row_id),
    );
    if let Some(pipeline) = session.pipeline() {
        let t0_s = -session.elapsed_s(0.0).unwrap_or(0.0);
        result.measured.record(
            pipeline.totals(),
            session.digest(),
            session.approaches(),
            t0_s,
        );
    }
    result.record_obstacles(session.digest());
    result.feed_frames = session
        .feed()
        .map_or(0, |f| f.counts().map(|(_, c)| c.frames).sum());
    if let Some(feed) = session.feed() {
        result.told = feed
            .told()
            .fold(crate::feed::Told::default(), |all, (_, _, t)| all.and(&t));
    }
    result.armed_t_s = flown.armed_t_s;
    result.legs_completed = flown.legs_completed as u64;
    result.plan_completed = flown.legs_completed == legs;
    result.sim_s = f64::from(flown.last_ms) / 1000.0;
    result.autopilot_did = did(heard, flown, px4);
    result.track = heard.track_text();
    Ok(())
}

/// What the autopilot did, from what it said.
pub(super) fn did(heard: &Heard, flown: &Flown, px4: bool) -> AutopilotDid {
    let since = |ms: u32| f64::from(ms) / 1000.0;
    // ArduCopter's AVOID_ADSB; PX4's traffic avoidance's return or land.
    let avoid_mode = heard
        .modes
        .iter()
        .find(|(_, m)| {
            if px4 {
                crate::study::pilot::fly::px4_avoiding(*m)
            } else {
                *m == mode::AVOID_ADSB
            }
        })
        .map(|(t, _)| since(*t));
    let collision = heard.first_collision_ms.map(since);
    let first_acted_t_s = [avoid_mode, collision, flown.slowed_t_s]
        .into_iter()
        .flatten()
        .reduce(f64::min);
    AutopilotDid {
        modes: heard
            .modes
            .iter()
            .map(|(_, m)| {
                if px4 {
                    px4_mode_name(*m)
                } else {
                    arducopter_mode_name(*m)
                }
            })
            .collect(),
        collision_messages: heard.collision_messages,
        avoidance_texts: heard.avoidance_texts.clone(),
        avoidance_texts_not_kept: heard.avoidance_texts_not_kept,
        first_acted_t_s,
        version: heard.version.clone(),
    }
}

//! A row's columns checked before anything starts: its autopilot, speedup, duration, feed,
//! plan, parameters, intruder, and the vehicles after its first (each one's plan, parameters
//! and home, one entry each or one for all). A bad column is the row's error, naming it.

use super::ids::{arducopter_sysid, MAX_VEHICLES};
use super::{input, RowError, DEFAULT_DURATION_S, SPEEDUP_RANGE};
use crate::companion::slot::CompanionConfig;
use crate::feed::FeedKinds;
use crate::scene::{Kind, Waypoint};
use crate::study::manifest::StudyRow;
use crate::study::plan::{self, Leg};
use savsim_core::bounds::{MAX_DURATION_S, MAX_ENU_M};

/// One vehicle of a row: its autopilot, plan and parameters, checked.
#[derive(Debug, Clone)]
pub(super) struct Flier {
    pub(super) px4: bool,
    pub(super) legs: Vec<Leg>,
    pub(super) params: Vec<(String, f64)>,
    /// Home, scene ENU metres east and north (on the scene's ground there).
    pub(super) home_en_m: [f64; 2],
}

/// A row's columns, checked.
pub(super) struct Checked {
    pub(super) own: Flier,
    /// The vehicles after the first, in the manifest's order.
    pub(super) others: Vec<Flier>,
    pub(super) feed: Option<FeedKinds>,
    pub(super) intruder: Option<(Kind, Vec<Waypoint>)>,
    pub(super) duration_s: f64,
    pub(super) speedup: f64,
    pub(super) stop_on_collision: bool,
}

/// Whether `name` (of `column`) is PX4.
pub(super) fn is_px4(column: &'static str, name: &str) -> Result<bool, RowError> {
    match name {
        "arducopter" => Ok(false),
        "px4" => Ok(true),
        other => Err(input(column, format!("{other:?}: give arducopter or px4"))),
    }
}

/// The row's vehicles after its first (`intruder_autopilot` and its columns): one for each
/// name in `intruder_autopilot`, separated by `|` (`arducopter|px4`); `intruder_plan`,
/// `intruder_params` and `intruder_home` give one entry for every vehicle, or one for all.
pub(super) fn check_others(row: &StudyRow) -> Result<Vec<Flier>, RowError> {
    fn given(v: &Option<String>) -> Option<&str> {
        v.as_deref().filter(|t| !t.trim().is_empty())
    }
    let Some(autopilots) = given(&row.intruder_autopilot) else {
        if given(&row.intruder_plan).is_some() || given(&row.intruder_params).is_some() {
            return Err(input(
                "intruder_autopilot",
                "intruder_plan and intruder_params are for a second autopilot: name it",
            ));
        }
        return Ok(Vec::new());
    };
    if given(&row.intruder).is_some() {
        return Err(input(
            "intruder_autopilot",
            "give a scripted intruder or an autopilot, not both",
        ));
    }
    let autopilots: Vec<&str> = autopilots.split('|').map(str::trim).collect();
    if autopilots.len() >= MAX_VEHICLES {
        return Err(input(
            "intruder_autopilot",
            format!(
                "{} vehicles after the first: a row flies at most {MAX_VEHICLES} in all",
                autopilots.len()
            ),
        ));
    }
    let n = autopilots.len();
    let plans = per_vehicle("intruder_plan", given(&row.intruder_plan), n)?;
    let params = per_vehicle("intruder_params", given(&row.intruder_params), n)?;
    let homes = per_vehicle("intruder_home", given(&row.intruder_home), n)?;
    let mut others = Vec::with_capacity(n);
    for (k, autopilot) in autopilots.into_iter().enumerate() {
        others.push(check_other(
            k + 1,
            autopilot,
            [plans[k], params[k], homes[k]],
        )?);
    }
    Ok(others)
}

/// A column's entries for `n` vehicles: none given (each `""`), one for all, or one each
/// (separated by `|`).
pub(super) fn per_vehicle<'a>(
    column: &'static str,
    text: Option<&'a str>,
    n: usize,
) -> Result<Vec<&'a str>, RowError> {
    let Some(text) = text else {
        return Ok(vec![""; n]);
    };
    let entries: Vec<&str> = text.split('|').map(str::trim).collect();
    match entries.len() {
        1 => Ok(vec![entries[0]; n]),
        k if k == n => Ok(entries),
        k => Err(input(
            column,
            format!("{k} entries for {n} vehicles: give one for all, or one each, separated by |"),
        )),
    }
}

/// The row's vehicle `k` (from 1) after its first: `autopilot`, and its plan, parameters and
/// home as given.
pub(super) fn check_other(
    k: usize,
    autopilot: &str,
    [plan_text, params_text, home]: [&str; 3],
) -> Result<Flier, RowError> {
    let px4 = is_px4("intruder_autopilot", autopilot)?;
    let legs = plan::parse(plan_text).map_err(|e| input("intruder_plan", e.to_string()))?;
    let mut params = plan::parse_params(params_text).map_err(|source| RowError::Params {
        column: "intruder_params",
        source,
    })?;
    if !px4 {
        // Last, so that it holds over the row's own: the session tells the vehicles apart by it.
        params.push(("SYSID_THISMAV".into(), f64::from(arducopter_sysid(k))));
    }
    let home_en_m = match home {
        "" => [0.0, 0.0],
        text => parse_home(text).map_err(|source| RowError::Home {
            column: "intruder_home",
            source,
        })?,
    };
    Ok(Flier {
        px4,
        legs,
        params,
        home_en_m,
    })
}

/// What is wrong with a home, as written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HomeError {
    /// Not two numbers.
    #[error("{0:?}: give E N in metres")]
    NotNumbers(String),
    /// Beyond the scene's bounds.
    #[error("{0:?}: give E N in metres, each within +/-{MAX_ENU_M}")]
    Beyond(String),
}

/// `E N`: metres east and north of the scene's origin, within the scene's bounds.
pub(super) fn parse_home(text: &str) -> Result<[f64; 2], HomeError> {
    let numbers: Vec<f64> = text
        .split_whitespace()
        .map(|w| w.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| HomeError::NotNumbers(text.to_string()))?;
    match numbers[..] {
        [e, n] if e.abs() <= MAX_ENU_M && n.abs() <= MAX_ENU_M => Ok([e, n]),
        _ => Err(HomeError::Beyond(text.to_string())),
    }
}

pub(super) fn check(row: &StudyRow, default_speedup: f64) -> Result<Checked, RowError> {
    let px4 = is_px4(
        "autopilot",
        row.autopilot.as_deref().unwrap_or("arducopter"),
    )?;
    let legs = plan::parse(row.plan.as_deref().unwrap_or_default())?;
    let params =
        plan::parse_params(row.params.as_deref().unwrap_or_default()).map_err(|source| {
            RowError::Params {
                column: "params",
                source,
            }
        })?;
    let others = check_others(row)?;
    let feed = row
        .feed
        .as_deref()
        .filter(|f| !f.trim().is_empty())
        .map(|f| FeedKinds::parse(f).map_err(|e| input("feed", format!("{f}: {e}"))))
        .transpose()?;
    let kind = match row.intruder_kind.as_deref().filter(|k| !k.is_empty()) {
        None => Kind::Dji,
        Some(k) => Kind::from_name(k).ok_or_else(|| input("intruder_kind", format!("{k:?}")))?,
    };
    let intruder = row
        .intruder
        .as_deref()
        .filter(|t| !t.trim().is_empty())
        .map(|t| {
            crate::runs::waypoints::parse_waypoints(t)
                .map_err(|why| input("intruder", why.to_string()))
        })
        .transpose()?
        .map(|w| (kind, w));
    let duration_s = row.duration_s.unwrap_or(DEFAULT_DURATION_S);
    if !(duration_s > 0.0 && duration_s <= MAX_DURATION_S) {
        return Err(input(
            "duration_s",
            format!("{duration_s}: give more than 0 and at most {MAX_DURATION_S} s"),
        ));
    }
    let speedup = row.speedup.unwrap_or(default_speedup);
    if !(SPEEDUP_RANGE.0..=SPEEDUP_RANGE.1).contains(&speedup) {
        return Err(input(
            "speedup",
            format!("{speedup}: give {} to {}", SPEEDUP_RANGE.0, SPEEDUP_RANGE.1),
        ));
    }
    if let Some(w) = row.w.filter(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(input("w", format!("{w}: give a finite weight >= 0")));
    }
    Ok(Checked {
        own: Flier {
            px4,
            legs,
            params,
            home_en_m: [0.0, 0.0],
        },
        others,
        feed,
        intruder,
        duration_s,
        speedup,
        stop_on_collision: row.stop_on_collision.unwrap_or(true),
    })
}

/// The row's companion columns, checked (none when it names no companion).
pub(super) fn check_companion(row: &StudyRow) -> Result<Option<CompanionConfig>, RowError> {
    let Some(command) = row
        .companion
        .as_deref()
        .map(str::trim)
        .filter(|c| !c.is_empty())
    else {
        for (column, set) in [
            ("companion_hz", row.companion_hz.is_some()),
            ("companion_latency_s", row.companion_latency_s.is_some()),
        ] {
            if set {
                return Err(input(column, "give a companion to go with it"));
            }
        }
        return Ok(None);
    };
    let hz = row
        .companion_hz
        .unwrap_or(crate::companion::slot::DEFAULT_HZ);
    let latency_s = row.companion_latency_s.unwrap_or(0.0);
    CompanionConfig::checked(command, hz, latency_s)
        .map(Some)
        .map_err(|(setting, why)| match setting {
            "hz" => input("companion_hz", why),
            _ => input("companion_latency_s", why),
        })
}

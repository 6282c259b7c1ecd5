//! Tracks written as text, `"t_s e_m n_m u_m; ..."` in a scene's ENU frame: an encounter's
//! ownship and intruder in a batch manifest, a study row's intruder, a study row's vehicle
//! track in its results.

use savsim_core::bounds::MAX_ENU_M;

use crate::scene::Waypoint;

/// Parse a waypoint track: `"t_s e_m n_m u_m; t_s e_m n_m u_m; ..."` (numbers separated by
/// spaces or commas), times strictly increasing.
///
/// ```
/// let w = savsim::runs::waypoints::parse_waypoints("0 0 0 100; 60, 600, 0, 100").unwrap();
/// assert_eq!(w[1].position_enu_m, [600.0, 0.0, 100.0]);
/// assert!(savsim::runs::waypoints::parse_waypoints("0 0 0").is_err());
/// ```
pub fn parse_waypoints(text: &str) -> Result<Vec<Waypoint>, WaypointError> {
    let mut out: Vec<Waypoint> = Vec::new();
    for (i, point) in text.split(';').map(str::trim).enumerate() {
        if point.is_empty() && i > 0 {
            continue;
        }
        let numbers: Vec<f64> = point
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse::<f64>().ok().filter(|v| v.abs() <= MAX_ENU_M))
            .collect::<Option<_>>()
            .ok_or_else(|| WaypointError::at(i, point, WaypointProblem::NotNumbers))?;
        let [t_s, e, n, u] = numbers[..] else {
            return Err(WaypointError::at(i, point, WaypointProblem::NotFour));
        };
        if out.last().is_some_and(|last| t_s <= last.t_s) {
            return Err(WaypointError::at(i, point, WaypointProblem::TimeNotAfter));
        }
        out.push(Waypoint {
            t_s,
            position_enu_m: [e, n, u],
        });
    }
    Ok(out)
}

/// Why a waypoint list could not be read: the waypoint (from 1), as written, and what is
/// wrong with it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("waypoint {index} {text:?}: {problem}")]
pub struct WaypointError {
    /// Which waypoint, from 1.
    pub index: usize,
    /// The waypoint as written.
    pub text: String,
    /// What is wrong.
    pub problem: WaypointProblem,
}

impl WaypointError {
    fn at(i: usize, text: &str, problem: WaypointProblem) -> Self {
        Self {
            index: i + 1,
            text: text.to_owned(),
            problem,
        }
    }
}

/// What is wrong with a waypoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum WaypointProblem {
    /// A word that is not a number, or one beyond [`MAX_ENU_M`].
    #[error("give numbers within {MAX_ENU_M:e} (seconds, metres)")]
    NotNumbers,
    /// Not four numbers.
    #[error("give four numbers, `t_s e_m n_m u_m`")]
    NotFour,
    /// A time not after the one before.
    #[error("times must increase")]
    TimeNotAfter,
}

//! A study row's flight plan: legs separated by `;`, in scene ENU metres and m/s, each flown
//! on the vehicle's own clock.
//!
//! | leg | meaning |
//! |---|---|
//! | `takeoff U` | arm and climb to `U` m above home |
//! | `goto E N U [SPEED]` | fly to (E, N, U) at `SPEED` m/s (default 5); done within 1 m |
//! | `velocity VE VN VU SECONDS` | hold that velocity for `SECONDS` of the vehicle's clock |
//! | `hold SECONDS` | stay where it is |
//! | `until T` | stay where it is until the row's clock reads `T` s (its first vehicle's clock from its boot) |
//! | `land` | land where it is; done when disarmed |
//!
//! ```
//! use savsim::study::plan::{parse, Leg};
//! let legs = parse("takeoff 30; goto 0 -30 30; velocity -5 0 0 25; land").unwrap();
//! assert_eq!(legs[0], Leg::Takeoff { up_m: 30.0 });
//! assert_eq!(legs[2], Leg::Velocity { enu_mps: [-5.0, 0.0, 0.0], seconds: 25.0 });
//! assert!(parse("goto 1 2").is_err());
//! assert!(parse("takeoff 30; jump 3").is_err());
//! ```

use savsim_core::bounds::MAX_ENU_M;

/// The default speed of a `goto`, m/s.
pub const GOTO_SPEED_MPS: f64 = 5.0;
/// The fastest speed a leg may ask for, m/s (a copter's, with room).
pub const MAX_SPEED_MPS: f64 = 50.0;
/// The longest a `velocity` or `hold` leg may last, seconds.
pub const MAX_LEG_S: f64 = 86_400.0;

/// One leg of a plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Leg {
    /// Arm (if not armed) and take off to `up_m` above home.
    Takeoff {
        /// Height above home, metres.
        up_m: f64,
    },
    /// Fly to a point.
    Goto {
        /// Where, scene ENU metres (up above home).
        enu_m: [f64; 3],
        /// How fast, m/s.
        speed_mps: f64,
    },
    /// Hold a velocity.
    Velocity {
        /// Velocity, scene ENU m/s.
        enu_mps: [f64; 3],
        /// For how long, seconds of the vehicle's clock.
        seconds: f64,
    },
    /// Stay in place.
    Hold {
        /// For how long, seconds of the vehicle's clock.
        seconds: f64,
    },
    /// Stay in place until the row's clock reads `t_s`: a leg that starts the next at the
    /// same moment for every vehicle of a row, whatever their take-off took.
    Until {
        /// Seconds of the row's clock (its first vehicle's, from its boot).
        t_s: f64,
    },
    /// Land where it is.
    Land,
}

/// Why a plan could not be read: the leg (from 1) and what is wrong with it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("plan leg {leg} {text:?}: {why}")]
pub struct PlanError {
    /// Which leg, from 1.
    pub leg: usize,
    /// The leg as written.
    pub text: String,
    /// What is wrong.
    pub why: LegError,
}

/// What is wrong with a leg.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LegError {
    /// A plan with no leg.
    #[error("no legs: give e.g. \"takeoff 30; goto 0 50 30; land\"")]
    NoLegs,
    /// A word where a number goes.
    #[error("{0:?} is not a number")]
    NotANumber(String),
    /// Too few or too many numbers: how the leg is written.
    #[error("give {0}")]
    Usage(&'static str),
    /// A coordinate or a velocity beyond its bound.
    #[error("a {what} is beyond +/-{max}")]
    Beyond {
        /// Which.
        what: &'static str,
        /// Its bound.
        max: f64,
    },
    /// A leg's time out of bounds.
    #[error("give more than 0 and at most {MAX_LEG_S} s")]
    Seconds,
    /// A takeoff out of bounds.
    #[error("take off to 1 m to {MAX_ENU_M} m above home")]
    TakeoffHeight,
    /// A goto's speed out of bounds.
    #[error("give a speed of more than 0 and at most {MAX_SPEED_MPS} m/s")]
    Speed,
    /// Not a leg's verb.
    #[error("{0:?} is not a leg: takeoff, goto, velocity, hold, until or land")]
    NotALeg(String),
}

/// What is wrong with a row's parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// No `=` or space between a name and its value.
    #[error("parameter {0:?}: give NAME=VALUE")]
    NoValue(String),
    /// A name that is not an autopilot parameter's.
    #[error("parameter {0:?}: a name is letters, digits and _, at most 16 characters")]
    BadName(String),
    /// A value that is not a number.
    #[error("parameter {0:?}: the value is not a number")]
    NotANumber(String),
}

/// Read a plan. An empty plan is an error: a row must fly something.
pub fn parse(text: &str) -> Result<Vec<Leg>, PlanError> {
    let legs: Vec<&str> = text
        .split(';')
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    if legs.is_empty() {
        return Err(PlanError {
            leg: 0,
            text: text.into(),
            why: LegError::NoLegs,
        });
    }
    legs.iter()
        .enumerate()
        .map(|(i, l)| {
            leg(l).map_err(|why| PlanError {
                leg: i + 1,
                text: (*l).into(),
                why,
            })
        })
        .collect()
}

/// One leg.
fn leg(text: &str) -> Result<Leg, LegError> {
    let mut words = text.split_whitespace();
    let verb = words.next().unwrap_or_default().to_ascii_lowercase();
    let numbers: Vec<f64> = words
        .map(|w| {
            w.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| LegError::NotANumber(w.to_string()))
        })
        .collect::<Result<_, _>>()?;
    let count = |n: &[usize], usage: &'static str| {
        if n.contains(&numbers.len()) {
            Ok(())
        } else {
            Err(LegError::Usage(usage))
        }
    };
    let within = |v: f64, max: f64, what: &'static str| {
        if v.abs() <= max {
            Ok(v)
        } else {
            Err(LegError::Beyond { what, max })
        }
    };
    let seconds = |v: f64| {
        if v > 0.0 && v <= MAX_LEG_S {
            Ok(v)
        } else {
            Err(LegError::Seconds)
        }
    };
    match verb.as_str() {
        "takeoff" => {
            count(&[1], "takeoff U (metres above home)")?;
            let up_m = numbers[0];
            if !(1.0..=MAX_ENU_M).contains(&up_m) {
                return Err(LegError::TakeoffHeight);
            }
            Ok(Leg::Takeoff { up_m })
        }
        "goto" => {
            count(&[3, 4], "goto E N U [SPEED]")?;
            let speed_mps = numbers.get(3).copied().unwrap_or(GOTO_SPEED_MPS);
            if !(speed_mps > 0.0 && speed_mps <= MAX_SPEED_MPS) {
                return Err(LegError::Speed);
            }
            let mut enu_m = [0.0; 3];
            for (axis, v) in enu_m.iter_mut().zip(&numbers) {
                *axis = within(*v, MAX_ENU_M, "coordinate (m)")?;
            }
            Ok(Leg::Goto { enu_m, speed_mps })
        }
        "velocity" => {
            count(&[4], "velocity VE VN VU SECONDS")?;
            let mut enu_mps = [0.0; 3];
            for (axis, v) in enu_mps.iter_mut().zip(&numbers) {
                *axis = within(*v, MAX_SPEED_MPS, "velocity (m/s)")?;
            }
            Ok(Leg::Velocity {
                enu_mps,
                seconds: seconds(numbers[3])?,
            })
        }
        "hold" => {
            count(&[1], "hold SECONDS")?;
            Ok(Leg::Hold {
                seconds: seconds(numbers[0])?,
            })
        }
        "until" => {
            count(&[1], "until T (seconds of the row's clock)")?;
            Ok(Leg::Until {
                t_s: seconds(numbers[0])?,
            })
        }
        "land" => {
            count(&[0], "land (no numbers)")?;
            Ok(Leg::Land)
        }
        other => Err(LegError::NotALeg(other.to_string())),
    }
}

/// A row's parameters, `NAME=VALUE;...` (`NAME VALUE` too), in order. Names are upper-cased
/// ArduPilot/PX4 names (letters, digits, `_`, at most 16 characters); values are numbers.
///
/// ```
/// let p = savsim::study::plan::parse_params("AVOID_ENABLE=3; PRX1_TYPE 2").unwrap();
/// assert_eq!(p, [("AVOID_ENABLE".to_string(), 3.0), ("PRX1_TYPE".to_string(), 2.0)]);
/// assert!(savsim::study::plan::parse_params("AVOID ENABLE=3").is_err());
/// ```
pub fn parse_params(text: &str) -> Result<Vec<(String, f64)>, ParamError> {
    text.split(';')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|p| {
            let (name, value) = p
                .split_once('=')
                .or_else(|| p.split_once(char::is_whitespace))
                .ok_or_else(|| ParamError::NoValue(p.to_string()))?;
            let name = name.trim().to_ascii_uppercase();
            let good = !name.is_empty()
                && name.len() <= 16
                && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            if !good {
                return Err(ParamError::BadName(p.to_string()));
            }
            let value = value
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| ParamError::NotANumber(p.to_string()))?;
            Ok((name, value))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_leg_reads_and_bad_ones_say_which() {
        let legs =
            parse("takeoff 30;goto 10 20 30 4; hold 5 ;velocity 0 1 0 2;until 80;land;").unwrap();
        assert_eq!(legs.len(), 6);
        assert_eq!(legs[4], Leg::Until { t_s: 80.0 });
        assert_eq!(
            legs[1],
            Leg::Goto {
                enu_m: [10.0, 20.0, 30.0],
                speed_mps: 4.0
            }
        );
        for (bad, leg) in [
            ("", 0),
            ("takeoff 0.5", 1),
            ("takeoff 30; goto 0 0 30 0", 2),
            ("hold -1", 1),
            ("hold NaN", 1),
            ("velocity 100 0 0 5", 1),
            ("land 3", 1),
            ("takeoff 30; until", 2),
            ("until -4", 1),
            ("takeoff 30; hold 1e9", 2),
        ] {
            let e = parse(bad).unwrap_err();
            assert_eq!(e.leg, leg, "{bad}: {e}");
        }
    }
}

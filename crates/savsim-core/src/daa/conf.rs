//! DAIDALUS's configuration files (`.conf`): `key = value [unit]` lines, `#` comments. What
//! savsim reads from them: the lookahead, the alerting filter (`hysteresis_time`,
//! `persistence_time`, `alerting_m`, `alerting_n`) and every alerter named in `alerters`, with
//! its levels (`<A>_alert_<k>_region`, `_alerting_time`, `_early_alerting_time`, `_detector`)
//! and their detectors (`<A>_<det>_WCV_DTHR`, `_ZTHR`, `_TTHR`, `_TCOA`, with
//! `<A>_load_core_detection_<det>` naming `WCV_TAUMOD`, or `WCV_TAUMOD_SUM` for sensor
//! uncertainty mitigation with the global z-scores `h_pos_z_score`, `h_vel_z_score_min`,
//! `h_vel_z_score_max`, `h_vel_z_distance`, `v_pos_z_score`, `v_vel_z_score`). Other keys
//! (bands, recovery) are read and left: they do not change alert levels. A detector of another
//! kind, and a per-detector z-score (which savsim does not read), are errors that name them.

use std::collections::HashMap;

use crate::daa::alerting::{Alerter, Level};
use crate::daa::units::value_si;
use crate::daa::well_clear::Volume;

/// What a configuration gives: the lookahead, the filter's parameters and the alerters.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Lookahead time, seconds.
    pub lookahead_s: f64,
    /// Hysteresis time, seconds.
    pub hysteresis_time_s: f64,
    /// Persistence time, seconds.
    pub persistence_time_s: f64,
    /// M of M-of-N alerting.
    pub alerting_m: usize,
    /// N of M-of-N alerting.
    pub alerting_n: usize,
    /// The alerters, in the order `alerters` names them (alerter 1 first).
    pub alerters: Vec<Alerter>,
    /// The z-scores of sensor uncertainty mitigation (levels whose detector is
    /// `WCV_TAUMOD_SUM`).
    pub z_scores: crate::daa::sum::ZScores,
    /// Whether an intruder's alerter is the ownship's (`ownship_centric_alerting`), not its own.
    pub ownship_centric: bool,
    /// The region from which a level is corrective (`corrective_region`; `MID` by default).
    pub corrective_region: String,
    /// The units DAIDALUS prints in: those of `min_horizontal_recovery`,
    /// `min_vertical_recovery`, `step_hs` and `step_vs` (nmi, ft, knot, fpm by default).
    pub output_units: OutputUnits,
}

/// The units of DaidalusAlerting's columns, as the configuration sets them.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputUnits {
    /// Horizontal distances.
    pub horizontal: String,
    /// Vertical distances.
    pub vertical: String,
    /// Horizontal speeds.
    pub horizontal_speed: String,
    /// Vertical speeds.
    pub vertical_speed: String,
}

/// The severity of a guidance region (`NONE` 0 ... `NEAR` 3), `None` for an unknown one.
pub fn region_severity(region: &str) -> Option<u8> {
    match region.trim().to_ascii_uppercase().as_str() {
        "NONE" | "UNKNOWN" => Some(0),
        "FAR" => Some(1),
        "MID" => Some(2),
        "NEAR" => Some(3),
        _ => None,
    }
}

/// Why a configuration could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfError {
    /// A line that is not `key = value`.
    #[error("line {line}: not `key = value`: {text:?}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// The line.
        text: String,
    },
    /// A key the alerters need is missing.
    #[error("missing key {0}")]
    Missing(String),
    /// A value that is not a number in a known unit, or out of its range.
    #[error("key {key}: bad value {value:?} (a number, optionally with a unit in brackets)")]
    Value {
        /// The key.
        key: String,
        /// Its value.
        value: String,
    },
    /// A setting savsim does not implement, set to what would change alert levels.
    #[error("key {key}: {why}")]
    Unsupported {
        /// The key.
        key: String,
        /// Why it cannot be honoured.
        why: &'static str,
    },
    /// A detector savsim does not implement.
    #[error(
        "alerter {alerter}: detector {detector} is {class}; savsim supports WCV_TAUMOD and WCV_TAUMOD_SUM"
    )]
    Detector {
        /// The alerter.
        alerter: String,
        /// The detector's name.
        detector: String,
        /// The class the configuration loads.
        class: String,
    },
}

/// The most alert levels an alerter may have (DAIDALUS's configurations have 1 to 4).
const MAX_LEVELS: usize = 16;

impl Config {
    /// Read a configuration from its text.
    ///
    /// ```
    /// use savsim_core::daa::conf::Config;
    /// let text = "lookahead_time = 3.0 [min]\nalerters = A\n\
    ///     A_alert_1_region = NEAR\nA_alert_1_alerting_time = 25 [s]\n\
    ///     A_alert_1_early_alerting_time = 55 [s]\nA_alert_1_detector = d\n\
    ///     A_d_WCV_DTHR = 0.66 [nmi]\nA_d_WCV_ZTHR = 450 [ft]\nA_d_WCV_TTHR = 35 [s]\n\
    ///     A_d_WCV_TCOA = 0 [s]\nA_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD\n";
    /// let c = Config::parse(text).unwrap();
    /// assert_eq!(c.lookahead_s, 180.0);
    /// let level = &c.alerters[0].levels[0];
    /// assert!((level.volume.dthr_m - 1222.32).abs() < 1e-9 && level.alerting_time_s == 25.0);
    /// ```
    pub fn parse(text: &str) -> Result<Self, ConfError> {
        let keys = key_values(text)?;
        let number = |key: &str, unit: &str, default: f64| -> Result<f64, ConfError> {
            match keys.get(key) {
                None => Ok(default),
                Some(v) => value_si(v, unit)
                    .filter(|x| x.is_finite() && *x >= 0.0)
                    .ok_or_else(|| ConfError::Value {
                        key: key.into(),
                        value: v.clone(),
                    }),
            }
        };
        let count = |key: &str| -> Result<usize, ConfError> {
            let x = number(key, "unitless", 0.0)?;
            if x.fract() != 0.0 || x > 1000.0 {
                return Err(ConfError::Value {
                    key: key.into(),
                    value: keys[key].clone(),
                });
            }
            Ok(x as usize)
        };
        const GLOBAL_Z: [&str; 6] = [
            "h_pos_z_score",
            "h_vel_z_score_min",
            "h_vel_z_score_max",
            "h_vel_z_distance",
            "v_pos_z_score",
            "v_vel_z_score",
        ];
        if let Some(key) = keys.keys().find(|k| {
            (k.contains("z_score") || k.ends_with("h_vel_z_distance"))
                && !GLOBAL_Z.contains(&k.as_str())
        }) {
            return Err(ConfError::Unsupported {
                key: key.clone(),
                why: "savsim reads the global z-scores only, not a detector's own",
            });
        }
        if keys
            .get("dta_logic")
            .is_some_and(|v| value_si(v, "unitless") != Some(0.0))
        {
            return Err(ConfError::Unsupported {
                key: "dta_logic".into(),
                why: "savsim has no DAA terminal area logic (give 0)",
            });
        }
        let names = keys
            .get("alerters")
            .ok_or_else(|| ConfError::Missing("alerters".into()))?;
        let alerters = names
            .split(',')
            .map(str::trim)
            .filter(|n| !n.is_empty())
            .map(|name| alerter(&keys, name))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Config {
            lookahead_s: number("lookahead_time", "s", 180.0)?,
            hysteresis_time_s: number("hysteresis_time", "s", 0.0)?,
            persistence_time_s: number("persistence_time", "s", 0.0)?,
            alerting_m: count("alerting_m")?,
            alerting_n: count("alerting_n")?,
            alerters,
            z_scores: crate::daa::sum::ZScores {
                h_pos: number("h_pos_z_score", "unitless", 0.0)?,
                h_vel_min: number("h_vel_z_score_min", "unitless", 0.0)?,
                h_vel_max: number("h_vel_z_score_max", "unitless", 0.0)?,
                h_vel_distance_m: number("h_vel_z_distance", "m", 0.0)?,
                v_pos: number("v_pos_z_score", "unitless", 0.0)?,
                v_vel: number("v_vel_z_score", "unitless", 0.0)?,
            },
            ownship_centric: keys
                .get("ownship_centric_alerting")
                .is_some_and(|v| v.eq_ignore_ascii_case("true")),
            corrective_region: keys
                .get("corrective_region")
                .cloned()
                .unwrap_or_else(|| "MID".into()),
            output_units: OutputUnits {
                horizontal: unit_of(&keys, "min_horizontal_recovery", "nmi"),
                vertical: unit_of(&keys, "min_vertical_recovery", "ft"),
                horizontal_speed: unit_of(&keys, "step_hs", "knot"),
                vertical_speed: unit_of(&keys, "step_vs", "fpm"),
            },
        })
    }

    /// The first level of alerter `alerter` (0-based) whose region is the corrective region or
    /// more severe (1-based), if any.
    pub fn corrective_level(&self, alerter: usize) -> Option<usize> {
        let bar = region_severity(&self.corrective_region)?;
        let levels = &self.alerters.get(alerter)?.levels;
        levels
            .iter()
            .position(|l| region_severity(&l.region).is_some_and(|s| s >= bar && s > 0))
            .map(|k| k + 1)
    }

    /// The most levels any alerter has.
    pub fn max_levels(&self) -> usize {
        self.alerters
            .iter()
            .map(|a| a.levels.len())
            .max()
            .unwrap_or(0)
    }
}

/// The unit written in brackets after `key`'s value, or `default`.
fn unit_of(keys: &HashMap<String, String>, key: &str, default: &str) -> String {
    keys.get(key)
        .and_then(|v| {
            let open = v.find('[')?;
            let close = v[open..].find(']')? + open;
            Some(v[open + 1..close].trim().to_string())
        })
        .filter(|u| crate::daa::units::si_per(u).is_some())
        .unwrap_or_else(|| default.into())
}

/// The `key = value` pairs of the text (a later line wins).
fn key_values(text: &str) -> Result<HashMap<String, String>, ConfError> {
    let mut keys = HashMap::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(ConfError::Syntax {
                line: k + 1,
                text: line.chars().take(200).collect(),
            });
        };
        keys.insert(key.trim().to_string(), value.trim().to_string());
    }
    Ok(keys)
}

/// Alerter `name`'s levels, 1 upwards while `<name>_alert_<k>_detector` is present.
fn alerter(keys: &HashMap<String, String>, name: &str) -> Result<Alerter, ConfError> {
    let get = |key: String| {
        keys.get(&key)
            .cloned()
            .ok_or_else(|| ConfError::Missing(key.clone()))
    };
    let seconds = |key: String| -> Result<f64, ConfError> {
        let v = get(key.clone())?;
        value_si(&v, "s")
            .filter(|x| x.is_finite() && *x >= 0.0)
            .ok_or(ConfError::Value { key, value: v })
    };
    let mut levels = Vec::new();
    for k in 1..=MAX_LEVELS {
        let Some(detector) = keys.get(&format!("{name}_alert_{k}_detector")) else {
            break;
        };
        for spread in ["hdir", "hs", "vs", "alt"] {
            let key = format!("{name}_alert_{k}_spread_{spread}");
            if let Some(v) = keys.get(&key) {
                if value_si(v, "unitless") != Some(0.0) {
                    return Err(ConfError::Unsupported {
                        key,
                        why: "savsim computes no kinematic alerting spreads (give 0)",
                    });
                }
            }
        }
        let class = get(format!("{name}_load_core_detection_{detector}"))?;
        let sum = match class.rsplit('.').next() {
            Some("WCV_TAUMOD") => false,
            Some("WCV_TAUMOD_SUM") => true,
            _ => {
                return Err(ConfError::Detector {
                    alerter: name.into(),
                    detector: detector.clone(),
                    class,
                })
            }
        };
        let metres = |what: &str| -> Result<f64, ConfError> {
            let key = format!("{name}_{detector}_WCV_{what}");
            let v = get(key.clone())?;
            value_si(&v, "m")
                .filter(|x| x.is_finite() && *x >= 0.0)
                .ok_or(ConfError::Value { key, value: v })
        };
        let volume = Volume {
            dthr_m: metres("DTHR")?,
            zthr_m: metres("ZTHR")?,
            tthr_s: seconds(format!("{name}_{detector}_WCV_TTHR"))?,
            tcoa_s: seconds(format!("{name}_{detector}_WCV_TCOA"))?,
        };
        let alerting_time_s = seconds(format!("{name}_alert_{k}_alerting_time"))?;
        let early = format!("{name}_alert_{k}_early_alerting_time");
        let early_alerting_time_s = if keys.contains_key(&early) {
            seconds(early)?
        } else {
            alerting_time_s
        };
        levels.push(Level {
            volume,
            alerting_time_s,
            early_alerting_time_s,
            region: keys
                .get(&format!("{name}_alert_{k}_region"))
                .cloned()
                .unwrap_or_else(|| "NONE".into()),
            sum,
        });
    }
    if levels.is_empty() {
        return Err(ConfError::Missing(format!("{name}_alert_1_detector")));
    }
    Ok(Alerter {
        name: name.into(),
        levels,
    })
}

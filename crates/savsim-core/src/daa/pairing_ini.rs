//! The pairing settings of an em-pairing-uncor-importancesampling `.ini` file
//! (`Example_Inputs/*.ini` there): `key = value ; comment` lines, values as MATLAB writes them
//! (numbers separated by spaces or commas, fractions `1/1.5`, `[]`, quoted strings, `a:b`).
//!
//! Read: `bin_edges_VMD`, `desired_proportions_VMD`, `bin_edges_HMD`, `desired_proportions_HMD`
//! (feet), `tCPA`, `sample_time` (seconds), `H_min` (feet), `R_min` (nautical miles). Settings
//! of that tool savsim does not implement (speed and altitude filters, 500 ft quantisation,
//! sampling from trajectory files or by duration, modified model statistics) are errors when
//! turned on. Settings that only name the tool's own files, outputs, IDs, random seed or
//! verbosity, and `altLayers` (the model file's own layer boundaries are used), are read and
//! ignored. Any other key is an error.

use crate::daa::pairing::{Bins, PairingError};
use crate::daa::well_clear::{FT_M, NMI_M};

/// How encounters are paired: the distributions and limits an `.ini` file sets.
#[derive(Debug, Clone, PartialEq)]
pub struct PairingSettings {
    /// The VMD bins (metres, intruder above positive) and the proportions rejection sampling
    /// keeps them in.
    pub vmd_m: Bins,
    /// The signed-HMD proposal (metres).
    pub hmd_m: Bins,
    /// The time of closest approach, whole seconds from the start.
    pub tca_s: usize,
    /// The encounter's length, whole seconds.
    pub duration_s: usize,
    /// An encounter whose aircraft start closer than both of these is drawn again.
    pub min_start_vertical_m: f64,
    /// See `min_start_vertical_m`.
    pub min_start_horizontal_m: f64,
    /// The true HMD is uniform over plus and minus this (10 nmi, as the tool's pairing sets it).
    pub max_hmd_m: f64,
}

/// Why an `.ini` file could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IniError {
    /// A line that is not `key = value`.
    #[error("line {line}: not `key = value`")]
    Syntax {
        /// 1-based.
        line: usize,
    },
    /// A key this reader does not know.
    #[error("line {line}: unknown key `{key}`")]
    Unknown {
        /// 1-based.
        line: usize,
        /// The key.
        key: String,
    },
    /// A setting savsim does not implement, turned on.
    #[error("`{key} = {value}`: not supported by savsim's pairing (leave it 0 or [])")]
    Unsupported {
        /// The key.
        key: String,
        /// Its value.
        value: String,
    },
    /// A value that is not what its key needs.
    #[error("`{key}`: {message}")]
    Value {
        /// The key.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A key the pairing needs is absent.
    #[error("no `{0}`")]
    Missing(&'static str),
    /// Bins that are not a distribution.
    #[error(transparent)]
    Bins(#[from] PairingError),
}

/// Keys read and ignored (see the module's documentation).
const IGNORED: &[&str] = &[
    "altLayers",
    "encIds",
    "outputEvents",
    "outputTrajectories",
    "ownshipEmFile",
    "intruderEmFile",
    "saveDirectory",
    "testDirectory",
    "ownship_trajectory_dir",
    "ownship_trajectory_datafile",
    "intruder_trajectory_dir",
    "intruder_trajectory_datafile",
    "randSeed",
    "verbose_level",
];

/// Keys of features savsim does not implement: they must be `0`, empty or `[]`.
const OFF: &[&str] = &[
    "applyOwnshipFilterWholeEncounter",
    "applyIntruderFilterWholeEncounter",
    "applyOwnshipFilterAtCPA",
    "applyIntruderFilterAtCPA",
    "applyOwnshipFilterSampling",
    "applyIntruderFilterSampling",
    "quantizeOwnshipAlt500",
    "quantizeIntruderAlt500",
    "sampleByDurationOwnship",
    "sampleByDurationIntruder",
    "ownshipSampleTrajectory",
    "intruderSampleTrajectory",
    "maxOwnSpeed_kts",
    "minOwnSpeed_kts",
    "maxOwnAlt_ft",
    "minOwnAlt_ft",
    "maxOwnAltType",
    "minOwnAltType",
    "ownEncVariablesFile",
    "ownEncStatisticsFile",
    "maxIntSpeed_kts",
    "minIntSpeed_kts",
    "maxIntAlt_ft",
    "minIntAlt_ft",
    "maxIntAltType",
    "minIntAltType",
    "intEncVariablesFile",
    "intEncStatisticsFile",
];

/// Keys read into the settings.
const READ: &[&str] = &[
    "bin_edges_VMD",
    "desired_proportions_VMD",
    "bin_edges_HMD",
    "desired_proportions_HMD",
    "tCPA",
    "sample_time",
    "H_min",
    "R_min",
];

/// One number as MATLAB writes it: `1.5`, `-3`, `1/1.5`.
fn number(text: &str) -> Option<f64> {
    let x = match text.split_once('/') {
        Some((a, b)) => a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?,
        None => text.trim().parse::<f64>().ok()?,
    };
    x.is_finite().then_some(x)
}

fn numbers(key: &'static str, value: &str) -> Result<Vec<f64>, IniError> {
    let inner = value.trim().trim_start_matches('[').trim_end_matches(']');
    inner
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| {
            number(s).ok_or_else(|| IniError::Value {
                key,
                message: format!("not a number: {s:?}"),
            })
        })
        .collect()
}

fn scalar(key: &'static str, value: &str) -> Result<f64, IniError> {
    match numbers(key, value)?.as_slice() {
        [x] => Ok(*x),
        other => Err(IniError::Value {
            key,
            message: format!("give one number, not {}", other.len()),
        }),
    }
}

/// Whether an unimplemented feature's value leaves it off.
fn is_off(value: &str) -> bool {
    let v = value.trim();
    v.is_empty() || v == "[]" || v == "''" || v == "\"\"" || number(v) == Some(0.0)
}

/// The `key = value` pairs, comments removed, unknown and turned-on keys refused.
fn entries(text: &str) -> Result<Vec<(&'static str, String)>, IniError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split(';').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let (key, value) = line
            .split_once('=')
            .ok_or(IniError::Syntax { line: i + 1 })?;
        let (key, value) = (key.trim(), value.trim());
        if let Some(k) = READ.iter().find(|k| **k == key) {
            out.push((*k, value.to_string()));
        } else if OFF.contains(&key) {
            if !is_off(value) {
                return Err(IniError::Unsupported {
                    key: key.into(),
                    value: value.into(),
                });
            }
        } else if !IGNORED.contains(&key) {
            return Err(IniError::Unknown {
                line: i + 1,
                key: key.into(),
            });
        }
    }
    Ok(out)
}

/// Whole, non-negative seconds no longer than a day.
fn seconds(key: &'static str, x: f64) -> Result<usize, IniError> {
    if x.fract() != 0.0 || !(0.0..=86_400.0).contains(&x) {
        return Err(IniError::Value {
            key,
            message: format!("{x}: give whole seconds from 0 to 86400"),
        });
    }
    Ok(x as usize)
}

impl PairingSettings {
    /// Read the settings of an `.ini` file.
    ///
    /// ```
    /// use savsim_core::daa::pairing_ini::PairingSettings;
    /// let ini = "bin_edges_VMD = -1500, 0, 1500 ; ft\n\
    ///            desired_proportions_VMD = 1/2 1\n\
    ///            bin_edges_HMD = -18240, 0, 18240\n\
    ///            desired_proportions_HMD = 1 1\n\
    ///            tCPA = 150\nsample_time = 180\nH_min = 800\nR_min = 1.5\n\
    ///            applyOwnshipFilterAtCPA = 0\nsaveDirectory = 'out'";
    /// let s = PairingSettings::parse(ini).unwrap();
    /// assert_eq!((s.tca_s, s.duration_s), (150, 180));
    /// assert!((s.vmd_m.edges()[0] + 457.2).abs() < 1e-9);
    /// assert!(PairingSettings::parse(&format!("{ini}\nquantizeOwnshipAlt500 = 1")).is_err());
    /// assert!(PairingSettings::parse(&format!("{ini}\nfoo = 1")).is_err());
    /// ```
    pub fn parse(text: &str) -> Result<Self, IniError> {
        let all = entries(text)?;
        let get = |key: &'static str| -> Result<&str, IniError> {
            all.iter()
                .rev()
                .find(|(k, _)| *k == key)
                .map(|(_, v)| v.as_str())
                .ok_or(IniError::Missing(key))
        };
        let feet = |key: &'static str| -> Result<Vec<f64>, IniError> {
            Ok(numbers(key, get(key)?)?.iter().map(|x| x * FT_M).collect())
        };
        let vmd_m = Bins::new(
            "bin_edges_VMD",
            &feet("bin_edges_VMD")?,
            &numbers("desired_proportions_VMD", get("desired_proportions_VMD")?)?,
        )?;
        let hmd_m = Bins::new(
            "bin_edges_HMD",
            &feet("bin_edges_HMD")?,
            &numbers("desired_proportions_HMD", get("desired_proportions_HMD")?)?,
        )?;
        let tca_s = seconds("tCPA", scalar("tCPA", get("tCPA")?)?)?;
        let duration_s = seconds("sample_time", scalar("sample_time", get("sample_time")?)?)?;
        if tca_s >= duration_s {
            return Err(IniError::Value {
                key: "tCPA",
                message: format!("{tca_s} s: must come before sample_time ({duration_s} s)"),
            });
        }
        let distance = |key: &'static str, unit_m: f64| -> Result<f64, IniError> {
            let x = scalar(key, get(key)?)?;
            if x < 0.0 {
                return Err(IniError::Value {
                    key,
                    message: format!("{x}: give a distance >= 0"),
                });
            }
            Ok(x * unit_m)
        };
        Ok(Self {
            vmd_m,
            hmd_m,
            tca_s,
            duration_s,
            min_start_vertical_m: distance("H_min", FT_M)?,
            min_start_horizontal_m: distance("R_min", NMI_M)?,
            max_hmd_m: 10.0 * NMI_M,
        })
    }
}

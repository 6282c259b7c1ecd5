//! DAIDALUS's state files (`.daa`): a header line naming the columns, an optional units line,
//! then one row per aircraft and time (the first aircraft of each time is the ownship).
//!
//! Columns, case-insensitive, in any order: the name (`name`, `aircraft`, `id`); the position,
//! geodetic (`lat`, `lon`, `alt`; default units deg, deg, ft) or Euclidean (`sx`, `sy`, `sz`;
//! nmi, nmi, ft; `east` and `north` are read as `sx` and `sy`, as MIT LL's encounter tools
//! write their trajectory files); the velocity, Cartesian (`vx`, `vy`, `vz`: east, north, up; knot, knot, fpm)
//! or polar (`trk`, `gs`, `vs`; deg from north, knot, fpm); the time (`time`, `clock`, `tm`,
//! `st`; s, or `hh:mm:ss`); optionally `alerter` (the alerter's number or name), and the state
//! uncertainty of sensor uncertainty mitigation (`s_EW_std`, `s_NS_std`, `s_EN_std`, `sz_std`,
//! `v_EW_std`, `v_NS_std`, `v_EN_std`, `vz_std`: 1-sigma, SI units unless the units line names a
//! known unit; an empty cell or a missing column is 0). A units line (`[deg]`, `[ft]`,
//! `unitless`...) overrides the defaults column by column. Other columns are kept nowhere.

use glam::DVec3;

use crate::daa::units::si_per;

/// An aircraft's position as the file gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Position {
    /// Latitude and longitude (degrees) and altitude (metres).
    Geodetic {
        /// Latitude, degrees.
        lat_deg: f64,
        /// Longitude, degrees.
        lon_deg: f64,
        /// Altitude, metres.
        alt_m: f64,
    },
    /// A point of a Euclidean frame (east, north, up), metres.
    Euclidean(DVec3),
}

/// One aircraft at one time.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Its name.
    pub name: String,
    /// Where it is.
    pub position: Position,
    /// Its velocity, east, north, up, m/s.
    pub velocity_enu_mps: DVec3,
    /// The alerter the row names (1-based), if it names one.
    pub alerter: Option<AlerterRef>,
    /// Its state's uncertainty (all 0 without the columns).
    pub uncertainty: crate::daa::sum::Uncertainty,
}

/// An alerter named by a row: by number or by name.
#[derive(Debug, Clone, PartialEq)]
pub enum AlerterRef {
    /// 1-based index.
    Index(usize),
    /// The alerter's name.
    Name(String),
}

/// Every aircraft at one time; the ownship first.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The time, seconds.
    pub time_s: f64,
    /// The aircraft, ownship first.
    pub aircraft: Vec<State>,
}

/// Why a state file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// The file has no header line.
    #[error("empty file: no header line")]
    Empty,
    /// A required column is absent.
    #[error(
        "no {0} column (the header needs name, lat|sx|east, lon|sy|north, alt|sz, vx|trk, vy|gs, vz|vs, time)"
    )]
    MissingColumn(&'static str),
    /// A unit the reader does not know.
    #[error("column {column}: unknown unit [{unit}]")]
    Unit {
        /// The column's header.
        column: String,
        /// The unit.
        unit: String,
    },
    /// A row that cannot be read.
    #[error("line {line}: {problem}")]
    Row {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: RowError,
    },
}

/// What is wrong with a row of a state file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RowError {
    /// Beyond the most rows read.
    #[error("more than {0} rows")]
    TooMany(usize),
    /// A column the header has and the row does not (1-based).
    #[error("no column {0}")]
    NoColumn(usize),
    /// A field that is not a number.
    #[error("column {column}: not a number: {text:?}")]
    NotNumber {
        /// 1-based.
        column: usize,
        /// The field.
        text: String,
    },
    /// A number beyond 1e12 or not finite.
    #[error("column {column}: out of range: {text:?}")]
    OutOfRange {
        /// 1-based.
        column: usize,
        /// The field.
        text: String,
    },
    /// A latitude beyond the poles.
    #[error("latitude {0} outside +/-90 degrees")]
    Latitude(f64),
    /// A time field that is not one.
    #[error("not a time: {0:?}")]
    NotTime(String),
}

/// The columns a state needs, their index and the SI per unit of each.
struct Columns {
    name: usize,
    geodetic: bool,
    polar: bool,
    position: [(usize, f64); 3],
    velocity: [(usize, f64); 3],
    time: (usize, f64),
    alerter: Option<usize>,
    /// The uncertainty columns present (`s_EW_std` ... `vz_std`), each with its unit's factor.
    uncertainty: [Option<(usize, f64)>; 8],
}

/// The uncertainty columns, in [`crate::daa::sum::Uncertainty`]'s order.
const UNCERTAINTY: [&str; 8] = [
    "s_ew_std", "s_ns_std", "s_en_std", "sz_std", "v_ew_std", "v_ns_std", "v_en_std", "vz_std",
];

/// Most rows a state file may hold (`savsim daa` reads it whole).
pub const MAX_ROWS: usize = 10_000_000;

/// Read a state file's steps, in time order: every row of one time is one step, wherever it
/// is in the file (as DAIDALUS's `SequenceReader` keys states by time), its aircraft in the
/// order of their first appearance in the file, so the file's first aircraft is the ownship
/// at every step. (MIT LL's trajectory files list one aircraft's rows, then the other's.)
///
/// ```
/// use savsim_core::daa::scenario::{parse, Position};
/// let text = "NAME sx sy sz vx vy vz time\n\
///     [none] [m] [m] [m] [m/s] [m/s] [m/s] [s]\n\
///     own 0 0 100 10 0 0 0\n\
///     intr 1000 0 100 -10 0 0 0\n";
/// let steps = parse(text).unwrap();
/// assert_eq!(steps.len(), 1);
/// assert_eq!(steps[0].aircraft[1].position, Position::Euclidean(glam::DVec3::new(1000.0, 0.0, 100.0)));
/// assert_eq!(steps[0].aircraft[1].velocity_enu_mps.x, -10.0);
/// // One aircraft's rows, then the other's: the same steps.
/// let by_aircraft = "NAME east north alt trk gs vs time\n\
///     OWN 0 0 0 0 1 0 0\nOWN 0 1 0 0 1 0 1\nINT 5 0 0 0 1 0 0\nINT 5 1 0 0 1 0 1\n";
/// let steps = parse(by_aircraft).unwrap();
/// assert_eq!(steps.len(), 2);
/// assert_eq!((steps[1].aircraft[0].name.as_str(), steps[1].aircraft[1].name.as_str()), ("OWN", "INT"));
/// ```
pub fn parse(text: &str) -> Result<Vec<Step>, ScenarioError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (_, header) = lines.next().ok_or(ScenarioError::Empty)?;
    let headers: Vec<String> = split(header).map(str::to_ascii_lowercase).collect();
    let mut pending = lines.next();
    let units: Option<Vec<String>> = match pending {
        Some((_, l)) if is_units_line(l) => {
            pending = None;
            Some(
                split(l)
                    .map(|u| u.trim_matches(['[', ']']).to_string())
                    .collect(),
            )
        }
        _ => None,
    };
    let columns = columns(&headers, units.as_deref())?;
    let mut rows: Vec<(f64, usize, State)> = Vec::new();
    let mut ranks: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    for (line, row) in pending.into_iter().chain(lines) {
        if rows.len() >= MAX_ROWS {
            return Err(ScenarioError::Row {
                line,
                problem: RowError::TooMany(MAX_ROWS),
            });
        }
        let (time_s, state) =
            read_row(&columns, row).map_err(|problem| ScenarioError::Row { line, problem })?;
        let next = ranks.len();
        let rank = *ranks.entry(state.name.clone()).or_insert(next);
        rows.push((time_s, rank, state));
    }
    // By time, then by each aircraft's first appearance in the file (stable: repeated rows
    // keep their order).
    rows.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut steps: Vec<Step> = Vec::new();
    for (time_s, _, state) in rows {
        match steps.last_mut() {
            Some(step) if step.time_s == time_s => step.aircraft.push(state),
            _ => steps.push(Step {
                time_s,
                aircraft: vec![state],
            }),
        }
    }
    Ok(steps)
}

/// A line's fields: comma-separated when it has a comma, else by whitespace.
fn split(line: &str) -> Box<dyn Iterator<Item = &str> + '_> {
    if line.contains(',') {
        Box::new(line.split(',').map(str::trim))
    } else {
        Box::new(line.split_whitespace())
    }
}

/// A units line: every field a bracketed unit or `unitless`.
fn is_units_line(line: &str) -> bool {
    split(line).all(|f| {
        let f = f.trim();
        f.is_empty() || f.starts_with('[') || f.eq_ignore_ascii_case("unitless")
    })
}

/// Where each needed column is, and its unit.
fn columns(headers: &[String], units: Option<&[String]>) -> Result<Columns, ScenarioError> {
    let find = |names: &[&str]| headers.iter().position(|h| names.contains(&h.as_str()));
    let need =
        |names: &[&str], what: &'static str| find(names).ok_or(ScenarioError::MissingColumn(what));
    let geodetic = find(&["lat", "latitude"]).is_some();
    let polar = find(&["trk", "track"]).is_some();
    let unit = |index: usize, default: &str| -> Result<f64, ScenarioError> {
        let given = units.and_then(|u| u.get(index)).map(String::as_str);
        let name = match given {
            Some(u) if !u.is_empty() && u != "unitless" && u != "none" => u,
            _ => default,
        };
        si_per(name).ok_or_else(|| ScenarioError::Unit {
            column: headers[index].clone(),
            unit: name.into(),
        })
    };
    let at = |names: &[&str],
              what: &'static str,
              default: &str|
     -> Result<(usize, f64), ScenarioError> {
        let index = need(names, what)?;
        Ok((index, unit(index, default)?))
    };
    let position = if geodetic {
        [
            at(&["lat", "latitude"], "lat", "deg")?,
            at(&["lon", "long", "longitude"], "lon", "deg")?,
            at(&["alt", "altitude"], "alt", "ft")?,
        ]
    } else {
        [
            at(&["sx", "east"], "sx", "nmi")?,
            at(&["sy", "north"], "sy", "nmi")?,
            at(&["sz", "alt", "altitude"], "sz", "ft")?,
        ]
    };
    let velocity = if polar {
        [
            at(&["trk", "track"], "trk", "deg")?,
            at(&["gs", "groundspeed", "groundspd"], "gs", "knot")?,
            at(&["vs", "verticalspeed", "hdot"], "vs", "fpm")?,
        ]
    } else {
        [
            at(&["vx"], "vx", "knot")?,
            at(&["vy"], "vy", "knot")?,
            at(&["vz"], "vz", "fpm")?,
        ]
    };
    Ok(Columns {
        name: need(&["name", "aircraft", "id"], "name")?,
        geodetic,
        polar,
        position,
        velocity,
        time: at(&["time", "clock", "tm", "st"], "time", "s")?,
        alerter: find(&["alerter"]),
        // DAIDALUS: a known unit converts; none, or one it does not know, is SI already.
        uncertainty: UNCERTAINTY.map(|name| {
            let index = find(&[name])?;
            let given = units.and_then(|u| u.get(index)).map(String::as_str);
            Some((index, given.and_then(si_per).unwrap_or(1.0)))
        }),
    })
}

/// One row: its time and the state.
fn read_row(c: &Columns, row: &str) -> Result<(f64, State), RowError> {
    let fields: Vec<&str> = split(row).collect();
    let field = |i: usize| fields.get(i).copied().ok_or(RowError::NoColumn(i + 1));
    let number = |(i, si): (usize, f64)| -> Result<f64, RowError> {
        let text = field(i)?;
        let x: f64 = text.parse().map_err(|_| RowError::NotNumber {
            column: i + 1,
            text: text.into(),
        })?;
        if !x.is_finite() || x.abs() > 1e12 {
            return Err(RowError::OutOfRange {
                column: i + 1,
                text: text.into(),
            });
        }
        Ok(x * si)
    };
    let [p0, p1, p2] = c.position.map(number);
    let position = if c.geodetic {
        let to_deg = 180.0 / std::f64::consts::PI;
        let (lat_deg, lon_deg) = (p0? * to_deg, p1? * to_deg);
        if lat_deg.abs() > 90.0 {
            return Err(RowError::Latitude(lat_deg));
        }
        Position::Geodetic {
            lat_deg,
            lon_deg,
            alt_m: p2?,
        }
    } else {
        Position::Euclidean(DVec3::new(p0?, p1?, p2?))
    };
    let [v0, v1, v2] = c.velocity.map(number);
    let velocity_enu_mps = if c.polar {
        let (trk_rad, gs_mps) = (v0?, v1?);
        DVec3::new(gs_mps * trk_rad.sin(), gs_mps * trk_rad.cos(), v2?)
    } else {
        DVec3::new(v0?, v1?, v2?)
    };
    let time_s = time(field(c.time.0)?, c.time.1)?;
    let alerter = c
        .alerter
        .and_then(|i| fields.get(i))
        .map(|a| match a.parse::<usize>() {
            Ok(k) => AlerterRef::Index(k),
            Err(_) => AlerterRef::Name(a.to_string()),
        });
    let mut sigma = [0.0; 8];
    for (out, column) in sigma.iter_mut().zip(c.uncertainty) {
        if let Some((i, si)) = column.filter(|(i, _)| fields.get(*i).is_some_and(|f| !f.is_empty()))
        {
            *out = number((i, si))?;
        }
    }
    let [s_ew_m, s_ns_m, s_en_m, sz_m, v_ew_mps, v_ns_mps, v_en_mps, vz_mps] = sigma;
    Ok((
        time_s,
        State {
            name: field(c.name)?.to_string(),
            position,
            velocity_enu_mps,
            alerter,
            uncertainty: crate::daa::sum::Uncertainty {
                s_ew_m,
                s_ns_m,
                s_en_m,
                sz_m,
                v_ew_mps,
                v_ns_mps,
                v_en_mps,
                vz_mps,
            },
        },
    ))
}

/// A time field: seconds (in the column's unit) or `hh:mm:ss`.
fn time(text: &str, si: f64) -> Result<f64, RowError> {
    let parts: Vec<&str> = text.split(':').collect();
    let bad = || RowError::NotTime(text.into());
    let t = if parts.len() > 1 {
        parts
            .iter()
            .try_fold(0.0, |acc, p| {
                p.trim().parse::<f64>().map(|x| acc * 60.0 + x)
            })
            .map_err(|_| bad())?
    } else {
        text.parse::<f64>().map_err(|_| bad())? * si
    };
    if t.is_finite() && t.abs() <= 1e12 {
        Ok(t)
    } else {
        Err(bad())
    }
}

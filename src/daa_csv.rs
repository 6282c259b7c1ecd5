//! `savsim daa`: a DAIDALUS state file's alerting as the CSV DAIDALUS's `DaidalusAlerting`
//! writes (its header, its units line, its columns in its order and units, its number format),
//! so that the two files compare cell by cell.

use std::io::Write;
use std::path::Path;

use crate::cli::DaaArgs;
use crate::daa::alerting_run::{alert_rows, AlertRow};
use crate::daa::conf::Config;
use crate::daa::scenario;
use crate::daa::units::si_per;
use crate::error::{Error, Result};

/// Most bytes read from one DAIDALUS file or encounter model.
const MAX_INPUT_BYTES: u64 = 1 << 30;

/// Run `savsim daa`.
pub fn command(args: &DaaArgs) -> Result<()> {
    let config = Config::parse(&read(&args.conf)?).map_err(|e| Error::Daa {
        path: args.conf.clone(),
        message: e.to_string(),
    })?;
    let steps = scenario::parse(&read(&args.scenario)?).map_err(|e| Error::Daa {
        path: args.scenario.clone(),
        message: e.to_string(),
    })?;
    let rows = alert_rows(&steps, &config);
    let text = csv(&config, &rows, usize::from(args.precision));
    match &args.out {
        Some(path) => std::fs::write(path, text).map_err(|e| Error::file(path, e)),
        None => std::io::stdout()
            .write_all(text.as_bytes())
            .map_err(|e| Error::file("<stdout>", e)),
    }
}

/// A DAIDALUS file or an encounter model, whole: at most 1 GiB (`MAX_INPUT_BYTES`), as text
/// (`crate::files::read_text`: a device or a FIFO that keeps writing is an error too).
pub fn read(path: &Path) -> Result<String> {
    crate::files::read_text(path, MAX_INPUT_BYTES).map_err(|e| Error::file(path, e))
}

/// The whole CSV: header, units line, one line per row.
pub fn csv(config: &Config, rows: &[AlertRow], precision: usize) -> String {
    let u = &config.output_units;
    let levels = config.max_levels();
    let mut header = String::from(" Time, Ownship, Traffic, Alerter, Alert Level");
    let mut units = String::from("[s],,,,");
    for level in 1..=levels {
        header += &format!(", Time to Volume of Alert({level})");
        units += ", [s]";
    }
    header += ", Horizontal Separation, Vertical Separation, Horizontal Closure Rate, \
               Vertical Closure Rate, Projected HMD, Projected VMD, Projected TCPA, \
               Projected DCPA, Projected TCOA, Projected TAUMOD (WCV*)";
    units += &format!(
        ", [{h}], [{v}], [{hs}], [{vs}], [{h}], [{v}], [s], [{h}], [s], [s]",
        h = u.horizontal,
        v = u.vertical,
        hs = u.horizontal_speed,
        vs = u.vertical_speed
    );
    let mut out = format!("{header}\n{units}\n");
    let per = |unit: &str| si_per(unit).unwrap_or(1.0);
    let (h, v) = (per(&u.horizontal), per(&u.vertical));
    let (hs, vs) = (per(&u.horizontal_speed), per(&u.vertical_speed));
    let f = |x: f64| number(x, precision);
    for r in rows {
        let mut line = format!(
            "{}, {}, {}, {}, {}",
            f(r.time_s),
            r.ownship,
            r.traffic,
            r.alerter,
            r.level
        );
        for level in 0..levels {
            line += ", ";
            if let Some(t) = r.time_to_volume_s.get(level) {
                line += &f(*t);
            }
        }
        let optional = |x: Option<f64>| x.map_or(String::new(), f);
        line += &format!(
            ", {}, {}, {}, {}, {}, {}, {}, {}, {}, {}\n",
            f(r.horizontal_m / h),
            f(r.vertical_m / v),
            f(r.horizontal_closure_mps / hs),
            f(r.vertical_closure_mps / vs),
            f(r.hmd_m / h),
            f(r.vmd_m / v),
            f(r.tcpa_s),
            f(r.dcpa_m / h),
            optional(r.tcoa_s),
            optional(r.tau_mod_s),
        );
        out += &line;
    }
    out
}

/// A number as DAIDALUS prints it: rounded to `precision` decimals, trailing zeros dropped but
/// one decimal kept (`0.0`, `799.95196`), `infty`/`-infty`, `NaN`, no negative zero.
///
/// ```
/// use savsim::daa_csv::number;
/// assert_eq!(number(0.0, 6), "0.0");
/// assert_eq!(number(799.951960001, 6), "799.95196");
/// assert_eq!(number(-0.0000001, 6), "0.0");
/// assert_eq!(number(f64::INFINITY, 6), "infty");
/// assert_eq!(number(12.5, 0), "12");
/// ```
pub fn number(x: f64, precision: usize) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "infty" } else { "-infty" }.into();
    }
    let text = format!("{x:.precision$}");
    let text = if precision == 0 {
        text
    } else {
        let trimmed = text.trim_end_matches('0');
        if trimmed.ends_with('.') {
            format!("{trimmed}0")
        } else {
            trimmed.to_string()
        }
    };
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => text,
    }
}

//! Bounds on every number that comes from outside (a flag, a manifest cell, a scene field)
//! before it sizes an allocation or a loop: an allocation failure aborts the process and no
//! `catch_unwind` catches it, and a loop sized by `1e300` never ends. One check, one typed
//! error that names the input, the value and the range.

/// A number outside the range its input allows.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} {}: give {what}", shown(*value))]
pub struct OutOfRange {
    /// The input (`--rate-hz`, `duration_s`).
    pub name: String,
    /// What it held.
    pub value: f64,
    /// The range, in words (`a number in [0, 1000]`).
    pub what: String,
}

/// A number as a person reads it: `1e14`, not fifteen digits (every error message that quotes a
/// number from outside writes it so).
///
/// ```
/// use savsim_core::bounds::shown;
/// assert_eq!(shown(1e300), "1e300");
/// assert_eq!(shown(2.5), "2.5");
/// ```
pub fn shown(value: f64) -> String {
    let a = value.abs();
    if a >= 1e9 || (a > 0.0 && a < 1e-6) {
        format!("{value:e}")
    } else {
        value.to_string()
    }
}

/// `value` if it is finite and in `[min, max]`.
///
/// ```
/// use savsim_core::bounds::within;
/// assert_eq!(within("rate_hz", 10.0, 0.0, 1000.0), Ok(10.0));
/// let e = within("rate_hz", 1e300, 0.0, 1000.0).unwrap_err();
/// assert_eq!(e.to_string(), "rate_hz 1e300: give a number in [0, 1000]");
/// assert!(within("duration_s", f64::NAN, 0.0, 1.0).is_err());
/// ```
pub fn within(name: &str, value: f64, min: f64, max: f64) -> Result<f64, OutOfRange> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(OutOfRange {
            name: name.to_owned(),
            value,
            what: format!("a number in [{}, {}]", shown(min), shown(max)),
        })
    }
}

/// `value` if it is finite, above 0 and at most `max`.
///
/// ```
/// use savsim_core::bounds::positive;
/// assert!(positive("duration_s", 0.0, 1e6).is_err());
/// assert_eq!(positive("duration_s", 60.0, 1e6), Ok(60.0));
/// ```
pub fn positive(name: &str, value: f64, max: f64) -> Result<f64, OutOfRange> {
    if value.is_finite() && value > 0.0 && value <= max {
        Ok(value)
    } else {
        Err(OutOfRange {
            name: name.to_owned(),
            value,
            what: format!("a number above 0, at most {}", shown(max)),
        })
    }
}

/// The most seconds a run, a row or a track may last: 30 days.
pub const MAX_DURATION_S: f64 = 30.0 * 86_400.0;
/// The most samples per second a run or a row may ask for.
pub const MAX_RATE_HZ: f64 = 1000.0;
/// The most samples one row may fly (`duration_s x rate_hz`): ten million.
pub const MAX_SAMPLES: f64 = 1e7;
/// The largest coordinate of a position in a scene's ENU frame, metres (beyond the Moon's
/// orbit a local tangent plane means nothing).
pub const MAX_ENU_M: f64 = 1e8;

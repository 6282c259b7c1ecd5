//! The units DAIDALUS's files write in brackets (`[nmi]`, `[ft]`, `[knot]`, `[fpm]`...), to and
//! from SI.

use crate::daa::well_clear::{FT_M, NMI_M};

/// Metres (or m/s, seconds, radians: the SI unit of the quantity) in one `unit`; `None` for a
/// unit this reader does not know. `unitless` and the empty unit are 1.
///
/// ```
/// use savsim_core::daa::units::si_per;
/// assert_eq!(si_per("ft"), Some(0.3048));
/// assert_eq!(si_per("knot"), Some(1852.0 / 3600.0));
/// assert!((si_per("fpm").unwrap() - 0.3048 / 60.0).abs() < 1e-15);
/// assert_eq!(si_per("furlong"), None);
/// ```
pub fn si_per(unit: &str) -> Option<f64> {
    Some(match unit.trim() {
        "" | "unitless" | "unspecified" | "none" => 1.0,
        "m" => 1.0,
        "km" => 1000.0,
        "ft" => FT_M,
        "nmi" | "NM" | "nm" => NMI_M,
        "mi" => 1609.344,
        "s" => 1.0,
        "ms" => 1e-3,
        "min" => 60.0,
        "h" | "hr" => 3600.0,
        "m/s" | "mps" => 1.0,
        "knot" | "kn" | "kts" | "nmi/h" => NMI_M / 3600.0,
        "nmi/s" => NMI_M,
        "km/s" => 1000.0,
        "m/min" => 1.0 / 60.0,
        "mph" => 1609.344 / 3600.0,
        "fpm" | "ft/min" => FT_M / 60.0,
        "ft/s" | "fps" | "ftps" => FT_M,
        "km/h" | "kph" => 1000.0 / 3600.0,
        "deg" => std::f64::consts::PI / 180.0,
        "rad" => 1.0,
        "deg/s" => std::f64::consts::PI / 180.0,
        "rad/s" => 1.0,
        "m/s^2" => 1.0,
        "G" => 9.80665,
        _ => return None,
    })
}

/// A value written `NUMBER [UNIT]` (the unit optional: then `default_unit`), in SI.
///
/// ```
/// use savsim_core::daa::units::value_si;
/// assert_eq!(value_si("0.5 [nmi]", "m"), Some(926.0));
/// assert_eq!(value_si("35.0", "s"), Some(35.0));
/// assert_eq!(value_si("x [s]", "s"), None);
/// ```
pub fn value_si(text: &str, default_unit: &str) -> Option<f64> {
    let (number, unit) = match text.find('[') {
        Some(at) => {
            let unit = text[at + 1..].strip_suffix(']').or_else(|| {
                let close = text[at + 1..].find(']')?;
                Some(&text[at + 1..at + 1 + close])
            })?;
            (&text[..at], unit)
        }
        None => (text, default_unit),
    };
    let x: f64 = number.trim().parse().ok()?;
    Some(x * si_per(unit)?)
}

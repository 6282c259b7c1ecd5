//! A building's height and base from its tags, by one policy: `height` (or `building:levels`
//! at a height a level), `min_height` (or `building:min_level`), else a default; lengths with
//! or without units, bounded.

use super::{tag, Tags};

/// Where a building's height came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeightSource {
    /// `height`.
    Height,
    /// `building:levels` (and `roof:levels`/`roof:height`).
    Levels,
    /// Neither: the default.
    Default,
}

/// The height policy's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightPolicy {
    /// Metres per level. Default 3.
    pub level_m: f64,
    /// The height of a building that says neither `height` nor `building:levels`. Default 10.
    pub default_m: f64,
}

impl Default for HeightPolicy {
    fn default() -> Self {
        Self {
            level_m: 3.0,
            default_m: 10.0,
        }
    }
}

/// A length as OSM writes it: metres (`12`, `12.5 m`, `12m`), or feet (`40 ft`, `40'`,
/// `40'6"`); `None` when it is not one.
///
/// ```
/// use savsim_core::scene::osm::length_m;
/// assert_eq!(length_m("12.5 m"), Some(12.5));
/// assert_eq!(length_m("40'"), Some(12.192));
/// assert_eq!(length_m("tall"), None);
/// ```
pub fn length_m(text: &str) -> Option<f64> {
    let t = text.trim();
    let number = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    let metres = if let Some(m) = t.strip_suffix('m') {
        number(m)?
    } else if let Some(f) = t.strip_suffix("ft") {
        number(f)? * 0.3048
    } else if let Some((feet, rest)) = t.split_once('\'') {
        let inches = rest.trim().strip_suffix('"').map_or(Some(0.0), number)?;
        (number(feet)? + inches / 12.0) * 0.3048
    } else {
        number(t)?
    };
    Some(metres)
}

/// The tallest height or base tag taken, metres (the tallest building is 828 m): a larger
/// value is not a height, as a tag that does not parse.
pub const MAX_HEIGHT_M: f64 = 2000.0;

/// The most levels taken.
pub const MAX_LEVELS: f64 = 500.0;

/// A building's base and top above the ground, metres, and where its height came from:
/// top = `height`, else `building:levels` x `level_m` + the roof (`roof:height`, else
/// `roof:levels` x `level_m`), else the default; base = `min_height`, else
/// `building:min_level` x `level_m`, else 0. A value beyond [`MAX_HEIGHT_M`] or
/// [`MAX_LEVELS`] counts as absent. `None` when the base is not below the top.
///
/// ```
/// use savsim_core::scene::osm::{heights, HeightPolicy, HeightSource};
/// let tags = |t: &[(&str, &str)]| t.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
/// let p = HeightPolicy::default();
/// assert_eq!(heights(&tags(&[("height", "21")]), p), Some((0.0, 21.0, HeightSource::Height)));
/// let levels = tags(&[("building:levels", "4"), ("roof:height", "2"), ("building:min_level", "1")]);
/// assert_eq!(heights(&levels, p), Some((3.0, 14.0, HeightSource::Levels)));
/// assert_eq!(heights(&tags(&[]), p), Some((0.0, 10.0, HeightSource::Default)));
/// ```
pub fn heights(tags: &Tags, policy: HeightPolicy) -> Option<(f64, f64, HeightSource)> {
    let number = |k: &str| {
        tag(tags, k)
            .and_then(length_m)
            .filter(|v| (0.0..=MAX_HEIGHT_M).contains(v))
    };
    let count = |k: &str| {
        tag(tags, k)
            .and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|v| (0.0..=MAX_LEVELS).contains(v))
    };
    let (top, source) = if let Some(h) = number("height") {
        (h, HeightSource::Height)
    } else if let Some(levels) = count("building:levels") {
        let roof = number("roof:height")
            .or_else(|| count("roof:levels").map(|l| l * policy.level_m))
            .unwrap_or(0.0);
        (levels * policy.level_m + roof, HeightSource::Levels)
    } else {
        (policy.default_m, HeightSource::Default)
    };
    let base = number("min_height")
        .or_else(|| count("building:min_level").map(|l| l * policy.level_m))
        .unwrap_or(0.0);
    (base < top).then_some((base, top, source))
}

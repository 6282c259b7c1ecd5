//! A vehicle's devices, as a run names them: `ideal` (savsim's feed as it was before sensors
//! were modelled: an exact, levelled 360-degree ring of 72 rays, up and down rays, ADS-B twice
//! a second exact and on time), or a list of presets with settings and of files of
//! `[[sensor]]` tables: `realsense-d435,tfmini-down,adsb-1090es:nacp=7:latency_s=1`.

use std::collections::BTreeSet;

use crate::sensors::device::{Device, Model};
use crate::sensors::spec::{DeviceSpec, SpecError};

/// A vehicle's sensors.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
#[serde(tag = "kind", content = "devices", rename_all = "kebab-case")]
pub enum Suite {
    /// The exact sensors savsim fed before (the default).
    #[default]
    Ideal,
    /// Modelled devices.
    Devices(Vec<Device>),
}

/// Why a list of sensors cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SuiteError {
    /// A device that is not valid.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A setting that is not `key=value`, or whose value is not a TOML value of its field.
    #[error("sensor {item:?}: setting {setting:?}: {why}")]
    Setting {
        /// The list's item.
        item: String,
        /// The setting.
        setting: String,
        /// What is wrong.
        why: String,
    },
    /// A file of `[[sensor]]` tables that could not be read or parsed.
    #[error("sensor file {path}: {why}")]
    File {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// Two devices of one name.
    #[error("two sensors are named {0:?}: give each its own `name`")]
    Duplicate(String),
    /// `ideal` among other devices.
    #[error("`ideal` is the exact feed as a whole: give it alone, or list devices")]
    IdealInList,
    /// Nothing named.
    #[error("no sensors named: give `ideal` or a list of presets and files")]
    Empty,
}

/// The `[[sensor]]` tables of a TOML document.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorFile {
    #[serde(default)]
    sensor: Vec<DeviceSpec>,
}

/// Devices from `[[sensor]]` tables in TOML text (a file's, or a scene's own section).
pub fn from_toml(text: &str) -> Result<Vec<DeviceSpec>, String> {
    toml::from_str::<SensorFile>(text)
        .map(|f| f.sensor)
        .map_err(|e| e.to_string())
}

impl Suite {
    /// The suite a run names (see the module's doc); `read` reads a file of `[[sensor]]`
    /// tables (an item ending in `.toml`).
    ///
    /// ```
    /// use savsim_core::sensors::suite::Suite;
    /// let none = |_: &str| Err("no files here".to_string());
    /// assert_eq!(Suite::parse("ideal", none).unwrap(), Suite::Ideal);
    /// let Suite::Devices(d) = Suite::parse("tfmini-down,adsb-1090es:nacp=7", none).unwrap() else {
    ///     panic!()
    /// };
    /// assert_eq!((d[0].name.as_str(), d[1].name.as_str()), ("tfmini-down", "adsb-1090es"));
    /// assert!(Suite::parse("adsb-1090es:nacp=12", none).unwrap_err().to_string().contains("nacp"));
    /// assert!(Suite::parse("laser-beam", none).is_err());
    /// ```
    pub fn parse(
        text: &str,
        read: impl Fn(&str) -> Result<String, String>,
    ) -> Result<Suite, SuiteError> {
        let items: Vec<&str> = split_outside(text, ',')
            .into_iter()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .collect();
        match items.as_slice() {
            [] => return Err(SuiteError::Empty),
            ["ideal"] => return Ok(Suite::Ideal),
            _ if items.contains(&"ideal") => return Err(SuiteError::IdealInList),
            _ => {}
        }
        let mut specs = Vec::new();
        for item in items {
            if item.to_ascii_lowercase().ends_with(".toml") {
                let file = |why: String| SuiteError::File {
                    path: item.to_owned(),
                    why,
                };
                let text = read(item).map_err(file)?;
                specs.extend(from_toml(&text).map_err(file)?);
            } else {
                specs.push(item_spec(item)?);
            }
        }
        Suite::from_specs(&specs)
    }

    /// The suite of these specs (each built; names unique).
    pub fn from_specs(specs: &[DeviceSpec]) -> Result<Suite, SuiteError> {
        if specs.is_empty() {
            return Err(SuiteError::Empty);
        }
        let devices = specs
            .iter()
            .map(DeviceSpec::build)
            .collect::<Result<Vec<Device>, SpecError>>()?;
        let mut names = BTreeSet::new();
        for d in &devices {
            if !names.insert(d.name.as_str()) {
                return Err(SuiteError::Duplicate(d.name.clone()));
            }
        }
        Ok(Suite::Devices(devices))
    }

    /// Its devices (none for `ideal`).
    pub fn devices(&self) -> &[Device] {
        match self {
            Suite::Ideal => &[],
            Suite::Devices(d) => d,
        }
    }

    /// True when a device measures distances.
    pub fn has_range(&self) -> bool {
        self.devices()
            .iter()
            .any(|d| matches!(d.model, Model::Range(_)))
    }
}

/// `text` cut at each `sep` outside a TOML array (`[...]`) and a quoted string, so that a
/// setting may hold an array (`fov_deg=[360,30]`) or a string with the separator in it.
///
/// ```
/// # use savsim_core::sensors::suite::split_outside;
/// assert_eq!(
///     split_outside("rplidar-a2:fov_deg=[360,0],tfmini", ','),
///     ["rplidar-a2:fov_deg=[360,0]", "tfmini"]
/// );
/// assert_eq!(split_outside("a:name=\"x:y\":rate_hz=5", ':'), ["a", "name=\"x:y\"", "rate_hz=5"]);
/// ```
pub fn split_outside(text: &str, sep: char) -> Vec<&str> {
    let (mut out, mut start, mut depth, mut quoted) = (Vec::new(), 0, 0usize, None);
    for (i, c) in text.char_indices() {
        match (c, quoted) {
            ('"' | '\'', None) => quoted = Some(c),
            (q, Some(open)) if q == open => quoted = None,
            (_, Some(_)) => {}
            ('[', None) => depth += 1,
            (']', None) => depth = depth.saturating_sub(1),
            (c, None) if c == sep && depth == 0 => {
                out.push(&text[start..i]);
                start = i + c.len_utf8();
            }
            _ => {}
        }
    }
    out.push(&text[start..]);
    out
}

/// `preset[:key=value...]` as a spec: the preset, and each setting as that TOML field.
fn item_spec(item: &str) -> Result<DeviceSpec, SuiteError> {
    let mut parts = split_outside(item, ':').into_iter();
    let preset = parts.next().unwrap_or_default().trim();
    let mut table = toml::Table::new();
    table.insert("preset".into(), toml::Value::String(preset.into()));
    for setting in parts {
        let bad = |why: String| SuiteError::Setting {
            item: item.to_owned(),
            setting: setting.to_owned(),
            why,
        };
        let (key, value) = setting
            .split_once('=')
            .ok_or_else(|| bad("give key=value".into()))?;
        let value: toml::Value = toml::from_str::<toml::Table>(&format!("v = {value}"))
            .map_err(|e| bad(e.to_string()))?
            .remove("v")
            .ok_or_else(|| bad("no value".into()))?;
        table.insert(key.trim().to_owned(), value);
    }
    toml::Value::Table(table)
        .try_into::<DeviceSpec>()
        .map_err(|e| SuiteError::Setting {
            item: item.to_owned(),
            setting: String::new(),
            why: e.to_string(),
        })
}

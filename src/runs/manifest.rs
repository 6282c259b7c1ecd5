//! Reading a manifest's rows: CSV with a header row (an empty cell is an absent value), TOML
//! `[[run]]` tables or a JSON array, told apart by the file's extension; the row type is the
//! command's (`batch::manifest::Run`, `study::manifest::StudyRow`).

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::{Error, Result};

/// The TOML form: `[[run]]` tables.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TomlManifest<T> {
    #[serde(default = "Vec::new")]
    run: Vec<T>,
}

/// The rows of a manifest file, and the directory its relative paths are relative to. The file
/// is read within `crate::files::MAX_TABLE_FILE_BYTES`.
pub fn read_rows<T: serde::de::DeserializeOwned>(path: &Path) -> Result<(Vec<T>, PathBuf)> {
    let text = crate::files::read_text(path, crate::files::MAX_TABLE_FILE_BYTES)
        .map_err(|e| Error::file(path, e))?;
    let bad = |why: String| Error::Usage(format!("manifest {}: {why}", path.display()));
    let rows = match path.extension().and_then(|e| e.to_str()) {
        Some("csv") => csv_rows(text.as_bytes()).map_err(|e| bad(e.to_string()))?,
        Some("toml") => {
            toml::from_str::<TomlManifest<T>>(&text)
                .map_err(|e| bad(e.to_string()))?
                .run
        }
        Some("json") => serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?,
        _ => return Err(bad("give a .csv, .toml or .json file".into())),
    };
    let base: PathBuf = path.parent().map(Path::to_path_buf).unwrap_or_default();
    Ok((rows, base))
}

/// Rows from CSV with a header row; an empty cell is an absent value.
pub fn csv_rows<T: serde::de::DeserializeOwned>(
    bytes: &[u8],
) -> std::result::Result<Vec<T>, csv::Error> {
    csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes)
        .deserialize()
        .collect()
}

/// Rows as CSV with a header row (what the generators write).
pub fn write_csv<T: serde::Serialize>(
    rows: &[T],
    out: impl std::io::Write,
) -> std::result::Result<(), csv::Error> {
    let mut w = csv::Writer::from_writer(out);
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}

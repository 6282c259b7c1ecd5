//! `--rerun-rows`: which rows of a study or batch are saved as rerun recordings, beside the
//! results in `OUT/rows/<index>-<id>.rrd`. `failed` cannot know a row's outcome before it is
//! flown, so every row is recorded while it flies and only those worth a look are kept; `all`
//! and a list of ids record only what they name (the other rows cost nothing extra).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::error::Error;

/// Which rows are kept as recordings.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RowChoice {
    /// Every row.
    All,
    /// Rows worth a look ([`crate::runs::summary::RowView::worth_a_look`]): not `pass` in a
    /// variant other than the nominal one, `pass` in the nominal one, or an error.
    Failed,
    /// The rows with these ids.
    Ids(BTreeSet<String>),
}

impl FromStr for RowChoice {
    type Err = Error;

    /// ```
    /// use savsim::runs::recordings::RowChoice;
    /// assert_eq!("all".parse::<RowChoice>().unwrap(), RowChoice::All);
    /// assert!("p1-nominal,p2-nominal".parse::<RowChoice>().unwrap().records("p2-nominal"));
    /// assert!(",".parse::<RowChoice>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, Error> {
        match s {
            "all" => Ok(RowChoice::All),
            "failed" => Ok(RowChoice::Failed),
            _ => {
                let ids: BTreeSet<String> = s
                    .split(',')
                    .map(str::trim)
                    .filter(|id| !id.is_empty())
                    .map(String::from)
                    .collect();
                if ids.is_empty() {
                    return Err(Error::Usage(format!(
                        "--rerun-rows {s:?}: give failed, all or row ids separated by commas"
                    )));
                }
                Ok(RowChoice::Ids(ids))
            }
        }
    }
}

impl RowChoice {
    /// Whether row `id` is recorded while it flies.
    pub fn records(&self, id: &str) -> bool {
        match self {
            RowChoice::All | RowChoice::Failed => true,
            RowChoice::Ids(ids) => ids.contains(id),
        }
    }

    /// Whether row `id`'s recording is kept, now that it is known how it `ended` in `variant`
    /// (`nominal` the variant compared against).
    pub fn keeps(&self, id: &str, variant: &str, ended: &str, nominal: &str) -> bool {
        match self {
            RowChoice::Failed => crate::runs::summary::RowView {
                variant: variant.into(),
                ended: ended.into(),
                ..Default::default()
            }
            .worth_a_look(nominal),
            _ => self.records(id),
        }
    }
}

/// The folder of a results directory that row recordings go to.
pub const RECORDINGS: &str = "rows";

/// Where row `index` (`id`)'s recording is kept in results directory `dir`.
pub fn recording_path(dir: &Path, index: u64, id: &str) -> PathBuf {
    dir.join(RECORDINGS)
        .join(format!("{}.rrd", crate::runs::row_name(index, id)))
}

/// Keep a recording made at `made` as row (`index`, `id`)'s in results directory `out`
/// (`out/rows/`, made when needed); the path it is kept at.
pub fn keep(made: &Path, out: &Path, index: u64, id: &str) -> std::io::Result<PathBuf> {
    let kept = recording_path(out, index, id);
    if let Some(parent) = kept.parent() {
        std::fs::create_dir_all(parent)?;
    }
    std::fs::rename(made, &kept)?;
    Ok(kept)
}

/// Record `session` for the rerun viewer to an .rrd file at `path` (a batch or study row's
/// recording). Needs a scene.
#[cfg(feature = "viz")]
pub fn record_to(session: &mut crate::session::Session, path: &Path) -> crate::error::Result<()> {
    use crate::viz::{logger, RerunTarget, VizOptions};
    let start = session
        .run_start()
        .ok_or_else(|| crate::error::Error::Usage("a recording needs a scene".into()))?;
    let target = RerunTarget::Save(path.to_path_buf());
    session.observe(Box::new(logger(&target, VizOptions::default(), start)?));
    Ok(())
}

/// Without the viewer's build (feature `viz`), no recording.
#[cfg(not(feature = "viz"))]
pub fn record_to(_: &mut crate::session::Session, _: &Path) -> crate::error::Result<()> {
    Err(crate::error::Error::Usage(
        "--rerun-rows: this savsim was built without rerun (feature viz)".into(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_keeps_what_did_not_go_as_meant() {
        let c = RowChoice::Failed;
        assert!(c.records("any"));
        assert!(c.keeps("a", "mitigated", "collision", "nominal"));
        assert!(c.keeps("a", "mitigated", "soft_fail", "nominal"));
        assert!(!c.keeps("a", "mitigated", "pass", "nominal"));
        assert!(c.keeps("a", "nominal", "pass", "nominal"));
        assert!(!c.keeps("a", "nominal", "collision", "nominal"));
        assert!(c.keeps("a", "nominal", "error", "nominal"));
    }

    #[test]
    fn ids_record_and_keep_only_themselves() {
        let c: RowChoice = " a , b ".parse().unwrap();
        assert!(c.records("a") && c.records("b") && !c.records("c"));
        assert!(c.keeps("a", "mitigated", "pass", "nominal"));
        assert!(!c.keeps("c", "mitigated", "collision", "nominal"));
    }
}

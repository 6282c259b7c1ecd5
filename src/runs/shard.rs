//! Which part of a manifest this process runs, and the file it writes.
//!
//! A manifest of `n` runs is cut into `count` contiguous shards; shard `k` (from 0) is rows
//! `k*n/count .. (k+1)*n/count` and is written to `part-{k}-of-{count}.parquet` (zero-padded)
//! atomically, so a finished shard is a whole file and a re-run of a failed array skips it.

use std::ops::Range;

use crate::error::{Error, Result};

/// One shard of a manifest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which, from 0.
    pub index: usize,
    /// Of how many.
    pub count: usize,
}

impl Shard {
    /// The whole manifest.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// The shard `--shard` names: `K/N`, or `N` with `K` from the scheduler (Slurm's
    /// `SLURM_ARRAY_TASK_ID` less `SLURM_ARRAY_TASK_MIN`, over `SLURM_ARRAY_TASK_STEP`; or
    /// Kubernetes' `JOB_COMPLETION_INDEX`). Without `--shard`, a Slurm array task takes its index and count
    /// from Slurm; anything else runs the whole manifest. `env` reads a variable.
    ///
    /// ```
    /// use savsim::runs::shard::Shard;
    /// let none = |_: &str| None;
    /// assert_eq!(Shard::from_args(Some("2/8"), none).unwrap(), Shard { index: 2, count: 8 });
    /// let k8s = |v: &str| (v == "JOB_COMPLETION_INDEX").then(|| "3".to_string());
    /// assert_eq!(Shard::from_args(Some("4"), k8s).unwrap(), Shard { index: 3, count: 4 });
    /// assert!(Shard::from_args(Some("8/8"), none).is_err());
    /// // Slurm `--array=10-40:10`: task 30 is shard 2 of 4.
    /// let slurm = |v: &str| match v {
    ///     "SLURM_ARRAY_TASK_ID" => Some("30".to_string()),
    ///     "SLURM_ARRAY_TASK_MIN" | "SLURM_ARRAY_TASK_STEP" => Some("10".to_string()),
    ///     "SLURM_ARRAY_TASK_COUNT" => Some("4".to_string()),
    ///     _ => None,
    /// };
    /// assert_eq!(Shard::from_args(None, slurm).unwrap(), Shard { index: 2, count: 4 });
    /// ```
    pub fn from_args(arg: Option<&str>, env: impl Fn(&str) -> Option<String>) -> Result<Shard> {
        let number = |what: &str, text: &str| {
            text.trim().parse::<usize>().map_err(|_| {
                Error::Usage(format!("--shard: {what} {text:?} is not a whole number"))
            })
        };
        let from_scheduler = || -> Result<Option<usize>> {
            if let Some(id) = env("SLURM_ARRAY_TASK_ID") {
                let min = env("SLURM_ARRAY_TASK_MIN")
                    .map_or(Ok(0), |m| number("SLURM_ARRAY_TASK_MIN", &m))?;
                // `--array=0-99:4` numbers its tasks 0, 4, 8, ...
                let step = env("SLURM_ARRAY_TASK_STEP")
                    .map_or(Ok(1), |m| number("SLURM_ARRAY_TASK_STEP", &m))?
                    .max(1);
                let id = number("SLURM_ARRAY_TASK_ID", &id)?;
                return id.checked_sub(min).map(|k| Some(k / step)).ok_or_else(|| {
                    Error::Usage(format!(
                        "SLURM_ARRAY_TASK_ID {id} is below SLURM_ARRAY_TASK_MIN {min}"
                    ))
                });
            }
            env("JOB_COMPLETION_INDEX")
                .map(|k| number("JOB_COMPLETION_INDEX", &k))
                .transpose()
        };
        let shard = match arg {
            Some(text) => match text.split_once('/') {
                Some((k, n)) => Shard {
                    index: number("index", k)?,
                    count: number("count", n)?,
                },
                None => Shard {
                    index: from_scheduler()?.ok_or_else(|| {
                        Error::Usage(format!(
                            "--shard {text}: give K/{text}, or run as a Slurm array task or a \
                             Kubernetes indexed job (SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX)"
                        ))
                    })?,
                    count: number("count", text)?,
                },
            },
            None => match (env("SLURM_ARRAY_TASK_ID"), env("SLURM_ARRAY_TASK_COUNT")) {
                (Some(_), Some(count)) => Shard {
                    index: from_scheduler()?.unwrap_or(0),
                    count: number("SLURM_ARRAY_TASK_COUNT", &count)?,
                },
                _ => Shard::WHOLE,
            },
        };
        if shard.count == 0 || shard.index >= shard.count {
            return Err(Error::Usage(format!(
                "shard {}/{}: give K/N with 0 <= K < N",
                shard.index, shard.count
            )));
        }
        Ok(shard)
    }

    /// The rows of a manifest of `len` runs in this shard.
    ///
    /// ```
    /// use savsim::runs::shard::Shard;
    /// let parts: Vec<_> = (0..3).map(|k| Shard { index: k, count: 3 }.rows(10)).collect();
    /// assert_eq!(parts, [0..3, 3..6, 6..10]);
    /// ```
    pub fn rows(&self, len: usize) -> Range<usize> {
        let at = |k: usize| (k as u128 * len as u128 / self.count as u128) as usize;
        at(self.index)..at(self.index + 1)
    }

    /// The shard's file name.
    pub fn file_name(&self) -> String {
        format!("part-{:05}-of-{:05}.parquet", self.index, self.count)
    }
}

//! `savsim study MANIFEST --until-converged PCT`: the manifest's pairs flown in rounds, in the
//! order they first appear, until every risk ratio judged (`--converge-on`: NMAC and loss of
//! well clear by default, the collision ratio for obstacle studies; each variant against the
//! nominal one) has a 95% interval whose half-width is within `PCT` percent of its value. The manifest is the budget: a study that has flown it all stops there, converged or
//! not. Judged after each round from the second on: the percentile bootstrap of a few pairs
//! can give a degenerate interval (every pair an NMAC under both variants gives `1 [1, 1]`).
//!
//! ```
//! use savsim::daa::ratios::Estimate;
//! use savsim::study::converge::half_width_pct;
//! let e = Estimate { value: Some(0.5), low: Some(0.45), high: Some(0.55) };
//! assert!((half_width_pct(&e).unwrap() - 10.0).abs() < 1e-9);
//! // Unbounded or undefined: never within any bound.
//! assert_eq!(half_width_pct(&Estimate { high: None, ..e }), None);
//! ```

use std::collections::HashMap;

use crate::daa::ratios::{Estimate, VariantRatios};
use crate::runs::summary::Ratio;
use crate::study::manifest::StudyRow;

/// Rounds flown before the first judgement.
pub const MIN_ROUNDS: usize = 2;

/// The manifest's rows cut into rounds of `pairs_per_round` pairs (a row's pair is its
/// `pair`, else its id, as the summary reads it), pairs in the order they first appear:
/// each round the indexes of its rows, in manifest order.
///
/// ```
/// use savsim::study::{converge::rounds, manifest::StudyRow};
/// let row = |pair: &str| StudyRow { pair: Some(pair.into()), ..Default::default() };
/// let rows = [row("a"), row("b"), row("a"), row("c"), row("b")];
/// assert_eq!(rounds(&rows, 2), vec![vec![0, 1, 2, 4], vec![3]]);
/// ```
pub fn rounds(rows: &[StudyRow], pairs_per_round: usize) -> Vec<Vec<usize>> {
    let mut round_of: HashMap<String, usize> = HashMap::new();
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (index, row) in rows.iter().enumerate() {
        let pair = row.pair_or(index);
        let next = round_of.len() / pairs_per_round.max(1);
        let round = *round_of.entry(pair).or_insert(next);
        if round == out.len() {
            out.push(Vec::new());
        }
        out[round].push(index);
    }
    out
}

/// An interval's half-width, `(high - low) / 2`, in percent of its value: `None` when the
/// value is undefined or a bound unbounded. A value of 0 with the interval `[0, 0]` is 0%;
/// with any width, unbounded (`None`).
pub fn half_width_pct(e: &Estimate) -> Option<f64> {
    let (value, low, high) = (e.value?, e.low?, e.high?);
    let half = (high - low) / 2.0;
    if value > 0.0 {
        Some(100.0 * half / value)
    } else {
        (half == 0.0).then_some(0.0)
    }
}

/// One ratio as judged.
#[derive(Debug, Clone, PartialEq)]
pub struct Judged {
    /// `mitigated / nominal NMAC ratio` and the like.
    pub name: String,
    /// Its half-width in percent of its value (`None`: undefined or unbounded).
    pub half_width_pct: Option<f64>,
}

/// The `on` ratios of every variant in `ratios`, judged against `pct`: whether all are within
/// it (false when there is none), and each as judged.
///
/// ```
/// use savsim::daa::ratios::{Estimate, VariantRatios};
/// use savsim::runs::summary::Ratio;
/// use savsim::study::converge::judge;
/// let e = |value: f64, low: f64, high: f64| Estimate { value: Some(value), low: Some(low), high: Some(high) };
/// let r = VariantRatios {
///     variant: "mitigated".into(), pairs: 400,
///     nmac_ratio: e(0.2, 0.19, 0.21), lowc_ratio: e(0.5, 0.45, 0.55),
///     collision_ratio: Estimate { value: None, low: None, high: None },
/// };
/// let (within, judged) = judge(&[r.clone()], &Ratio::DEFAULT, 5.0, "nominal");
/// assert!(!within); // the LoWC ratio's half-width is 10% of its value
/// assert_eq!(judged.len(), 2);
/// assert!(judge(&[r.clone()], &Ratio::DEFAULT, 11.0, "nominal").0);
/// // An undefined ratio is never within.
/// assert!(!judge(&[r], &[Ratio::Collision], 100.0, "nominal").0);
/// ```
pub fn judge(
    ratios: &[VariantRatios],
    on: &[Ratio],
    pct: f64,
    nominal: &str,
) -> (bool, Vec<Judged>) {
    let judged: Vec<Judged> = ratios
        .iter()
        .flat_map(|r| {
            on.iter().map(move |which| {
                let (what, e) = which.of(r);
                Judged {
                    name: format!("{} / {nominal} {what} ratio", r.variant),
                    half_width_pct: half_width_pct(e),
                }
            })
        })
        .collect();
    let within = !judged.is_empty()
        && judged
            .iter()
            .all(|j| j.half_width_pct.is_some_and(|h| h <= pct));
    (within, judged)
}

/// The judged ratios as one line: `mitigated / nominal NMAC ratio ±3.1%, ... ±unbounded`.
pub fn line(judged: &[Judged]) -> String {
    let one = |j: &Judged| match j.half_width_pct {
        Some(h) => format!("{} ±{h:.1}%", j.name),
        None => format!("{} ±unbounded", j.name),
    };
    judged.iter().map(one).collect::<Vec<_>>().join(", ")
}

/// A round's file name in the results directory.
pub fn file_name(round: usize) -> String {
    format!("round-{round:05}.parquet")
}

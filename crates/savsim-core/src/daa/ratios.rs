//! Risk ratios over many encounters (DO-365 Appendix L; MIT LL DEGAS): for each variant, the
//! weighted rate of NMAC and of loss of well clear, and for each variant against the nominal
//! one, `ratio = sum(w * event | variant) / sum(w * event | nominal)` over the encounters
//! (`pair`s) flown under both. 95% intervals by a percentile bootstrap over pairs (2000
//! resamples, a fixed seed: the same answer every run); a resample with no nominal event has
//! an undefined ratio, which counts as unbounded, so an interval whose bound falls among them
//! is open on that side (`None`).
//!
//! An encounter flown more than once under one variant (a repeated `pair`, as a study's
//! `repeat` makes) enters a ratio once, as the share of its flights with the event and their
//! mean weight: repeats estimate that encounter's probability of the event, and are never
//! dropped. Rates count every flight as an encounter of its own.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// One encounter flown under one variant.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The encounter: outcomes with one `pair` are the same encounter under different variants.
    pub pair: String,
    /// The variant (`nominal`, `mitigated`, ...).
    pub variant: String,
    /// Its importance weight (1 when the encounters were drawn from the model itself).
    pub weight: f64,
    /// Whether it had an NMAC.
    pub nmac: bool,
    /// Whether it lost well clear.
    pub lowc: bool,
    /// Whether it collided (with anything: an obstacle, terrain or a moving body).
    pub collision: bool,
}

/// A value and its 95% interval (`None` ends when the bootstrap cannot give them).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Estimate {
    /// The value on all the data (`None` when undefined: a zero denominator).
    pub value: Option<f64>,
    /// 2.5th percentile of the bootstrap (`None`: unbounded, or no data).
    pub low: Option<f64>,
    /// 97.5th percentile of the bootstrap (`None`: unbounded, or no data).
    pub high: Option<f64>,
}

impl Estimate {
    /// The value and its interval as text, `decimals` after the point: `0.25 [0.1, 0.4]`,
    /// `2.5 [1.2, unbounded)` when the upper bound is unbounded, `undefined` without a value.
    ///
    /// ```
    /// use savsim_core::daa::ratios::Estimate;
    /// let e = Estimate { value: Some(0.5), low: Some(0.25), high: None };
    /// assert_eq!(e.text(2), "0.50 [0.25, unbounded)");
    /// ```
    pub fn text(&self, decimals: usize) -> String {
        let Some(v) = self.value else {
            return "undefined".into();
        };
        match (self.low, self.high) {
            (Some(l), Some(h)) => format!("{v:.decimals$} [{l:.decimals$}, {h:.decimals$}]"),
            (Some(l), None) => format!("{v:.decimals$} [{l:.decimals$}, unbounded)"),
            _ => format!("{v:.decimals$} [interval unbounded]"),
        }
    }
}

/// One variant's rates.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct VariantRates {
    /// The variant.
    pub variant: String,
    /// Encounters flown under it.
    pub encounters: usize,
    /// Weighted NMAC rate.
    pub nmac_rate: Estimate,
    /// Weighted loss-of-well-clear rate.
    pub lowc_rate: Estimate,
    /// Weighted collision rate.
    pub collision_rate: Estimate,
}

/// One variant against the nominal one, over the pairs flown under both.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct VariantRatios {
    /// The variant.
    pub variant: String,
    /// Pairs flown under both.
    pub pairs: usize,
    /// P(NMAC | variant) / P(NMAC | nominal).
    pub nmac_ratio: Estimate,
    /// P(LoWC | variant) / P(LoWC | nominal).
    pub lowc_ratio: Estimate,
    /// P(collision | variant) / P(collision | nominal).
    pub collision_ratio: Estimate,
}

/// Bootstrap resamples.
pub const RESAMPLES: usize = 2000;
/// The bootstrap's seed (ChaCha8): the same intervals on every run.
pub const BOOTSTRAP_SEED: u64 = 0x5a75_1a7e;

/// A rate or a ratio as a quotient of sums, each item its (numerator, denominator) terms:
/// a weighted rate's are (w * event, w), a ratio's (w * event under the variant, w * event
/// under the nominal one). Undefined when the denominator's sum is not positive.
type Terms = (f64, f64);

/// sum(numerators) / sum(denominators), summed in the items' order.
fn quotient(terms: impl Iterator<Item = Terms>) -> Option<f64> {
    // From -0.0 as `Iterator::sum` does; + 0.0: an empty (or all -0.0) sum is then 0.0.
    let (num, den) = terms.fold((-0.0f64, -0.0f64), |(n, d), (a, b)| (n + a, d + b));
    let num = num + 0.0;
    (den > 0.0).then(|| num / den)
}

/// The quotient on the data and its percentile-bootstrap interval. A resample whose quotient
/// is undefined (a ratio whose resample drew no nominal event) counts as unbounded: it sorts
/// above every finite value, so a bound that falls on one is `None` (unbounded). Each resample
/// is summed as it is drawn, nothing copied.
fn estimate(items: &[Terms]) -> Estimate {
    let value = quotient(items.iter().copied());
    if items.is_empty() {
        return Estimate {
            value,
            low: None,
            high: None,
        };
    }
    let mut rng = ChaCha8Rng::seed_from_u64(BOOTSTRAP_SEED);
    let mut stats: Vec<f64> = Vec::with_capacity(RESAMPLES);
    for _ in 0..RESAMPLES {
        let drawn = (0..items.len()).map(|_| items[rng.random_range(0..items.len())]);
        stats.push(quotient(drawn).unwrap_or(f64::INFINITY));
    }
    stats.sort_by(f64::total_cmp);
    let (low, high) = percentile_bounds(&stats);
    Estimate { value, low, high }
}

/// The 2.5th and 97.5th percentiles of sorted resamples (the nearest rank below, as
/// `floor(q * n)`), `None` where the percentile is unbounded.
fn percentile_bounds(sorted: &[f64]) -> (Option<f64>, Option<f64>) {
    let at = |q: f64| {
        let i = ((q * sorted.len() as f64) as usize).min(sorted.len() - 1);
        Some(sorted[i]).filter(|v| v.is_finite())
    };
    (at(0.025), at(0.975))
}

/// Every variant's rates, in name order.
///
/// ```
/// use savsim_core::daa::ratios::{rates, Outcome};
/// let o = |pair: &str, variant: &str, nmac: bool| Outcome {
///     pair: pair.into(), variant: variant.into(), weight: 1.0, nmac, lowc: nmac, collision: false,
/// };
/// let r = rates(&[o("a", "nominal", true), o("b", "nominal", false)]);
/// assert_eq!(r[0].nmac_rate.value, Some(0.5));
/// ```
pub fn rates(outcomes: &[Outcome]) -> Vec<VariantRates> {
    let mut by: BTreeMap<&str, Vec<&Outcome>> = BTreeMap::new();
    for o in outcomes {
        by.entry(o.variant.as_str()).or_default().push(o);
    }
    by.into_iter()
        .map(|(variant, rows)| {
            // A weighted rate: sum(w * event) / sum(w).
            let of = |f: fn(&Outcome) -> bool| -> Vec<Terms> {
                rows.iter()
                    .map(|o| (o.weight * share(&[*o], f), o.weight))
                    .collect()
            };
            let (nmac, lowc, collision) = (of(|o| o.nmac), of(|o| o.lowc), of(|o| o.collision));
            VariantRates {
                variant: variant.into(),
                encounters: rows.len(),
                nmac_rate: estimate(&nmac),
                lowc_rate: estimate(&lowc),
                collision_rate: estimate(&collision),
            }
        })
        .collect()
}

/// Every other variant against `nominal`, in name order, over the pairs flown under both.
///
/// ```
/// use savsim_core::daa::ratios::{ratios, Outcome};
/// let o = |pair: &str, variant: &str, nmac: bool| Outcome {
///     pair: pair.into(), variant: variant.into(), weight: 1.0, nmac, lowc: false, collision: false,
/// };
/// // 4 NMACs unmitigated, 1 mitigated: ratio 0.25.
/// let mut all = Vec::new();
/// for (k, mitigated) in [(0, true), (1, false), (2, false), (3, false)] {
///     all.push(o(&k.to_string(), "nominal", true));
///     all.push(o(&k.to_string(), "mitigated", mitigated));
/// }
/// let r = ratios(&all, "nominal");
/// assert_eq!(r[0].nmac_ratio.value, Some(0.25));
/// assert_eq!(r[0].lowc_ratio.value, None);
/// ```
pub fn ratios(outcomes: &[Outcome], nominal: &str) -> Vec<VariantRatios> {
    let mut by_pair: BTreeMap<&str, BTreeMap<&str, Vec<&Outcome>>> = BTreeMap::new();
    for o in outcomes {
        by_pair
            .entry(o.pair.as_str())
            .or_default()
            .entry(o.variant.as_str())
            .or_default()
            .push(o);
    }
    let mut variants: Vec<&str> = outcomes
        .iter()
        .map(|o| o.variant.as_str())
        .filter(|v| *v != nominal)
        .collect();
    variants.sort_unstable();
    variants.dedup();
    variants
        .into_iter()
        .map(|variant| {
            let both: Vec<(&[&Outcome], &[&Outcome])> = by_pair
                .values()
                .filter_map(|m| Some((m.get(variant)?.as_slice(), m.get(nominal)?.as_slice())))
                .collect();
            // sum(w * event | variant) / sum(w * event | nominal).
            let of = |f: fn(&Outcome) -> bool| -> Vec<Terms> {
                both.iter()
                    .map(|(v, n)| (mean_weight(v) * share(v, f), mean_weight(n) * share(n, f)))
                    .collect()
            };
            VariantRatios {
                variant: variant.into(),
                pairs: both.len(),
                nmac_ratio: estimate(&of(|o| o.nmac)),
                lowc_ratio: estimate(&of(|o| o.lowc)),
                collision_ratio: estimate(&of(|o| o.collision)),
            }
        })
        .collect()
}

/// The share of `flights` (one encounter under one variant, flown once or more) in which the
/// event happened.
fn share(flights: &[&Outcome], event: fn(&Outcome) -> bool) -> f64 {
    let hits = flights.iter().filter(|o| event(o)).count();
    hits as f64 / flights.len().max(1) as f64
}

/// The mean weight of an encounter's flights under one variant.
fn mean_weight(flights: &[&Outcome]) -> f64 {
    flights.iter().map(|o| o.weight).sum::<f64>() / flights.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(pair: usize, variant: &str, nmac: bool) -> Outcome {
        Outcome {
            // Zero-padded: the module orders pairs by name, the reference by number.
            pair: format!("{pair:03}"),
            variant: variant.into(),
            weight: 1.0,
            nmac,
            lowc: false,
            collision: false,
        }
    }

    /// 40 pairs, 3 nominal NMACs and 10 mitigated ones: about 4% of resamples draw no nominal
    /// NMAC, so the upper bound is unbounded. The reference draws the same resamples and
    /// computes each ratio by counting, with no helper of the module.
    #[test]
    fn undefined_resamples_count_as_unbounded_as_a_plain_bootstrap_says() {
        let n = 40;
        let mut all = Vec::new();
        for k in 0..n {
            all.push(outcome(k, "nominal", k < 3));
            all.push(outcome(k, "mitigated", k % 4 == 0));
        }
        let r = &ratios(&all, "nominal")[0];

        let mut rng = ChaCha8Rng::seed_from_u64(BOOTSTRAP_SEED);
        let mut reference: Vec<f64> = (0..RESAMPLES)
            .map(|_| {
                let (mut num, mut den) = (0u32, 0u32);
                for _ in 0..n {
                    let k = rng.random_range(0..n);
                    num += u32::from(k % 4 == 0);
                    den += u32::from(k < 3);
                }
                if den == 0 {
                    f64::INFINITY
                } else {
                    f64::from(num) / f64::from(den)
                }
            })
            .collect();
        reference.sort_by(f64::total_cmp);
        let undefined = reference.iter().filter(|v| v.is_infinite()).count();
        assert!(
            (50..=100).contains(&undefined),
            "{undefined} undefined resamples"
        );
        let pick =
            |q: f64| Some(reference[(q * RESAMPLES as f64) as usize]).filter(|v| v.is_finite());
        assert_eq!(r.nmac_ratio.value, Some(10.0 / 3.0));
        assert!(pick(0.025).is_some_and(|low| low > 0.0));
        assert_eq!(r.nmac_ratio.low, pick(0.025));
        assert_eq!(
            r.nmac_ratio.high, None,
            "the upper bound falls among the undefined"
        );
        assert_eq!(pick(0.975), None);
    }

    #[test]
    fn a_repeated_pair_enters_a_ratio_as_the_share_of_its_flights() {
        // Pair 0 flown three times mitigated (one NMAC), once nominal (an NMAC); pair 1 once
        // each (NMAC nominal, none mitigated).
        let all = [
            outcome(0, "nominal", true),
            outcome(0, "mitigated", true),
            outcome(0, "mitigated", false),
            outcome(0, "mitigated", false),
            outcome(1, "nominal", true),
            outcome(1, "mitigated", false),
        ];
        let r = &ratios(&all, "nominal")[0];
        assert_eq!(r.pairs, 2);
        // (1/3 + 0) / (1 + 1): the last flight alone would have said 0.
        assert_eq!(r.nmac_ratio.value, Some((1.0 / 3.0) / 2.0));
        // Rates count every flight.
        let rates = rates(&all);
        let mitigated = rates.iter().find(|v| v.variant == "mitigated").unwrap();
        assert_eq!(mitigated.encounters, 4);
        assert_eq!(mitigated.nmac_rate.value, Some(0.25));
    }
}

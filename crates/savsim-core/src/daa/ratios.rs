//! Risk ratios over many encounters (DO-365 Appendix L; MIT LL DEGAS): for each variant, the
//! weighted rate of NMAC and of loss of well clear, and for each variant against the nominal
//! one, `ratio = sum(w * event | variant) / sum(w * event | nominal)` over the encounters
//! (`pair`s) flown under both. 95% intervals by a percentile bootstrap over pairs (2000
//! resamples, a fixed seed: the same answer every run).

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
    /// 2.5th percentile of the bootstrap.
    pub low: Option<f64>,
    /// 97.5th percentile of the bootstrap.
    pub high: Option<f64>,
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
const SEED: u64 = 0x5a75_1a7e;

/// A weighted rate over rows: sum(w * event) / sum(w).
fn rate(rows: &[Weighted]) -> Option<f64> {
    let total: f64 = rows.iter().map(|r| r.0).sum();
    // + 0.0: an empty sum of floats is -0.0.
    let hits: f64 = rows.iter().filter(|r| r.1).map(|r| r.0).sum::<f64>() + 0.0;
    (total > 0.0).then(|| hits / total)
}

/// A weight and whether the event happened.
type Weighted = (f64, bool);

/// A ratio over pairs (the variant's, the nominal's): sum(w * event | variant) /
/// sum(w * event | nominal).
fn ratio(pairs: &[(Weighted, Weighted)]) -> Option<f64> {
    let num: f64 = pairs.iter().filter(|p| p.0 .1).map(|p| p.0 .0).sum::<f64>() + 0.0;
    let den: f64 = pairs.iter().filter(|p| p.1 .1).map(|p| p.1 .0).sum();
    (den > 0.0).then(|| num / den)
}

/// The statistic on the data and its percentile-bootstrap interval.
fn estimate<T: Clone>(items: &[T], stat: impl Fn(&[T]) -> Option<f64>) -> Estimate {
    let value = stat(items);
    if items.is_empty() {
        return Estimate {
            value,
            low: None,
            high: None,
        };
    }
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut sample = Vec::with_capacity(items.len());
    let mut stats: Vec<f64> = Vec::with_capacity(RESAMPLES);
    for _ in 0..RESAMPLES {
        sample.clear();
        sample.extend((0..items.len()).map(|_| items[rng.random_range(0..items.len())].clone()));
        if let Some(s) = stat(&sample) {
            stats.push(s);
        }
    }
    // Resamples with an undefined statistic (no nominal event drawn) count as unbounded.
    if stats.len() * 20 < RESAMPLES * 19 {
        return Estimate {
            value,
            low: None,
            high: None,
        };
    }
    stats.sort_by(f64::total_cmp);
    let at = |q: f64| stats[((q * (RESAMPLES as f64)) as usize).min(stats.len() - 1)];
    Estimate {
        value,
        low: Some(at(0.025)),
        high: Some(at(0.975)),
    }
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
            let nmac: Vec<Weighted> = rows.iter().map(|o| (o.weight, o.nmac)).collect();
            let lowc: Vec<Weighted> = rows.iter().map(|o| (o.weight, o.lowc)).collect();
            let collision: Vec<Weighted> = rows.iter().map(|o| (o.weight, o.collision)).collect();
            VariantRates {
                variant: variant.into(),
                encounters: rows.len(),
                nmac_rate: estimate(&nmac, rate),
                lowc_rate: estimate(&lowc, rate),
                collision_rate: estimate(&collision, rate),
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
    let mut by_pair: BTreeMap<&str, BTreeMap<&str, &Outcome>> = BTreeMap::new();
    for o in outcomes {
        by_pair
            .entry(o.pair.as_str())
            .or_default()
            .insert(o.variant.as_str(), o);
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
            let both: Vec<(&Outcome, &Outcome)> = by_pair
                .values()
                .filter_map(|m| Some((*m.get(variant)?, *m.get(nominal)?)))
                .collect();
            let of = |f: fn(&Outcome) -> bool| -> Vec<(Weighted, Weighted)> {
                both.iter()
                    .map(|(v, n)| ((v.weight, f(v)), (n.weight, f(n))))
                    .collect()
            };
            VariantRatios {
                variant: variant.into(),
                pairs: both.len(),
                nmac_ratio: estimate(&of(|o| o.nmac), ratio),
                lowc_ratio: estimate(&of(|o| o.lowc), ratio),
                collision_ratio: estimate(&of(|o| o.collision), ratio),
            }
        })
        .collect()
}

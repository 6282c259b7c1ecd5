//! What ticks cost, kept as a histogram: a run of any length holds a few kilobytes, never one
//! number per tick.

use hdrhistogram::Histogram;

/// Per-tick costs, nanoseconds (three significant digits, up to an hour a tick).
#[derive(Debug, Clone)]
pub struct TickCosts {
    histogram: Histogram<u64>,
}

impl Default for TickCosts {
    fn default() -> Self {
        Self {
            histogram: Histogram::new_with_bounds(1, 3_600_000_000_000, 3)
                .expect("fixed, valid bounds"),
        }
    }
}

impl TickCosts {
    /// Count one tick that cost `ns` nanoseconds (clamped into the histogram's range).
    pub fn record(&mut self, ns: u64) {
        self.histogram.saturating_record(ns.max(1));
    }

    /// Ticks counted.
    pub fn len(&self) -> u64 {
        self.histogram.len()
    }

    /// True when no tick was counted.
    pub fn is_empty(&self) -> bool {
        self.histogram.is_empty()
    }

    /// Median and 99th percentile, microseconds (0, 0 when empty).
    ///
    /// ```
    /// let mut costs = savsim::costs::TickCosts::default();
    /// for ns in 1..=1000u64 {
    ///     costs.record(ns * 1000);
    /// }
    /// let (median_us, p99_us) = costs.percentiles_us();
    /// assert!((median_us - 500.0).abs() < 1.0 && (p99_us - 990.0).abs() < 1.0);
    /// ```
    pub fn percentiles_us(&self) -> (f64, f64) {
        if self.histogram.is_empty() {
            return (0.0, 0.0);
        }
        let at = |q: f64| self.histogram.value_at_quantile(q) as f64 / 1e3;
        (at(0.5), at(0.99))
    }
}

/// Median and 99th percentile of a bounded set of costs (the bench's flights), microseconds,
/// exactly.
pub fn percentiles_us(costs_ns: &[u64]) -> (f64, f64) {
    if costs_ns.is_empty() {
        return (0.0, 0.0);
    }
    let mut sorted = costs_ns.to_vec();
    sorted.sort_unstable();
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize] as f64 / 1e3;
    (at(0.5), at(0.99))
}

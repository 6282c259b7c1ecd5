//! The error processes every device is built from: a first-order Gauss-Markov error stepped at
//! the device's instants, a bias drawn once per run, and quantisation. Each draw is keyed by
//! its instant ([`Draws`]), so an error is a function of the seed and of the vehicle's clock.

use crate::sensors::draws::Draws;

/// A first-order Gauss-Markov error (DO-365 Appendix Q as MIT LL's DEGAS models it): at the
/// first instant `e[0] = sigma w[0]` (the stationary distribution), then
/// `e[k+1] = phi e[k] + sigma sqrt(1 - phi^2) w[k+1]` with `phi = exp(-dt / tau)`; `tau = 0`
/// is white noise of `sigma`. Units are the channel's.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GaussMarkov {
    /// Standard deviation, the channel's unit.
    pub sigma: f64,
    /// Correlation time, seconds (0: white).
    pub tau_s: f64,
}

/// Where a [`GaussMarkov`] error is: its last instant and value.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MarkovState {
    last: Option<(u64, f64)>,
}

/// The most instants an error steps through at once; past this it starts again from its
/// stationary distribution at the instant asked (a gap of days on a fast device).
pub const MAX_STEPS: u64 = 1 << 22;

impl GaussMarkov {
    /// No error.
    pub const ZERO: GaussMarkov = GaussMarkov {
        sigma: 0.0,
        tau_s: 0.0,
    };

    /// `phi` for instants `dt_s` apart.
    pub fn phi(&self, dt_s: f64) -> f64 {
        if self.tau_s > 0.0 {
            libm::exp(-dt_s / self.tau_s)
        } else {
            0.0
        }
    }

    /// The error at instant `k` (instants `dt_s` apart from instant 0, the start of the
    /// vehicle's clock), stepping `state` through every instant since its last (from instant 0
    /// the first time), each with its own draw of `stream`: the value at `k` does not depend on
    /// which instants were asked before. An instant before the last starts again from 0.
    ///
    /// ```
    /// use savsim_core::sensors::draws::Draws;
    /// use savsim_core::sensors::errors::{GaussMarkov, MarkovState};
    /// let gm = GaussMarkov { sigma: 2.0, tau_s: 5.0 };
    /// let (mut a, mut b) = (MarkovState::default(), MarkovState::default());
    /// let draws = Draws::new(1);
    /// let every: Vec<f64> = (0..50).map(|k| gm.at(&mut a, &draws, 9, k, 0.1)).collect();
    /// // Asked only every seventh instant, the same values there.
    /// for k in (0..50).step_by(7) {
    ///     assert_eq!(gm.at(&mut b, &draws, 9, k, 0.1), every[k as usize]);
    /// }
    /// ```
    pub fn at(
        &self,
        state: &mut MarkovState,
        draws: &Draws,
        stream: u64,
        k: u64,
        dt_s: f64,
    ) -> f64 {
        if self.sigma == 0.0 {
            return 0.0;
        }
        let (mut i, mut e) = match state.last {
            Some((last, e)) if last <= k && k - last <= MAX_STEPS => (last, e),
            _ => {
                let start = k.saturating_sub(MAX_STEPS);
                (start, self.sigma * draws.normal(stream, start))
            }
        };
        let phi = self.phi(dt_s);
        let gain = self.sigma * libm::sqrt(1.0 - phi * phi);
        while i < k {
            i += 1;
            e = phi * e + gain * draws.normal(stream, i);
        }
        state.last = Some((k, e));
        e
    }
}

/// A bias drawn once per run, uniform in `[-half, half]` (DEGAS's per-encounter bias; the
/// field it calls a standard deviation is this half-width).
pub fn uniform_bias(draws: &Draws, stream: u64, half: f64) -> f64 {
    if half == 0.0 {
        0.0
    } else {
        draws.symmetric(stream, 0, half)
    }
}

/// `x` rounded to the nearest multiple of `quantum` (no rounding for 0).
///
/// ```
/// use savsim_core::sensors::errors::quantise;
/// assert_eq!(quantise(112.4, 25.0), 100.0);
/// assert_eq!(quantise(112.6, 25.0), 125.0);
/// assert_eq!(quantise(1.23456, 0.0), 1.23456);
/// ```
pub fn quantise(x: f64, quantum: f64) -> f64 {
    if quantum > 0.0 {
        (x / quantum).round() * quantum
    } else {
        x
    }
}

/// The standard deviation per horizontal axis of a position whose 95% bound is `bound95_m`:
/// the bound of a circular normal's radius, `bound95 / sqrt(-2 ln 0.05)`, 2.448 (NACp 8's 92.6
/// m gives 37.8 m; NACp 7's 185.2 m, 75.7 m).
///
/// ```
/// use savsim_core::sensors::errors::sigma_from_bound95;
/// assert!((sigma_from_bound95(92.6) - 37.8).abs() < 0.05);
/// assert!((sigma_from_bound95(185.2) - 75.7).abs() < 0.05);
/// ```
pub fn sigma_from_bound95(bound95_m: f64) -> f64 {
    bound95_m / libm::sqrt(-2.0 * libm::log(0.05))
}

//! Importance-sampled pairing of two sampled tracks into an encounter, after MIT LL's
//! em-pairing-uncor-importancesampling (`generateDAAEncounterSet.m`,
//! `initializeUncorrelatedEncounter.m`): what decides the geometry at the time of closest
//! approach (TCA) and the weight `w` that undoes the sampling's bias.
//!
//! - **VMD** (the intruder's altitude above the ownship's at TCA, each track at its own sampled
//!   altitude) is kept with probability `p_i / max p` in VMD bin `i` (rejection sampling; a VMD
//!   outside the bins is never kept); its weight is `max p / p_i`.
//! - **Relative heading** (the intruder's course relative to the ownship's at TCA) is drawn
//!   with density proportional to the relative speed `|v_rel(psi)|` (horizontal speeds at TCA
//!   and the difference of vertical rates): encounters happen in proportion to it. Its weight
//!   is the normalising integral `∫ |v_rel(psi)| dpsi` over a turn ([`heading_norm_ftps`]).
//! - **HMD** (signed: the side of the relative velocity the intruder passes on) is drawn from
//!   the proposal, piecewise uniform over its bins with bin probabilities `q_i / sum q`; the
//!   encounter's true HMD is uniform over `±max_hmd`; its weight is the ratio of the two
//!   densities, `(1 / (2 max_hmd)) / proposal(hmd)`.
//!
//! `w` is the product of the three, in MIT LL's units (feet per second for the heading norm):
//! only ratios of weighted sums mean anything.

use rand::Rng;

/// Why a pairing's distributions are unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PairingError {
    /// Bin edges and proportions that do not describe a distribution.
    #[error("{name}: {message}")]
    Bins {
        /// Which distribution (`bin_edges_HMD`...).
        name: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// A piecewise-uniform distribution over bins: bin `i` spans `edges[i]..edges[i+1]` and has
/// probability `proportions[i] / sum(proportions)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Bins {
    edges: Vec<f64>,
    probabilities: Vec<f64>,
}

/// Most bins a pairing distribution may have (MIT LL's examples have 6).
const MAX_BINS: usize = 10_000;

impl Bins {
    /// Bins from their edges (increasing) and one non-negative proportion per bin, at least
    /// one of them positive; `name` names them in errors.
    ///
    /// ```
    /// use savsim_core::daa::pairing::Bins;
    /// let b = Bins::new("hmd", &[-2.0, 0.0, 2.0], &[1.0, 3.0]).unwrap();
    /// assert_eq!(b.probabilities(), &[0.25, 0.75]);
    /// assert_eq!(b.density(1.0), 0.375);
    /// assert_eq!(b.density(3.0), 0.0);
    /// assert!(Bins::new("hmd", &[0.0, 0.0], &[1.0]).is_err());
    /// ```
    pub fn new(
        name: &'static str,
        edges: &[f64],
        proportions: &[f64],
    ) -> Result<Self, PairingError> {
        let bad = |message: String| PairingError::Bins { name, message };
        if edges.len() < 2 || edges.len() > MAX_BINS + 1 {
            return Err(bad(format!(
                "{} edges: give 2 to {}",
                edges.len(),
                MAX_BINS + 1
            )));
        }
        if proportions.len() + 1 != edges.len() {
            return Err(bad(format!(
                "{} proportions for {} bins",
                proportions.len(),
                edges.len() - 1
            )));
        }
        if edges.iter().any(|e| !e.is_finite()) || edges.windows(2).any(|w| w[1] <= w[0]) {
            return Err(bad("edges must be finite and strictly increasing".into()));
        }
        if proportions.iter().any(|p| !p.is_finite() || *p < 0.0) {
            return Err(bad("proportions must be finite and >= 0".into()));
        }
        let sum: f64 = proportions.iter().sum();
        if sum <= 0.0 {
            return Err(bad("every proportion is 0".into()));
        }
        Ok(Self {
            edges: edges.to_vec(),
            probabilities: proportions.iter().map(|p| p / sum).collect(),
        })
    }

    /// The bins' edges.
    pub fn edges(&self) -> &[f64] {
        &self.edges
    }

    /// Each bin's probability (they sum to 1).
    pub fn probabilities(&self) -> &[f64] {
        &self.probabilities
    }

    /// The bin `x` falls in (a bin holds its lower edge; the last one its upper edge too).
    pub fn bin(&self, x: f64) -> Option<usize> {
        let last = self.edges.len() - 1;
        if !(self.edges[0]..=self.edges[last]).contains(&x) {
            return None;
        }
        Some(self.edges.partition_point(|e| *e <= x).clamp(1, last) - 1)
    }

    /// The probability density at `x` (0 outside the bins).
    pub fn density(&self, x: f64) -> f64 {
        self.bin(x).map_or(0.0, |i| {
            self.probabilities[i] / (self.edges[i + 1] - self.edges[i])
        })
    }

    /// A draw: a bin by its probability, then uniform within it.
    pub fn sample(&self, rng: &mut impl Rng) -> f64 {
        let u: f64 = rng.random();
        let mut acc = 0.0;
        let mut bin = self.probabilities.len() - 1;
        for (i, p) in self.probabilities.iter().enumerate() {
            acc += p;
            if u < acc {
                bin = i;
                break;
            }
        }
        rng.random_range(self.edges[bin]..self.edges[bin + 1])
    }

    /// The probability of keeping a value in rejection sampling toward these proportions: its
    /// bin's probability over the largest bin probability (`None` outside the bins: never kept).
    pub fn acceptance(&self, x: f64) -> Option<f64> {
        let max = self.probabilities.iter().cloned().fold(0.0, f64::max);
        self.bin(x)
            .map(|i| self.probabilities[i] / max)
            .filter(|a| *a > 0.0)
    }
}

/// The complete elliptic integral of the second kind, `E(m) = ∫_0^{π/2} sqrt(1 - m sin²θ) dθ`,
/// for a parameter `0 <= m <= 1`, by the arithmetic-geometric mean.
///
/// ```
/// use savsim_core::daa::pairing::elliptic_e;
/// assert!((elliptic_e(0.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// assert!((elliptic_e(1.0) - 1.0).abs() < 1e-12);
/// assert!((elliptic_e(0.5) - 1.350_643_881_047_675_5).abs() < 1e-14);
/// ```
pub fn elliptic_e(m: f64) -> f64 {
    let m = m.clamp(0.0, 1.0);
    if m == 1.0 {
        return 1.0;
    }
    let (mut a, mut g) = (1.0f64, (1.0 - m).sqrt());
    let mut c2_sum = 0.5 * m;
    let mut power = 0.5;
    for _ in 0..64 {
        if (a - g).abs() <= f64::EPSILON * a {
            break;
        }
        let c = 0.5 * (a - g);
        power *= 2.0;
        c2_sum += power * c * c;
        (a, g) = (0.5 * (a + g), (a * g).sqrt());
    }
    std::f64::consts::FRAC_PI_2 / a * (1.0 - c2_sum)
}

/// The relative speed at relative heading `psi_rad` of two aircraft with horizontal speeds
/// `own_ftps`, `intruder_ftps` and a difference of vertical rates `dvz_ftps`.
pub fn relative_speed_ftps(own_ftps: f64, intruder_ftps: f64, dvz_ftps: f64, psi_rad: f64) -> f64 {
    let (s, c) = psi_rad.sin_cos();
    ((intruder_ftps * c - own_ftps).powi(2) + (intruder_ftps * s).powi(2) + dvz_ftps.powi(2)).sqrt()
}

/// `∫_{-π}^{π} |v_rel(psi)| dpsi = 4 sqrt(A) E(4 v1 v2 / A)`, `A = (v1 + v2)² + dvz²`.
pub fn heading_norm_ftps(own_ftps: f64, intruder_ftps: f64, dvz_ftps: f64) -> f64 {
    let a = (own_ftps + intruder_ftps).powi(2) + dvz_ftps.powi(2);
    if a <= 0.0 {
        return 0.0;
    }
    4.0 * a.sqrt() * elliptic_e(4.0 * own_ftps * intruder_ftps / a)
}

/// A relative heading in `-π..π` drawn with density proportional to the relative speed
/// (rejection against the head-on speed, the largest).
pub fn relative_heading(
    own_ftps: f64,
    intruder_ftps: f64,
    dvz_ftps: f64,
    rng: &mut impl Rng,
) -> f64 {
    let max = relative_speed_ftps(own_ftps, intruder_ftps, dvz_ftps, std::f64::consts::PI);
    loop {
        let psi = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let keep: f64 = rng.random();
        if max <= 0.0 || keep * max <= relative_speed_ftps(own_ftps, intruder_ftps, dvz_ftps, psi) {
            return psi;
        }
    }
}

/// The weight of a signed HMD drawn from `proposal` when the true HMD is uniform over
/// `±max_hmd_m` (0 for one the proposal cannot draw or the truth never has).
pub fn hmd_weight(hmd_m: f64, proposal: &Bins, max_hmd_m: f64) -> f64 {
    let q = proposal.density(hmd_m);
    if q <= 0.0 || hmd_m.abs() > max_hmd_m {
        0.0
    } else {
        (1.0 / (2.0 * max_hmd_m)) / q
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// The heading norm against a midpoint quadrature of the relative speed over a turn.
    #[test]
    fn heading_norm_is_the_integral_of_the_relative_speed() {
        for (v1, v2, dz) in [
            (150.0, 90.0, 0.0),
            (30.0, 200.0, 25.0),
            (80.0, 80.0, 0.0),
            (0.1, 60.0, 5.0),
        ] {
            let n = 200_000;
            let h = std::f64::consts::TAU / n as f64;
            let quad: f64 = (0..n)
                .map(|k| {
                    relative_speed_ftps(v1, v2, dz, -std::f64::consts::PI + (k as f64 + 0.5) * h)
                        * h
                })
                .sum();
            let norm = heading_norm_ftps(v1, v2, dz);
            assert!(
                (norm - quad).abs() < 1e-6 * quad,
                "{v1} {v2} {dz}: {norm} vs {quad}"
            );
        }
    }

    /// Drawn headings' bin frequencies against the relative speed integrated over each bin.
    #[test]
    fn relative_headings_follow_the_relative_speed() {
        let (v1, v2, dz) = (120.0, 60.0, 10.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let bins = 12;
        let n = 60_000;
        let mut counts = vec![0usize; bins];
        for _ in 0..n {
            let psi = relative_heading(v1, v2, dz, &mut rng);
            let b = ((psi + std::f64::consts::PI) / std::f64::consts::TAU * bins as f64) as usize;
            counts[b.min(bins - 1)] += 1;
        }
        let width = std::f64::consts::TAU / bins as f64;
        let total = heading_norm_ftps(v1, v2, dz);
        let chi2: f64 = (0..bins)
            .map(|b| {
                let steps = 1000;
                let mass: f64 = (0..steps)
                    .map(|k| {
                        let psi = -std::f64::consts::PI
                            + width * (b as f64 + (k as f64 + 0.5) / steps as f64);
                        relative_speed_ftps(v1, v2, dz, psi) * width / steps as f64
                    })
                    .sum();
                let expected = n as f64 * mass / total;
                (counts[b] as f64 - expected).powi(2) / expected
            })
            .sum();
        // 11 degrees of freedom: the 0.01 critical value is 24.7.
        assert!(chi2 < 24.7, "chi-square {chi2}: {counts:?}");
    }

    #[test]
    fn bins_sample_their_probabilities_and_the_acceptance_is_relative_to_the_largest() {
        let b = Bins::new("vmd", &[-10.0, -1.0, 0.0, 1.0, 10.0], &[0.5, 1.0, 1.0, 0.5]).unwrap();
        assert_eq!(b.acceptance(-5.0), Some(0.5));
        assert_eq!(b.acceptance(0.5), Some(1.0));
        assert_eq!(b.acceptance(10.0), Some(0.5));
        assert_eq!(b.acceptance(10.5), None);
        assert_eq!(b.bin(-10.0), Some(0));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut counts = [0usize; 4];
        for _ in 0..30_000 {
            counts[b.bin(b.sample(&mut rng)).unwrap()] += 1;
        }
        let p = b.probabilities();
        let chi2: f64 = (0..4)
            .map(|i| (counts[i] as f64 - 30_000.0 * p[i]).powi(2) / (30_000.0 * p[i]))
            .sum();
        assert!(chi2 < 11.34, "{counts:?}");
    }

    #[test]
    fn hmd_weight_is_the_ratio_of_the_densities() {
        let b = Bins::new("hmd", &[-1000.0, 0.0, 1000.0], &[1.0, 3.0]).unwrap();
        // True density 1/20000 per metre; the proposal's 0.75/1000 on the positive side.
        assert!((hmd_weight(10.0, &b, 10_000.0) - (1.0 / 20_000.0) / 0.00075).abs() < 1e-12);
        assert_eq!(hmd_weight(5000.0, &b, 10_000.0), 0.0);
    }
}

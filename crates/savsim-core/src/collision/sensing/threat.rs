//! The threat coefficient (paper §3.3.2): beta = W1*T + W2*V + W3*A, with W from an AHP
//! judgment matrix by the geometric-mean method, and the matrix's consistency ratio.

/// The paper's judgment matrix (Table 3), rows and columns T, V, A.
pub const PAPER_MATRIX: [[f64; 3]; 3] = [
    [1.0, 7.0 / 3.0, 3.0 / 2.0],
    [3.0 / 7.0, 1.0, 5.0 / 4.0],
    [2.0 / 3.0, 4.0 / 5.0, 1.0],
];

/// Saaty's random index for n = 3.
pub const RANDOM_INDEX_3: f64 = 0.58;

/// AHP weights and how consistent the judgments behind them are.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AhpWeights {
    /// Weights of T (type), V (speed), A (angle); they sum to 1.
    pub w: [f64; 3],
    /// Principal eigenvalue estimate.
    pub lambda_max: f64,
    /// Consistency index (lambda_max - n) / (n - 1).
    pub ci: f64,
    /// Consistency ratio CI / RI; judgments are acceptable below 0.1.
    pub cr: f64,
}

impl AhpWeights {
    /// Weights from a positive reciprocal judgment matrix by the geometric-mean method.
    /// `None` if an entry is not positive and finite.
    ///
    /// ```
    /// use savsim_core::collision::sensing::threat::{AhpWeights, PAPER_MATRIX};
    /// let w = AhpWeights::from_matrix(PAPER_MATRIX).unwrap();
    /// assert!((w.w[0] - 0.4833).abs() < 1e-4);
    /// assert!((w.w[1] - 0.2586).abs() < 1e-4 && (w.w[2] - 0.2582).abs() < 1e-4);
    /// assert!(w.cr < 0.1);
    /// ```
    pub fn from_matrix(m: [[f64; 3]; 3]) -> Option<Self> {
        if m.iter().flatten().any(|v| !(v.is_finite() && *v > 0.0)) {
            return None;
        }
        let roots = m.map(|row| row.iter().product::<f64>().cbrt());
        let sum: f64 = roots.iter().sum();
        let w = roots.map(|r| r / sum);
        let lambda_max = (0..3)
            .map(|i| (0..3).map(|j| m[i][j] * w[j]).sum::<f64>() / w[i])
            .sum::<f64>()
            / 3.0;
        let ci = (lambda_max - 3.0) / 2.0;
        Some(Self {
            w,
            lambda_max,
            ci,
            cr: ci / RANDOM_INDEX_3,
        })
    }

    /// The threat coefficient of an obstacle of threat `t`, moving at `speed_mps`, seen at
    /// `angle_deg` from the UAV's forward axis. A = 180 - angle within 45 degrees, else 0.
    ///
    /// ```
    /// use savsim_core::collision::sensing::threat::{AhpWeights, PAPER_MATRIX};
    /// let w = AhpWeights::from_matrix(PAPER_MATRIX).unwrap();
    /// let ahead = w.beta(60.0, 0.0, 0.0);
    /// assert!((ahead - (0.4833 * 60.0 + 0.2582 * 180.0)).abs() < 0.05);
    /// assert!(w.beta(60.0, 0.0, 90.0) < 50.0); // a building abeam is no threat
    /// ```
    pub fn beta(&self, t: f64, speed_mps: f64, angle_deg: f64) -> f64 {
        let a = if (0.0..=45.0).contains(&angle_deg) {
            180.0 - angle_deg
        } else {
            0.0
        };
        self.w[0] * t + self.w[1] * speed_mps + self.w[2] * a
    }
}

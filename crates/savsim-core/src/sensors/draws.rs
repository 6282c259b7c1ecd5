//! Random numbers as a function of a key, not of a sequence: the draw for (seed, stream,
//! instant) is the same whichever draws were made before it, on any machine. A reading taken
//! at a device's instant k on the vehicle's clock therefore gets the same errors at any
//! speedup, however the samples fell (ChaCha8 seeked to the instant's words; logarithms and
//! cosines from `libm`, the same bits everywhere).

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The draws of one run (its seed).
#[derive(Debug, Clone)]
pub struct Draws {
    rng: ChaCha8Rng,
}

/// Mix a value into a stream key (splitmix64's finaliser: every input bit moves every output
/// bit).
pub fn mix(key: u64, value: u64) -> u64 {
    let mut z = key ^ value.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Words each draw uses: two 64-bit numbers.
const WORDS_PER_DRAW: u128 = 4;

impl Draws {
    /// The draws of a run with this seed.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// Two independent 64-bit numbers for (`stream`, `index`).
    fn words(&mut self, stream: u64, index: u64) -> (u64, u64) {
        self.rng.set_stream(stream);
        self.rng.set_word_pos(u128::from(index) * WORDS_PER_DRAW);
        (self.rng.next_u64(), self.rng.next_u64())
    }

    /// A uniform number in [0, 1) for (`stream`, `index`).
    ///
    /// ```
    /// use savsim_core::sensors::draws::Draws;
    /// let (mut a, mut b) = (Draws::new(7), Draws::new(7));
    /// let late = a.uniform(3, 1000);
    /// // b draws other things first: the draw for (3, 1000) does not change.
    /// for k in 0..10 { b.uniform(3, k); }
    /// assert_eq!(b.uniform(3, 1000), late);
    /// assert!((0.0..1.0).contains(&late));
    /// ```
    pub fn uniform(&mut self, stream: u64, index: u64) -> f64 {
        unit(self.words(stream, index).0)
    }

    /// A standard normal number for (`stream`, `index`) (Box-Muller on two uniforms).
    pub fn normal(&mut self, stream: u64, index: u64) -> f64 {
        let (a, b) = self.words(stream, index);
        // (0, 1]: the logarithm is finite.
        let u1 = 1.0 - unit(a);
        let u2 = unit(b);
        libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(2.0 * std::f64::consts::PI * u2)
    }

    /// A Laplace number of scale `b` (density exp(-|x| / b) / 2b) for (`stream`, `index`), by
    /// the inverse of its distribution.
    pub fn laplace(&mut self, stream: u64, index: u64, b: f64) -> f64 {
        let u = self.uniform(stream, index) - 0.5;
        // 1 - 2|u| in (0, 1]: finite.
        -b * u.signum() * libm::log(1.0 - 2.0 * u.abs())
    }

    /// A uniform number in [-half, half] for (`stream`, `index`).
    pub fn symmetric(&mut self, stream: u64, index: u64, half: f64) -> f64 {
        half * (2.0 * self.uniform(stream, index) - 1.0)
    }
}

/// The top 53 bits of `x` as a number in [0, 1).
fn unit(x: u64) -> f64 {
    (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

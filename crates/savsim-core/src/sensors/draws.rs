//! Random numbers as a function of a key, not of a sequence: the draw for (seed, stream,
//! instant) is the same whichever draws were made before it, on any machine. A reading taken
//! at a device's instant k on the vehicle's clock therefore gets the same errors at any
//! speedup, however the samples fell. The generator is SplitMix64 (Steele, Lea and Flood,
//! "Fast splittable pseudorandom number generators", OOPSLA 2014), whose n-th output is a
//! function of n alone: each stream starts where a hash of the run's seed and the stream puts
//! it, and a draw is the stream's outputs 2k and 2k + 1 (logarithms and cosines from `libm`, the
//! same bits everywhere).

/// SplitMix64's increment (the golden ratio's fraction, odd).
const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// The draws of one run (its seed).
#[derive(Debug, Clone, Copy)]
pub struct Draws {
    seed: u64,
}

/// SplitMix64's output function (the finaliser of MurmurHash3's 64-bit variant, with Stafford's
/// constants): every input bit moves every output bit.
fn finalise(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Mix a value into a stream key.
pub fn mix(key: u64, value: u64) -> u64 {
    finalise(key ^ value.wrapping_add(GAMMA))
}

impl Draws {
    /// The draws of a run with this seed.
    pub fn new(seed: u64) -> Self {
        Self { seed }
    }

    /// Two independent 64-bit numbers for (`stream`, `index`): SplitMix64's outputs 2 index
    /// and 2 index + 1 from the stream's start.
    fn words(&self, stream: u64, index: u64) -> (u64, u64) {
        let start = mix(self.seed, stream);
        let output = |n: u64| finalise(start.wrapping_add(n.wrapping_add(1).wrapping_mul(GAMMA)));
        let first = index.wrapping_mul(2);
        (output(first), output(first.wrapping_add(1)))
    }

    /// A uniform number in [0, 1) for (`stream`, `index`).
    ///
    /// ```
    /// use savsim_core::sensors::draws::Draws;
    /// let (a, b) = (Draws::new(7), Draws::new(7));
    /// let late = a.uniform(3, 1000);
    /// // b draws other things first: the draw for (3, 1000) does not change.
    /// for k in 0..10 { b.uniform(3, k); }
    /// assert_eq!(b.uniform(3, 1000), late);
    /// assert!((0.0..1.0).contains(&late));
    /// ```
    pub fn uniform(&self, stream: u64, index: u64) -> f64 {
        unit(self.words(stream, index).0)
    }

    /// A standard normal number for (`stream`, `index`) (Box-Muller on two uniforms).
    pub fn normal(&self, stream: u64, index: u64) -> f64 {
        let (a, b) = self.words(stream, index);
        // (0, 1]: the logarithm is finite.
        let u1 = 1.0 - unit(a);
        let u2 = unit(b);
        libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(2.0 * std::f64::consts::PI * u2)
    }

    /// A Laplace number of scale `b` (density exp(-|x| / b) / 2b) for (`stream`, `index`), by
    /// the inverse of its distribution.
    pub fn laplace(&self, stream: u64, index: u64, b: f64) -> f64 {
        let u = self.uniform(stream, index) - 0.5;
        // 1 - 2|u| in (0, 1]: finite.
        -b * u.signum() * libm::log(1.0 - 2.0 * u.abs())
    }

    /// A uniform number in [-half, half] for (`stream`, `index`).
    pub fn symmetric(&self, stream: u64, index: u64, half: f64) -> f64 {
        half * (2.0 * self.uniform(stream, index) - 1.0)
    }
}

/// The top 53 bits of `x` as a number in [0, 1).
fn unit(x: u64) -> f64 {
    (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

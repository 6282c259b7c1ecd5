//! The compass's and barometer's noise in what savsim tells PX4 (HIL_SENSOR).
//!
//! PX4's sensors module takes a reading that repeats exactly (each axis within 1e-6) for a
//! dead sensor (its `DataValidator`: more than 100 repeats in a row for a barometer, 1000
//! counted over a compass's axes) and stops publishing it. A landed body's truth repeats
//! bit for bit, so without noise PX4 soon dropped both, and its estimator aligned only if it
//! had started before then: some boots never armed (docs/lockstep.md). PX4's own simulators
//! add noise for this reason; the sizes here are Gazebo classic's plugins' defaults
//! (magnetometer 0.4 mgauss, barometer 1 Pa).
//!
//! Each draw is a function of the instance's port and the step's time alone
//! ([`Draws`]): the readings depend on the clock, not on the machine.

use glam::DVec3;
use savsim_core::sensors::draws::{mix, Draws};

/// The compass's noise, gauss (one sigma, each axis, each message).
pub const MAG_NOISE_GAUSS: f64 = 0.4e-3;
/// The barometer's noise, pascals (one sigma, each message).
pub const BARO_NOISE_PA: f64 = 1.0;

/// The streams of the draws: the compass's axes, the barometer.
const MAG_STREAMS: [u64; 3] = [1, 2, 3];
const BARO_STREAM: u64 = 4;
/// The base of every instance's seed.
const SEED: u64 = 0x5AF5_1A4B;

/// One PX4 instance's sensor noise.
#[derive(Debug, Clone, Copy)]
pub struct HilNoise {
    draws: Draws,
}

impl HilNoise {
    /// The noise of the PX4 on simulator port `port`.
    pub fn for_port(port: u16) -> Self {
        Self {
            draws: Draws::new(mix(SEED, u64::from(port))),
        }
    }

    /// The compass's error at `time_us` of the clock, gauss (body axes).
    ///
    /// ```
    /// use savsim::lockstep::hil_noise::{HilNoise, MAG_NOISE_GAUSS};
    /// let noise = HilNoise::for_port(4560);
    /// assert_eq!(noise.mag_gauss(4_000), HilNoise::for_port(4560).mag_gauss(4_000));
    /// assert_ne!(noise.mag_gauss(4_000), noise.mag_gauss(8_000));
    /// assert!(noise.mag_gauss(4_000).abs().max_element() < 6.0 * MAG_NOISE_GAUSS);
    /// ```
    pub fn mag_gauss(&self, time_us: u64) -> DVec3 {
        let [x, y, z] = MAG_STREAMS.map(|s| self.draws.normal(s, time_us));
        DVec3::new(x, y, z) * MAG_NOISE_GAUSS
    }

    /// The barometer's error at `time_us` of the clock, pascals.
    pub fn baro_pa(&self, time_us: u64) -> f64 {
        self.draws.normal(BARO_STREAM, time_us) * BARO_NOISE_PA
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_has_its_sigma_and_never_repeats_a_reading() {
        let noise = HilNoise::for_port(4561);
        let n = 20_000u64;
        let baro: Vec<f64> = (1..=n).map(|k| noise.baro_pa(k * 4_000)).collect();
        let mean = baro.iter().sum::<f64>() / n as f64;
        let sd = (baro.iter().map(|b| (b - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(
            mean.abs() < 0.05 && (sd - BARO_NOISE_PA).abs() < 0.03,
            "{mean} {sd}"
        );
        // PX4 counts a reading within 1e-6 of the one before as a repeat.
        let mag: Vec<DVec3> = (1..=n).map(|k| noise.mag_gauss(k * 4_000)).collect();
        let repeats = mag
            .windows(2)
            .filter(|w| (w[1] - w[0]).abs().max_element() < 1e-6)
            .count();
        assert!(repeats < 20, "{repeats} compass readings repeated");
        assert_ne!(
            noise.baro_pa(4_000),
            HilNoise::for_port(4560).baro_pa(4_000)
        );
    }
}

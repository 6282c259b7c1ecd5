//! The seed a row's sensor errors are drawn with, one rule for `batch` and `study`: the row's
//! own `sensor_seed` when the manifest gives one; else a seed made from the row's base seed
//! (its `seed` column, 1 without) and its encounter (its `pair`, else its id).
//!
//! So the variants of one encounter (`nominal`, `mitigated/ideal`, `mitigated/adsb-nacp6`...)
//! draw one realisation of the errors, each scaled by its own sigmas (common random numbers:
//! a ratio between variants compares sensors, not draws), and two encounters draw independent
//! ones: a study's rate is a rate over the error distribution, not over one draw of it.
//! Targets within a row draw independently of each other (the sensor models key each draw by
//! its target).

use sha2::{Digest, Sha256};

use crate::sensors::draws::mix;

/// The base seed of a row without one.
pub const DEFAULT_BASE_SEED: u64 = 1;

/// The seed of a row's sensor errors: `explicit` when given; else one made from `base`
/// ([`DEFAULT_BASE_SEED`] when `None`) and the name of the row's `encounter`.
///
/// ```
/// use savsim::runs::seeds::sensor_seed;
/// // The variants of one encounter share a seed; two encounters do not.
/// assert_eq!(sensor_seed(None, Some(11), "enc-1"), sensor_seed(None, Some(11), "enc-1"));
/// assert_ne!(sensor_seed(None, Some(11), "enc-1"), sensor_seed(None, Some(11), "enc-2"));
/// // Another base seed, other draws for the same encounter.
/// assert_ne!(sensor_seed(None, Some(11), "enc-1"), sensor_seed(None, Some(12), "enc-1"));
/// // A row's own seed wins.
/// assert_eq!(sensor_seed(Some(7), Some(11), "enc-1"), 7);
/// ```
pub fn sensor_seed(explicit: Option<u64>, base: Option<u64>, encounter: &str) -> u64 {
    explicit.unwrap_or_else(|| mix(base.unwrap_or(DEFAULT_BASE_SEED), name_key(encounter)))
}

/// A name as 64 bits: the first eight bytes of its SHA-256 (the same on every machine and
/// toolchain, unlike `std`'s hasher).
fn name_key(name: &str) -> u64 {
    let digest = Sha256::digest(name.as_bytes());
    let mut first = [0u8; 8];
    first.copy_from_slice(&digest[..8]);
    u64::from_le_bytes(first)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pinned: the seed of an encounter must not change between versions, or a study flown
    /// again draws other errors.
    #[test]
    fn an_encounters_seed_is_the_same_on_every_version() {
        assert_eq!(name_key(""), 0x141c_fc98_42c4_b0e3);
        assert_eq!(
            sensor_seed(None, None, "p-1"),
            mix(DEFAULT_BASE_SEED, name_key("p-1"))
        );
    }
}

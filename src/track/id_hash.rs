//! A hasher for maps keyed by the tracker's own small integer ids (trace and
//! identity numbers).
//!
//! The standard SipHash guards a map against keys chosen by an attacker;
//! these keys are counters the tracker hands out itself, and the live
//! tracker looks one up for every marker of every frame (1 000 a frame at
//! 360 Hz), where SipHash was a measurable part of the frame. A Fibonacci
//! multiply spreads consecutive ids over the table. Nothing iterates these
//! maps in an order that reaches an output, so the hash function changes no
//! result.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Hashes one integer by a multiply with 2^64 / φ.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct IdHasher(u64);

impl Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        // Only integer keys are hashed here; bytes (never used) still hash.
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }

    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0 ^ i).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// A map from a tracker id.
pub(crate) type IdMap<V> = HashMap<usize, V, BuildHasherDefault<IdHasher>>;

#[cfg(test)]
mod tests {
    use super::*;

    /// Consecutive ids land in different buckets of a small table: the
    /// table's index is the hash's top bits in hashbrown, low in others,
    /// so both ends must vary.
    #[test]
    fn consecutive_ids_spread_over_high_and_low_bits() {
        let hash = |i: usize| {
            let mut h = IdHasher::default();
            h.write_usize(i);
            h.finish()
        };
        let top: std::collections::HashSet<u64> = (0..64).map(|i| hash(i) >> 58).collect();
        let low: std::collections::HashSet<u64> = (0..64).map(|i| hash(i) & 63).collect();
        assert!(top.len() > 32, "top bits: {}", top.len());
        assert!(low.len() > 16, "low bits: {}", low.len());
    }
}

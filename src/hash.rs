//! SplitMix64, the one hash the crate uses for reproducible pseudo-random numbers (the wind's
//! gust noise, the subdivision grid check's control cloud) and for its hash maps of integer keys
//! ([`IntHasher`]). Engine-free.

use std::hash::Hasher;

/// `2⁶⁴ / φ`, the increment of the SplitMix64 generator.
pub(crate) const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// The SplitMix64 output function: a bijective 64-bit mixer.
#[inline]
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The top 24 bits of `h` as a number in `[0, 1]` (both ends included, exactly).
#[inline]
pub(crate) fn unit_interval(h: u64) -> f32 {
    (h >> 40) as f32 / ((1u32 << 24) - 1) as f32
}

/// Entry `i` of the SplitMix64 stream that starts from state 0.
pub(crate) fn splitmix(i: u64) -> u64 {
    mix64(i.wrapping_add(1).wrapping_mul(GOLDEN_GAMMA))
}

/// A hasher for keys made of integers (grid cells, pairs of particles): a multiply per word and
/// SplitMix64's mixer at the end. Much cheaper than the standard library's keyed hash, and the
/// same in every process, so maps iterate in one order from run to run.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct IntHasher(u64);

impl Hasher for IntHasher {
    fn finish(&self) -> u64 {
        mix64(self.0)
    }
    fn write(&mut self, bytes: &[u8]) {
        // A slice of integers arrives as its bytes: four at a time.
        for chunk in bytes.chunks(4) {
            let mut word = [0; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u32(u32::from_le_bytes(word));
        }
    }
    fn write_u32(&mut self, i: u32) {
        self.0 = (self.0 ^ u64::from(i)).wrapping_mul(GOLDEN_GAMMA);
    }
    fn write_i32(&mut self, i: i32) {
        self.write_u32(i as u32);
    }
    fn write_u64(&mut self, i: u64) {
        self.write_u32(i as u32);
        self.write_u32((i >> 32) as u32);
    }
}

//! SplitMix64, the one hash the crate uses for reproducible pseudo-random numbers (the wind's
//! gust noise, the subdivision grid check's control cloud). Engine-free.

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

//! Size limits that the solver enforces and the crate's error messages name. It sits below both
//! (`sim` re-exports what is public here) and must not import anything from the crate.

/// Largest number of particles a cloth may have (16,777,216, a 4096 × 4096 grid): far beyond
/// real time, and small enough that building the cloth's springs fits in memory.
pub const MAX_PARTICLES: usize = 1 << 24;

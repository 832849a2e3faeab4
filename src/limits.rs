//! Size limits that the solver enforces and the crate's error messages name. It sits below both
//! (`sim` re-exports what is public here) and must not import anything from the crate.

/// Largest number of particles a cloth may have (1,048,576, a 1024 × 1024 grid): beyond what a
/// cloth steps in real time, and small enough that a machine builds such a cloth (its springs,
/// colours and solver layouts) in well under its memory. Every path that makes particles (grid
/// and disc specs, meshes, subdivision before simulating, hand-built models) checks its count
/// against this before allocating them.
pub const MAX_PARTICLES: usize = 1 << 20;

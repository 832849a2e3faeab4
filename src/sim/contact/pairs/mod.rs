//! What a cloth's contacts with itself (`self_contact`) and with other cloths (`cloths`) share,
//! below both: the geometry of vertex–triangle and edge–edge pairs ([`geometry`]), the spatial
//! hash of the broad phases ([`hash_grid`]), the response to one pair ([`response`]), the
//! candidates' bands of distance ([`bands`]), and the snapshots of the particles that the narrow
//! phase works on and that let a substep defer its resolution ([`snapshots`]). Nothing here
//! knows either kind of contact.

mod bands;
mod geometry;
mod hash_grid;
mod response;
mod snapshots;

pub(super) use bands::{GapBands, reorder};
pub(super) use geometry::{closest_on_segments, edge_table, pair_key, point_triangle_distance};
pub(super) use hash_grid::{SpatialHash, boxes_meet, boxes_meet_wide, cell_of, for_cells};
#[cfg(test)]
pub(super) use response::EDGES_APART_SHARE;
pub(super) use response::{LayerSpacing, later_passes};
pub(super) use snapshots::{
    DEFER_CLOSING, GatheredParticles, LastResolution, storage_order_changed,
};

/// `s.map(f)` for the four particles of a pair, written out: in the narrow phase's hot loop the
/// library's `map` was left as a call.
#[inline(always)]
pub(super) fn map_four<T: Copy, U>(s: [T; 4], f: impl Fn(T) -> U) -> [U; 4] {
    [f(s[0]), f(s[1]), f(s[2]), f(s[3])]
}

/// The square root of the largest of `square(k)` for `k` in `0..n` (squared distances), 0 for
/// none, infinite if one is NaN or infinite: eight running maxima (and sums, which keep a NaN
/// that the comparisons drop), so that one value's comparison does not wait on the last.
#[inline(always)]
pub(super) fn largest_root(n: usize, square: impl Fn(usize) -> f32) -> f32 {
    const LANES: usize = 8;
    let (mut worst, mut total) = ([0.0f32; LANES], [0.0f32; LANES]);
    let whole = n - n % LANES;
    for start in (0..whole).step_by(LANES) {
        for k in 0..LANES {
            let d = square(start + k);
            worst[k] = if d > worst[k] { d } else { worst[k] };
            total[k] += d;
        }
    }
    for (k, i) in (whole..n).enumerate() {
        let d = square(i);
        worst[k] = if d > worst[k] { d } else { worst[k] };
        total[k] += d;
    }
    let worst = worst.into_iter().fold(0.0f32, f32::max);
    let total: f32 = total.into_iter().sum();
    // A sum too large counts as a NaN.
    if total.is_finite() {
        worst.sqrt()
    } else {
        f32::INFINITY
    }
}

/// The larger of `a` and `b`, infinite if `b` is NaN (a non-finite displacement must force a new
/// search, not vanish in a comparison).
pub(super) fn max_or_infinite(a: f32, b: f32) -> f32 {
    if b.is_nan() { f32::INFINITY } else { a.max(b) }
}

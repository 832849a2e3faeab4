//! The lane arithmetic of XPBD's spring kernel: a batch's constants ([`Batch`],
//! [`SlotConstants`]), the lane-wise update ([`update`]), and the batches that gather their lanes
//! from the columns and scatter them back: contiguous, interleaved and scattered ones. Which
//! batches run in which order is the sweep's (`kernel/mod.rs`).

#[cfg(doc)]
use super::super::layout::Layout;
use super::super::layout::{LANES, Projections, interleaved_offset};
use super::columns::{Column, SplitPositions, array, load};
use crate::sim::simd;

/// The per-slot constants of the batch at slots `k..k + N`, and where its multipliers live.
pub(super) struct Batch<'a, const N: usize> {
    slots: SlotConstants<'a, N>,
    lambda: Column<'a>,
    k: usize,
}

impl<'a, const N: usize> Batch<'a, N> {
    /// Slots `k..k + N` of `p` (the runs never reach past the slots: a panic if they did).
    #[inline(always)]
    pub(super) fn at(p: &'a Projections, lambda: Column<'a>, k: usize) -> Self {
        let slots = |v: &'a [f32]| array(&v[k..k + N]);
        Self {
            slots: SlotConstants {
                rest: slots(&p.rest),
                compliance: slots(&p.compliance),
                weights: [slots(&p.weights[0]), slots(&p.weights[1])],
            },
            lambda,
            k,
        }
    }
}

/// The lane-wise XPBD update of `N` independent slots: `s[0..3]` are the first ends' x, y, z
/// at the start of the substep and `s[3..6]` the second ends', `d` their displacements since,
/// which the update moves.
///
/// # Safety
/// No other thread touches the batch's multipliers while it runs.
#[inline(always)]
pub(super) unsafe fn project<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    s: &[[f32; N]; 6],
    d: &mut [[f32; N]; 6],
    wa: &[f32; N],
    wb: &[f32; N],
    batch: Batch<'_, N>,
    inv_h2: f32,
) {
    let mut lambda = if ACCUMULATE {
        // SAFETY: the caller's contract.
        unsafe { batch.lambda.load::<N>(batch.k) }
    } else {
        [0.0; N]
    };
    update::<ACCUMULATE, FUSED, N>(s, d, (wa, wb), batch.slots, &mut lambda, inv_h2);
    if ACCUMULATE {
        // SAFETY: the caller's contract.
        unsafe { batch.lambda.store(batch.k, &lambda) };
    }
}

/// The per-slot constants of a batch that [`update`] reads: rest lengths, compliances and
/// [`Projections::weights`].
pub(super) struct SlotConstants<'a, const N: usize> {
    pub(super) rest: &'a [f32; N],
    pub(super) compliance: &'a [f32; N],
    pub(super) weights: [&'a [f32; N]; 2],
}

/// [`project`]'s arithmetic, lane by lane, with the batch's inverse masses and constants, and its
/// multipliers in `lambda` (read and written only with `ACCUMULATE`). Without `ACCUMULATE`, λ is
/// 0 and the update is `w_a Δλ = (L - |d|) / |d| · w_a / (w_a + w_b + α̃)`, whose second factor
/// the layout keeps per slot ([`Projections::weights`]): fewer operations per spring, and neither
/// the inverse masses nor the compliances are read.
#[inline(always)]
pub(super) fn update<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    s: &[[f32; N]; 6],
    d: &mut [[f32; N]; 6],
    (wa, wb): (&[f32; N], &[f32; N]),
    slots: SlotConstants<'_, N>,
    lambda: &mut [f32; N],
    inv_h2: f32,
) {
    let SlotConstants {
        rest,
        compliance,
        weights: [weight_a, weight_b],
    } = slots;
    for l in 0..N {
        // The start vectors and the displacements are differenced separately, so that the
        // small displacements keep their precision.
        let dx = (s[0][l] - s[3][l]) + (d[0][l] - d[3][l]);
        let dy = (s[1][l] - s[4][l]) + (d[1][l] - d[4][l]);
        let dz = (s[2][l] - s[5][l]) + (d[2][l] - d[5][l]);
        // Fused multiply-adds: one rounding each, and fewer instructions on the kernel's path.
        let fma = simd::mul_add::<FUSED>;
        let len2 = fma(dx, dx, fma(dy, dy, dz * dz));
        let rest = rest[l];
        let len = len2.sqrt();
        // A spring of (near) zero length has no direction and is skipped, and so is a padding
        // slot (rest length 0). A spring whose ends are both pinned (w = 0) gets a finite step
        // (α̃ > 0) that its zero inverse masses ignore.
        let moves = len2 > 1e-20 && rest > 0.0;
        let (sa, sb) = if ACCUMULATE {
            let lam = lambda[l];
            let alpha = compliance[l] * inv_h2;
            let scale = (rest - len - alpha * lam) / ((wa[l] + wb[l] + alpha) * len);
            let scale = if moves { scale } else { 0.0 };
            lambda[l] = lam + scale * len;
            (scale * wa[l], scale * wb[l])
        } else {
            let strain = (rest - len) / len;
            let strain = if moves { strain } else { 0.0 };
            (strain * weight_a[l], strain * weight_b[l])
        };
        d[0][l] = fma(dx, sa, d[0][l]);
        d[1][l] = fma(dy, sa, d[1][l]);
        d[2][l] = fma(dz, sa, d[2][l]);
        d[3][l] = fma(-dx, sb, d[3][l]);
        d[4][l] = fma(-dy, sb, d[4][l]);
        d[5][l] = fma(-dz, sb, d[5][l]);
    }
}

/// Slots joining particles `ia..ia + N` to `ib..ib + N`.
///
/// # Safety
/// No other thread touches those particles' displacements or the batch's multipliers while it
/// runs.
#[inline(always)]
pub(super) unsafe fn solve_contiguous<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    x: SplitPositions,
    inv_mass: &[f32],
    ia: usize,
    ib: usize,
    batch: Batch<'_, N>,
    inv_h2: f32,
) {
    // One test covers every load and store below (the columns are cut to the particle count).
    assert!(
        ia.max(ib) + N <= inv_mass.len(),
        "a batch past the particles"
    );
    // The x, y, z of particles `ia..ia + N`, then of `ib..ib + N`.
    let s = ends(ia, ib, |c, i| x.start[c].load(i));
    // SAFETY: the caller's contract.
    let mut d = ends(ia, ib, |c, i| unsafe { x.delta[c].load(i) });
    let (wa, wb) = (load(inv_mass, ia), load(inv_mass, ib));
    // SAFETY: the caller's contract.
    unsafe { project::<ACCUMULATE, FUSED, N>(&s, &mut d, &wa, &wb, batch, inv_h2) };
    for (c, coord) in x.delta.iter().enumerate() {
        // SAFETY: the caller's contract.
        unsafe {
            coord.store(ia, &d[c]);
            coord.store(ib, &d[c + 3]);
        }
    }
}

/// The x, y, z of particles `ia..ia + N`, then of `ib..ib + N`, with `load(coordinate, first)`.
#[inline(always)]
pub(super) fn ends<const N: usize>(
    ia: usize,
    ib: usize,
    load: impl Fn(usize, usize) -> [f32; N],
) -> [[f32; N]; 6] {
    [
        load(0, ia),
        load(1, ia),
        load(2, ia),
        load(0, ib),
        load(1, ib),
        load(2, ib),
    ]
}

/// Eight slots over the 16 particles `window..window + 16` (see [`Layout::Interleaved`]).
///
/// # Safety
/// As [`solve_contiguous`], for the window's particles.
#[inline(always)]
pub(super) unsafe fn solve_interleaved<
    const ACCUMULATE: bool,
    const FUSED: bool,
    const D: usize,
>(
    x: SplitPositions,
    inv_mass: &[f32],
    window: usize,
    batch: Batch<'_, LANES>,
    inv_h2: f32,
) {
    // One test covers every load and store below (the columns are cut to the particle count).
    assert!(
        window + 2 * LANES <= inv_mass.len(),
        "a window past the particles"
    );
    let (start, delta) = (x.start, x.delta);
    // SAFETY: the caller's contract.
    let win: [[f32; 16]; 7] = unsafe {
        [
            start[0].load(window),
            start[1].load(window),
            start[2].load(window),
            delta[0].load(window),
            delta[1].load(window),
            delta[2].load(window),
            load(inv_mass, window),
        ]
    };
    let (mut s, mut d) = ([[0.0f32; LANES]; 6], [[0.0f32; LANES]; 6]);
    let (mut wa, mut wb) = ([0.0f32; LANES], [0.0f32; LANES]);
    for l in 0..LANES {
        let (a, b) = (interleaved_offset(D, l), interleaved_offset(D, l) + D);
        for c in 0..3 {
            (s[c][l], s[c + 3][l]) = (win[c][a], win[c][b]);
            (d[c][l], d[c + 3][l]) = (win[c + 3][a], win[c + 3][b]);
        }
        (wa[l], wb[l]) = (win[6][a], win[6][b]);
    }
    // SAFETY: the caller's contract.
    unsafe { project::<ACCUMULATE, FUSED, LANES>(&s, &mut d, &wa, &wb, batch, inv_h2) };
    for (c, coord) in delta.iter().enumerate() {
        let mut out = [0.0f32; 16];
        for l in 0..LANES {
            out[interleaved_offset(D, l)] = d[c][l];
            out[interleaved_offset(D, l) + D] = d[c + 3][l];
        }
        // SAFETY: the caller's contract.
        unsafe { coord.store(window, &out) };
    }
}

/// The batch's slots at arbitrary particles `a[k..]`, `b[k..]`: gather, project, scatter.
///
/// # Safety
/// As [`solve_contiguous`], for the batch's particles.
#[inline(always)]
pub(super) unsafe fn solve_gathered<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    a: &[u32],
    b: &[u32],
    x: SplitPositions,
    inv_mass: &[f32],
    batch: Batch<'_, N>,
    inv_h2: f32,
) {
    let (start, delta) = (x.start, x.delta);
    let (a, b) = (&a[batch.k..batch.k + N], &b[batch.k..batch.k + N]);
    let (mut s, mut d) = ([[0.0f32; N]; 6], [[0.0f32; N]; 6]);
    let (mut wa, mut wb) = ([0.0f32; N], [0.0f32; N]);
    for l in 0..N {
        for (e, i) in [(0, a[l] as usize), (3, b[l] as usize)] {
            for c in 0..3 {
                // SAFETY: the caller's contract.
                (s[e + c][l], d[e + c][l]) = (start[c].get(i), unsafe { delta[c].get(i) });
            }
        }
        (wa[l], wb[l]) = (inv_mass[a[l] as usize], inv_mass[b[l] as usize]);
    }
    // SAFETY: the caller's contract.
    unsafe { project::<ACCUMULATE, FUSED, N>(&s, &mut d, &wa, &wb, batch, inv_h2) };
    for l in 0..N {
        for (e, i) in [(0, a[l] as usize), (3, b[l] as usize)] {
            for c in 0..3 {
                // SAFETY: the caller's contract.
                unsafe { delta[c].set(i, d[e + c][l]) };
            }
        }
    }
}

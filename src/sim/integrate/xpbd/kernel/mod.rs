//! XPBD's spring kernel: one Gauss-Seidel sweep over a layout's runs ([`solve_springs`]), on
//! columns that the two threads of a shared sweep use at once (`columns`, whose types say who may
//! do what). The sweep streams a run's batches here; their lane arithmetic is `lanes`.

mod columns;
mod lanes;

use super::layout::{LANES, Layout, Projections, Run, WIDE_BATCH};
use crate::sim::simd::{self, Build, Kernel};
pub(super) use columns::{Column, ReadColumn, SplitPositions};
use columns::{array, load, slot_of};
use lanes::{
    Batch, SlotConstants, ends, solve_contiguous, solve_gathered, solve_interleaved, update,
};

/// What one Gauss-Seidel sweep works on, for the thread or threads that run it.
pub(super) struct Sweep<'a> {
    pub p: &'a Projections,
    pub x: SplitPositions<'a>,
    pub lambda: Column<'a>,
    pub inv_h2: f32,
}

impl Sweep<'_> {
    /// Projects the springs of `runs`, one share of a colour (with `accumulate`, keeping the
    /// multipliers).
    ///
    /// # Safety
    /// As [`solve_springs`]: no other thread touches what `runs` touch meanwhile.
    pub unsafe fn run(&self, runs: &[Run], accumulate: bool) {
        let (p, x, lambda, inv_h2) = (self.p, self.x, self.lambda, self.inv_h2);
        // SAFETY: the caller's contract.
        unsafe {
            if accumulate {
                solve_springs::<true>(p, runs, x, lambda, inv_h2);
            } else {
                solve_springs::<false>(p, runs, x, lambda, inv_h2);
            }
        }
    }
}

/// One Gauss-Seidel sweep over the springs of `runs`, which are one share of a colour
/// ([`Projections::share`]; the layout pairs batches within a share): the XPBD update
/// `Δλ = (-C - α̃ λ) / (w_a + w_b + α̃)`, `α̃ = α / h²`, `C = |x_a - x_b| - L`, then
/// `x_a += w_a Δλ n`, `x_b -= w_b Δλ n` with `n = (x_a - x_b) / |x_a - x_b|`.
///
/// Slots go in batches of [`LANES`] along the [`Run`]s: contiguous and interleaved runs are read
/// and written with whole vector loads and stores, scattered ones gathered particle by particle;
/// the arithmetic (square root and division included) is the same lane-wise code for all, so the
/// layout never changes a result. With `ACCUMULATE = false` (one iteration per substep) λ is known
/// to be 0 and is neither read nor stored.
///
/// A vector [`Kernel`]: on x86-64 CPUs it runs as 8-wide AVX2 vectors, or with AVX-512 as 16-wide
/// ones where a contiguous run allows, two of them at once where it allows that or where the
/// layout pairs two batches of the share. The springs of a colour touch disjoint particles, so
/// their order changes no result: the results are bit-identical either way.
///
/// # Safety
/// While it runs, no other thread reads or writes the displacements of the particles, or the
/// multipliers of the slots, that `runs` touch (the runs of one colour's share, see
/// [`Projections::share`], touch none that the other share does).
pub(super) unsafe fn solve_springs<const ACCUMULATE: bool>(
    p: &Projections,
    runs: &[Run],
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
) {
    simd::run(SolveSprings::<ACCUMULATE> {
        p,
        runs,
        x,
        lambda,
        inv_h2,
    });
}

/// [`solve_springs`] in `build`, if the CPU has it; returns whether it ran. For the tests that
/// compare the builds.
///
/// # Safety
/// As [`solve_springs`].
#[cfg(test)]
pub(super) unsafe fn solve_springs_in<const ACCUMULATE: bool>(
    build: Build,
    p: &Projections,
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
) -> bool {
    let shares = (0..p.color_count()).flat_map(|c| [p.share(c, 0), p.share(c, 1)]);
    shares
        .map(|runs| {
            simd::run_as(
                build,
                SolveSprings::<ACCUMULATE> {
                    p,
                    runs,
                    x,
                    lambda,
                    inv_h2,
                },
            )
        })
        .fold(true, |ran, r| ran & r)
}

/// [`solve_springs`] in the plain build with its fused multiply-adds in plain arithmetic, as a
/// CPU without FMA runs it. For the tests that compare the builds.
///
/// # Safety
/// As [`solve_springs`].
#[cfg(test)]
pub(super) unsafe fn solve_springs_unfused<const ACCUMULATE: bool>(
    p: &Projections,
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
) {
    for c in 0..p.color_count() {
        for share in [p.share(c, 0), p.share(c, 1)] {
            // SAFETY: the caller's contract.
            unsafe { solve_springs_body::<ACCUMULATE, false, false>(p, share, x, lambda, inv_h2) };
        }
    }
}

/// [`solve_springs`]'s arguments, as a [`Kernel`]. Made only by [`solve_springs`], whose caller
/// promises the exclusive use of what `runs` touch.
struct SolveSprings<'a, const ACCUMULATE: bool> {
    p: &'a Projections,
    runs: &'a [Run],
    x: SplitPositions<'a>,
    lambda: Column<'a>,
    inv_h2: f32,
}

impl<const ACCUMULATE: bool> Kernel for SolveSprings<'_, ACCUMULATE> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let Self {
            p,
            runs,
            x,
            lambda,
            inv_h2,
        } = self;
        // Fused multiply-adds by the CPU's instructions where it has them, else by the same
        // rounding in plain arithmetic rather than a library call per lane.
        if simd::fma_in_hardware() {
            // SAFETY: the caller of `solve_springs`, which made `self`, has exclusive use of what
            // `runs` touch.
            unsafe { solve_springs_body::<ACCUMULATE, true, WIDE>(p, runs, x, lambda, inv_h2) };
        } else {
            // SAFETY: as above.
            unsafe { solve_springs_body::<ACCUMULATE, false, WIDE>(p, runs, x, lambda, inv_h2) };
        }
    }
}

/// The body of [`solve_springs`], which states its safety contract.
#[inline(always)]
unsafe fn solve_springs_body<const ACCUMULATE: bool, const FUSED: bool, const WIDE: bool>(
    p: &Projections,
    runs: &[Run],
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
) {
    assert!(
        ACCUMULATE || p.weighted_for(inv_h2),
        "the slots' weights are not set for this substep"
    );
    let inv_mass = &p.inv_mass[..];
    // Every column cut to the particle count, so that one bounds check per batch covers them all.
    let x = x.cut(inv_mass.len());
    // A batch of `WIDE_BATCH` slots waiting for another to be projected with: two chains of
    // square root and division in flight instead of one. The runs are one share of a colour,
    // and the pair touches disjoint particles, so it gives what the two give one after the
    // other.
    let mut waiting: Option<usize> = None;
    for run in runs {
        let (start, end) = (run.start as usize, (run.start + run.len) as usize);
        let mut k = start;
        if WIDE && run.layout == Layout::Contiguous {
            let offset = (p.b[k] - p.a[k]) as usize;
            // Four batches at once where their 64 particles are distinct: two independent chains
            // of square root and division in flight, which a batch mostly waits on.
            if offset >= 4 * LANES {
                // SAFETY: the batches' slots and particles are among those `runs` touch.
                k = unsafe {
                    solve_contiguous_run::<ACCUMULATE, FUSED, { 4 * LANES }>(
                        p, x, lambda, inv_h2, k, end,
                    )
                };
            }
            // Batches of 16 slots, paired as the layout says ([`Projections::solo`]).
            if offset >= WIDE_BATCH {
                while k + WIDE_BATCH <= end {
                    if p.solo[k] {
                        // SAFETY: as above.
                        unsafe {
                            solve_contiguous_at::<ACCUMULATE, FUSED, WIDE_BATCH>(
                                p, x, lambda, inv_h2, k,
                            )
                        };
                    } else if let Some(first) = waiting.take() {
                        // SAFETY: as above.
                        unsafe {
                            solve_contiguous_pair::<ACCUMULATE, FUSED>(
                                p,
                                x,
                                lambda,
                                inv_h2,
                                [first, k],
                            )
                        };
                    } else {
                        waiting = Some(k);
                    }
                    k += WIDE_BATCH;
                }
            }
        }
        if run.layout == Layout::Contiguous {
            // Every whole batch of the run: only a tail is left.
            // SAFETY: the run's slots and particles are among those `runs` touch.
            k = unsafe {
                solve_contiguous_run::<ACCUMULATE, FUSED, LANES>(p, x, lambda, inv_h2, k, end)
            };
        }
        while k + LANES <= end {
            let batch = Batch::at(p, lambda, k);
            let a = p.a[k] as usize;
            // SAFETY: the batch's slots and particles are among those `runs` touch.
            unsafe {
                match run.layout {
                    Layout::Contiguous => unreachable!("a contiguous run's batches are streamed"),
                    Layout::Interleaved(1) => {
                        solve_interleaved::<ACCUMULATE, FUSED, 1>(x, inv_mass, a, batch, inv_h2)
                    }
                    Layout::Interleaved(_) => {
                        solve_interleaved::<ACCUMULATE, FUSED, 2>(x, inv_mass, a, batch, inv_h2)
                    }
                    Layout::Scattered => solve_gathered::<ACCUMULATE, FUSED, LANES>(
                        &p.a, &p.b, x, inv_mass, batch, inv_h2,
                    ),
                }
            }
            k += LANES;
        }
        // Whatever is left of the run, one slot at a time.
        for k in k..end {
            let batch = Batch::<1>::at(p, lambda, k);
            // SAFETY: the slot and its particles are among those `runs` touch.
            unsafe {
                solve_gathered::<ACCUMULATE, FUSED, 1>(&p.a, &p.b, x, inv_mass, batch, inv_h2)
            };
        }
    }
    if let Some(k) = waiting {
        // SAFETY: as above.
        unsafe { solve_contiguous_at::<ACCUMULATE, FUSED, WIDE_BATCH>(p, x, lambda, inv_h2, k) };
    }
}

/// The slots of a contiguous run from `k` on, in batches of `N` while a whole batch fits before
/// `end` (the run's end); returns the first slot left. The run's two ends must be at least `N`
/// particles apart, so that a batch's particles are distinct.
///
/// In a contiguous run slot `k + m` joins particles `a + m` and `b + m`, with `a` and `b` those
/// of slot `k` ([`Layout::Contiguous`]), so one bounds test covers the whole run and its batches
/// are streamed, without looking up their particles, layout or bounds one by one. The arithmetic
/// is [`update`]'s, as for a batch on its own.
///
/// # Safety
/// As [`solve_contiguous`], for the slots `k..end`, which are part of one contiguous run (the
/// particles touched are those the layout gives the slots).
#[inline(always)]
unsafe fn solve_contiguous_run<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    p: &Projections,
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
    k: usize,
    end: usize,
) -> usize {
    let count = end.saturating_sub(k) / N * N;
    if count == 0 {
        return k;
    }
    let (a, b) = (p.a[k] as usize, p.b[k] as usize);
    let inv_mass = &p.inv_mass[..];
    // The one test for every access below.
    let n = inv_mass.len();
    let slots = [&p.rest, &p.compliance, &p.weights[0], &p.weights[1]];
    assert!(
        a.max(b) + count <= n
            && x.start.iter().all(|c| c.len() == n)
            && x.delta.iter().all(|c| c.len() == n)
            && slots.iter().all(|v| k + count <= v.len())
            && (!ACCUMULATE || k + count <= lambda.len()),
        "a run past the particles or the slots"
    );
    let mut m = 0;
    while m < count {
        let (ia, ib, i) = (a + m, b + m, k + m);
        // SAFETY: every index is within the run, in bounds (tested above); the caller has
        // exclusive use of what the run touches.
        unsafe {
            let s = ends(ia, ib, |c, j| x.start[c].load_unchecked(j));
            let mut d = ends(ia, ib, |c, j| x.delta[c].load_unchecked(j));
            let (wa, wb) = (slot_of::<N>(inv_mass, ia), slot_of::<N>(inv_mass, ib));
            let mut lam = if ACCUMULATE {
                lambda.load_unchecked::<N>(i)
            } else {
                [0.0; N]
            };
            let constants = SlotConstants {
                rest: slot_of(&p.rest, i),
                compliance: slot_of(&p.compliance, i),
                weights: [slot_of(&p.weights[0], i), slot_of(&p.weights[1], i)],
            };
            update::<ACCUMULATE, FUSED, N>(&s, &mut d, (wa, wb), constants, &mut lam, inv_h2);
            for (c, coord) in x.delta.iter().enumerate() {
                coord.store_unchecked(ia, &d[c]);
                coord.store_unchecked(ib, &d[c + 3]);
            }
            if ACCUMULATE {
                lambda.store_unchecked(i, &lam);
            }
        }
        m += N;
    }
    k + count
}

/// The contiguous batch of `N` slots at slot `k`.
///
/// # Safety
/// As [`solve_contiguous`].
#[inline(always)]
unsafe fn solve_contiguous_at<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    p: &Projections,
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
    k: usize,
) {
    let batch = Batch::at(p, lambda, k);
    let (a, b) = (p.a[k] as usize, p.b[k] as usize);
    // SAFETY: the caller's contract.
    unsafe { solve_contiguous::<ACCUMULATE, FUSED, N>(x, &p.inv_mass, a, b, batch, inv_h2) };
}

/// Two contiguous batches of [`WIDE_BATCH`] slots, at slots `k[0]` and `k[1]`, projected as one
/// of twice the width. The result is that of the two in turn only if their particles are
/// disjoint (the layout pairs only such batches).
///
/// # Safety
/// As [`solve_contiguous`], for both batches.
#[inline(always)]
unsafe fn solve_contiguous_pair<const ACCUMULATE: bool, const FUSED: bool>(
    p: &Projections,
    x: SplitPositions,
    lambda: Column,
    inv_h2: f32,
    k: [usize; 2],
) {
    const N: usize = WIDE_BATCH;
    let inv_mass = &p.inv_mass[..];
    let [(a0, b0), (a1, b1)] = k.map(|k| (p.a[k] as usize, p.b[k] as usize));
    // One test covers every load and store below (the columns are cut to the particle count).
    assert!(
        a0.max(b0).max(a1).max(b1) + N <= inv_mass.len(),
        "a batch past the particles"
    );
    // Plain copies rather than `std::array::from_fn`, whose closures the compiler may leave
    // uninlined in this hot loop.
    let both = |first: [f32; N], second: [f32; N]| -> [f32; 2 * N] {
        let mut v = [0.0; 2 * N];
        v[..N].copy_from_slice(&first);
        v[N..].copy_from_slice(&second);
        v
    };
    let both6 = |first: [[f32; N]; 6], second: [[f32; N]; 6]| -> [[f32; 2 * N]; 6] {
        let mut v = [[0.0; 2 * N]; 6];
        for e in 0..6 {
            v[e] = both(first[e], second[e]);
        }
        v
    };
    let slots = |v: &[f32]| both(load(v, k[0]), load(v, k[1]));
    let s = ends(a0, b0, |c, i| x.start[c].load::<N>(i));
    let t = ends(a1, b1, |c, i| x.start[c].load::<N>(i));
    let s = both6(s, t);
    // SAFETY: the caller's contract.
    let (d, e) = unsafe {
        (
            ends(a0, b0, |c, i| x.delta[c].load::<N>(i)),
            ends(a1, b1, |c, i| x.delta[c].load::<N>(i)),
        )
    };
    let mut d = both6(d, e);
    let wa = both(load(inv_mass, a0), load(inv_mass, a1));
    let wb = both(load(inv_mass, b0), load(inv_mass, b1));
    let mut lam = if ACCUMULATE {
        // SAFETY: the caller's contract.
        unsafe { both(lambda.load(k[0]), lambda.load(k[1])) }
    } else {
        [0.0; 2 * N]
    };
    let (rest, compliance) = (slots(&p.rest), slots(&p.compliance));
    let weights = [slots(&p.weights[0]), slots(&p.weights[1])];
    let constants = SlotConstants {
        rest: &rest,
        compliance: &compliance,
        weights: [&weights[0], &weights[1]],
    };
    update::<ACCUMULATE, FUSED, { 2 * N }>(&s, &mut d, (&wa, &wb), constants, &mut lam, inv_h2);
    let half = |v: &[f32; 2 * N], h: usize| -> [f32; N] { *array(&v[h * N..(h + 1) * N]) };
    for (c, coord) in x.delta.iter().enumerate() {
        // SAFETY: the caller's contract.
        unsafe {
            coord.store(a0, &half(&d[c], 0));
            coord.store(b0, &half(&d[c + 3], 0));
            coord.store(a1, &half(&d[c], 1));
            coord.store(b1, &half(&d[c + 3], 1));
        }
    }
    if ACCUMULATE {
        // SAFETY: the caller's contract.
        unsafe {
            lambda.store(k[0], &half(&lam, 0));
            lambda.store(k[1], &half(&lam, 1));
        }
    }
}

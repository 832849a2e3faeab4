//! XPBD's spring kernel: one Gauss-Seidel sweep over a layout's runs ([`solve_springs`]), on
//! columns that the two threads of a shared sweep use at once. The types say who may do what:
//! a [`Read`] column is shared and only read (the substep's start positions), a [`Column`] is
//! written by both threads, each only at the particles and slots of its own share of a colour,
//! so its loads and stores are `unsafe` and every caller names the share that makes them
//! exclusive ([`Projections`] keeps the shares of a colour disjoint).

use std::marker::PhantomData;

use super::layout::{LANES, Layout, Projections, Run, WIDE_BATCH, interleaved_offset};
use crate::sim::simd::{self, Build, Kernel};

/// A column of `f32` that every thread of a sweep only reads.
#[derive(Clone, Copy)]
pub(super) struct Read<'a>(&'a [f32]);

impl<'a> Read<'a> {
    /// The elements of `s`.
    pub fn new(s: &'a [f32]) -> Self {
        Self(s)
    }

    /// The first `n` elements (a panic if there are fewer).
    #[inline(always)]
    fn cut(self, n: usize) -> Self {
        Self(&self.0[..n])
    }

    /// Copies `N` values starting at `i`.
    #[inline(always)]
    fn load<const N: usize>(self, i: usize) -> [f32; N] {
        load(self.0, i)
    }

    /// Element `i`.
    #[inline(always)]
    fn get(self, i: usize) -> f32 {
        self.0[i]
    }

    /// Copies `N` values starting at `i`, without a bounds test.
    ///
    /// # Safety
    /// `i + N` is at most the length.
    #[inline(always)]
    unsafe fn load_unchecked<const N: usize>(self, i: usize) -> [f32; N] {
        // SAFETY: the caller's contract.
        unsafe { *slot_of(self.0, i) }
    }
}

/// A column of `f32` (a coordinate of the displacements, or the multipliers) that the threads of
/// a sweep write at once, each at its own elements: a pointer and a length, borrowed from a
/// `&mut [f32]` for `'a`. Every access is `unsafe`: its caller promises that no other thread
/// touches the same elements meanwhile. An index out of range is a panic, never an access.
#[derive(Clone, Copy)]
pub(super) struct Column<'a> {
    ptr: *mut f32,
    len: usize,
    life: PhantomData<&'a mut [f32]>,
}

// SAFETY: a column gives access to its elements only through `unsafe` methods, whose callers
// promise that no two threads touch the same element at once.
unsafe impl Send for Column<'_> {}
// SAFETY: as above.
unsafe impl Sync for Column<'_> {}

impl<'a> Column<'a> {
    /// The elements of `s`, which the column borrows exclusively for `'a`.
    pub fn new(s: &'a mut [f32]) -> Self {
        Self {
            ptr: s.as_mut_ptr(),
            len: s.len(),
            life: PhantomData,
        }
    }

    /// The first `n` elements (a panic if there are fewer).
    #[inline(always)]
    fn cut(self, n: usize) -> Self {
        assert!(n <= self.len, "a column cut past its end");
        Self { len: n, ..self }
    }

    /// Panics unless `i..i + n` is in range; the same test as slicing `i..i + n`, so that one
    /// test per batch of the kernel covers every access to it.
    #[inline(always)]
    fn check(self, i: usize, n: usize) {
        let end = i + n;
        assert!(
            i <= end && end <= self.len,
            "a column accessed past its end"
        );
    }

    /// Copies `N` values starting at `i`.
    ///
    /// # Safety
    /// No other thread writes elements `i..i + N` meanwhile.
    #[inline(always)]
    pub unsafe fn load<const N: usize>(self, i: usize) -> [f32; N] {
        self.check(i, N);
        // SAFETY: in bounds (checked) and within the borrow; no other thread writes there.
        unsafe { self.ptr.add(i).cast::<[f32; N]>().read_unaligned() }
    }

    /// Writes `values` to elements `i..i + N`.
    ///
    /// # Safety
    /// No other thread reads or writes elements `i..i + N` meanwhile.
    #[inline(always)]
    pub unsafe fn store<const N: usize>(self, i: usize, values: &[f32; N]) {
        self.check(i, N);
        // SAFETY: in bounds (checked) and within the borrow; no other thread touches them.
        unsafe { self.ptr.add(i).cast::<[f32; N]>().write_unaligned(*values) }
    }

    /// [`Self::load`] without the bounds test.
    ///
    /// # Safety
    /// As [`Self::load`], and `i + N` is at most the length.
    #[inline(always)]
    unsafe fn load_unchecked<const N: usize>(self, i: usize) -> [f32; N] {
        debug_assert!(i + N <= self.len);
        // SAFETY: in bounds and within the borrow; no other thread writes there (the caller's
        // contract).
        unsafe { self.ptr.add(i).cast::<[f32; N]>().read_unaligned() }
    }

    /// [`Self::store`] without the bounds test.
    ///
    /// # Safety
    /// As [`Self::store`], and `i + N` is at most the length.
    #[inline(always)]
    unsafe fn store_unchecked<const N: usize>(self, i: usize, values: &[f32; N]) {
        debug_assert!(i + N <= self.len);
        // SAFETY: in bounds and within the borrow; no other thread touches them (the caller's
        // contract).
        unsafe { self.ptr.add(i).cast::<[f32; N]>().write_unaligned(*values) }
    }

    /// Elements `range`, as a slice (a panic if out of range).
    ///
    /// # Safety
    /// Nothing else reads or writes them while the slice lives.
    pub unsafe fn slice_mut(self, range: std::ops::Range<usize>) -> &'a mut [f32] {
        assert!(range.start <= range.end, "an inverted column range");
        self.check(range.start, range.len());
        // SAFETY: in bounds (checked) and within the borrow; exclusive (the caller's contract).
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// Element `i`.
    ///
    /// # Safety
    /// As [`Self::load`].
    #[inline(always)]
    unsafe fn get(self, i: usize) -> f32 {
        // SAFETY: the caller's contract.
        unsafe { self.load::<1>(i)[0] }
    }

    /// Sets element `i`.
    ///
    /// # Safety
    /// As [`Self::store`].
    #[inline(always)]
    unsafe fn set(self, i: usize, value: f32) {
        // SAFETY: the caller's contract.
        unsafe { self.store::<1>(i, &[value]) }
    }
}

/// Positions during XPBD's projection, one column per coordinate: where each particle began the
/// substep, and its displacement since. The corrections accumulate in the small displacements
/// rather than in the large positions, so that f32 keeps them (added to a position of about 1 m,
/// a correction below 1e-7 m would vanish, and the velocity `Δx / h` with it).
#[derive(Clone, Copy)]
pub(super) struct Split<'a> {
    pub start: [Read<'a>; 3],
    pub delta: [Column<'a>; 3],
}

impl Split<'_> {
    /// Every column cut to `n` elements.
    #[inline(always)]
    fn cut(self, n: usize) -> Self {
        Self {
            start: self.start.map(|c| c.cut(n)),
            delta: self.delta.map(|c| c.cut(n)),
        }
    }
}

/// What one Gauss-Seidel sweep works on, for the thread or threads that run it.
pub(super) struct Sweep<'a> {
    pub p: &'a Projections,
    pub x: Split<'a>,
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
    x: Split,
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
    x: Split,
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
    x: Split,
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
    x: Split<'a>,
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

/// The per-slot constants of the batch at slots `k..k + N`, and where its multipliers live.
struct Batch<'a, const N: usize> {
    slots: Slots<'a, N>,
    lambda: Column<'a>,
    k: usize,
}

impl<'a, const N: usize> Batch<'a, N> {
    /// Slots `k..k + N` of `p` (the runs never reach past the slots: a panic if they did).
    #[inline(always)]
    fn at(p: &'a Projections, lambda: Column<'a>, k: usize) -> Self {
        let slots = |v: &'a [f32]| array(&v[k..k + N]);
        Self {
            slots: Slots {
                rest: slots(&p.rest),
                compliance: slots(&p.compliance),
                weights: [slots(&p.weights[0]), slots(&p.weights[1])],
            },
            lambda,
            k,
        }
    }
}

/// `s` as an array (its length is `N`: slices of `N` elements are passed).
#[inline(always)]
fn array<const N: usize>(s: &[f32]) -> &[f32; N] {
    s.try_into().expect("a batch is N slots")
}

/// The body of [`solve_springs`], which states its safety contract.
#[inline(always)]
unsafe fn solve_springs_body<const ACCUMULATE: bool, const FUSED: bool, const WIDE: bool>(
    p: &Projections,
    runs: &[Run],
    x: Split,
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

/// The lane-wise XPBD update of `N` independent slots: `s[0..3]` are the first ends' x, y, z
/// at the start of the substep and `s[3..6]` the second ends', `d` their displacements since,
/// which the update moves.
///
/// # Safety
/// No other thread touches the batch's multipliers while it runs.
#[inline(always)]
unsafe fn project<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
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
struct Slots<'a, const N: usize> {
    rest: &'a [f32; N],
    compliance: &'a [f32; N],
    weights: [&'a [f32; N]; 2],
}

/// [`project`]'s arithmetic, lane by lane, with the batch's inverse masses and constants, and its
/// multipliers in `lambda` (read and written only with `ACCUMULATE`). Without `ACCUMULATE`, λ is
/// 0 and the update is `w_a Δλ = (L - |d|) / |d| · w_a / (w_a + w_b + α̃)`, whose second factor
/// the layout keeps per slot ([`Projections::weights`]): fewer operations per spring, and neither
/// the inverse masses nor the compliances are read.
#[inline(always)]
fn update<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    s: &[[f32; N]; 6],
    d: &mut [[f32; N]; 6],
    (wa, wb): (&[f32; N], &[f32; N]),
    slots: Slots<'_, N>,
    lambda: &mut [f32; N],
    inv_h2: f32,
) {
    let Slots {
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

/// Copies `N` values starting at `i` out of `v`.
#[inline(always)]
fn load<const N: usize>(v: &[f32], i: usize) -> [f32; N] {
    *array(&v[i..i + N])
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
    x: Split,
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
            && x.start.iter().all(|c| c.0.len() == n)
            && x.delta.iter().all(|c| c.len == n)
            && slots.iter().all(|v| k + count <= v.len())
            && (!ACCUMULATE || k + count <= lambda.len),
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
            let constants = Slots {
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

/// `N` values of `v` from `i` on, without a bounds test.
///
/// # Safety
/// `i + N` is at most `v`'s length.
#[inline(always)]
unsafe fn slot_of<const N: usize>(v: &[f32], i: usize) -> &[f32; N] {
    debug_assert!(i + N <= v.len());
    // SAFETY: in bounds (the caller's contract).
    unsafe { &*v.as_ptr().add(i).cast::<[f32; N]>() }
}

/// The contiguous batch of `N` slots at slot `k`.
///
/// # Safety
/// As [`solve_contiguous`].
#[inline(always)]
unsafe fn solve_contiguous_at<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    p: &Projections,
    x: Split,
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
    x: Split,
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
    let constants = Slots {
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

/// Slots joining particles `ia..ia + N` to `ib..ib + N`.
///
/// # Safety
/// No other thread touches those particles' displacements or the batch's multipliers while it
/// runs.
#[inline(always)]
unsafe fn solve_contiguous<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    x: Split,
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
fn ends<const N: usize>(
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
unsafe fn solve_interleaved<const ACCUMULATE: bool, const FUSED: bool, const D: usize>(
    x: Split,
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
unsafe fn solve_gathered<const ACCUMULATE: bool, const FUSED: bool, const N: usize>(
    a: &[u32],
    b: &[u32],
    x: Split,
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

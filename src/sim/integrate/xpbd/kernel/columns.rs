//! The columns XPBD's spring kernel works on, and who may do what with them: a [`ReadColumn`] is
//! shared and only read (the substep's start positions), a [`Column`] is written by both threads
//! of a shared sweep, each only at the particles and slots of its own share of a colour, so its
//! loads and stores are `unsafe` and every caller names the share that makes them exclusive
//! ([`Projections`](super::super::layout::Projections) keeps the shares of a colour disjoint).
//! Also the plain slice reads the kernel shares. No arithmetic of the projection here.

use std::marker::PhantomData;

/// A column of `f32` that every thread of a sweep only reads.
#[derive(Clone, Copy)]
pub(in super::super) struct ReadColumn<'a>(&'a [f32]);

impl<'a> ReadColumn<'a> {
    /// The elements of `s`.
    pub fn new(s: &'a [f32]) -> Self {
        Self(s)
    }

    /// The first `n` elements (a panic if there are fewer).
    #[inline(always)]
    pub(super) fn cut(self, n: usize) -> Self {
        Self(&self.0[..n])
    }

    /// Copies `N` values starting at `i`.
    #[inline(always)]
    pub(super) fn load<const N: usize>(self, i: usize) -> [f32; N] {
        load(self.0, i)
    }

    /// Element `i`.
    #[inline(always)]
    pub(super) fn get(self, i: usize) -> f32 {
        self.0[i]
    }

    /// The number of elements.
    #[inline(always)]
    pub(super) fn len(self) -> usize {
        self.0.len()
    }

    /// Copies `N` values starting at `i`, without a bounds test.
    ///
    /// # Safety
    /// `i + N` is at most the length.
    #[inline(always)]
    pub(super) unsafe fn load_unchecked<const N: usize>(self, i: usize) -> [f32; N] {
        // SAFETY: the caller's contract.
        unsafe { *slot_of(self.0, i) }
    }
}

/// A column of `f32` (a coordinate of the displacements, or the multipliers) that the threads of
/// a sweep write at once, each at its own elements: a pointer and a length, borrowed from a
/// `&mut [f32]` for `'a`. Every access is `unsafe`: its caller promises that no other thread
/// touches the same elements meanwhile. An index out of range is a panic, never an access.
#[derive(Clone, Copy)]
pub(in super::super) struct Column<'a> {
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
    pub(super) fn cut(self, n: usize) -> Self {
        assert!(n <= self.len, "a column cut past its end");
        Self { len: n, ..self }
    }

    /// The number of elements.
    #[inline(always)]
    pub(super) fn len(self) -> usize {
        self.len
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
    pub(super) unsafe fn load_unchecked<const N: usize>(self, i: usize) -> [f32; N] {
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
    pub(super) unsafe fn store_unchecked<const N: usize>(self, i: usize, values: &[f32; N]) {
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
    pub(super) unsafe fn get(self, i: usize) -> f32 {
        // SAFETY: the caller's contract.
        unsafe { self.load::<1>(i)[0] }
    }

    /// Sets element `i`.
    ///
    /// # Safety
    /// As [`Self::store`].
    #[inline(always)]
    pub(super) unsafe fn set(self, i: usize, value: f32) {
        // SAFETY: the caller's contract.
        unsafe { self.store::<1>(i, &[value]) }
    }
}

/// Positions during XPBD's projection, one column per coordinate: where each particle began the
/// substep, and its displacement since. The corrections accumulate in the small displacements
/// rather than in the large positions, so that f32 keeps them (added to a position of about 1 m,
/// a correction below 1e-7 m would vanish, and the velocity `Δx / h` with it).
#[derive(Clone, Copy)]
pub(in super::super) struct SplitPositions<'a> {
    pub start: [ReadColumn<'a>; 3],
    pub delta: [Column<'a>; 3],
}

impl SplitPositions<'_> {
    /// Every column cut to `n` elements.
    #[inline(always)]
    pub(super) fn cut(self, n: usize) -> Self {
        Self {
            start: self.start.map(|c| c.cut(n)),
            delta: self.delta.map(|c| c.cut(n)),
        }
    }
}

/// `s` as an array (its length is `N`: slices of `N` elements are passed).
#[inline(always)]
pub(super) fn array<const N: usize>(s: &[f32]) -> &[f32; N] {
    s.try_into().expect("a batch is N slots")
}

/// Copies `N` values starting at `i` out of `v`.
#[inline(always)]
pub(super) fn load<const N: usize>(v: &[f32], i: usize) -> [f32; N] {
    *array(&v[i..i + N])
}

/// `N` values of `v` from `i` on, without a bounds test.
///
/// # Safety
/// `i + N` is at most `v`'s length.
#[inline(always)]
pub(super) unsafe fn slot_of<const N: usize>(v: &[f32], i: usize) -> &[f32; N] {
    debug_assert!(i + N <= v.len());
    // SAFETY: in bounds (the caller's contract).
    unsafe { &*v.as_ptr().add(i).cast::<[f32; N]>() }
}

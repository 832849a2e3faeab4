//! Runs: stretches of springs `(aₖ, aₖ + d)` of one index offset `d` whose first particles
//! increase, which a vector kernel reads and writes with whole vector loads and stores. The
//! explicit integrators' force kernel (`forces.rs`) and XPBD's projection layout
//! (`integrate/xpbd/layout.rs`) both lay their springs out in runs found here.

/// Longest hole (in slots) inside a run that is padded rather than ending the run: the row ends of
/// a grid leave holes of one or two.
pub(crate) const MAX_GAP: usize = 2;

/// The run that starts at spring `i` of the springs `a[..end]`, `b[..end]` (sorted by offset
/// `b - a`, then by `a`; `b[i] ≥ a[i]`): the springs after `i` with its offset whose slots,
/// `slot_of(a[k] - a[i])`, increase with holes of at most [`MAX_GAP`]. `slot_of` maps a first
/// particle's distance from the run's first to its slot (`None`: no slot holds it). Returns the
/// number of springs taken (`i..i + taken`) and of slots (the last one's slot + 1).
pub(crate) fn extent(
    a: &[u32],
    b: &[u32],
    i: usize,
    end: usize,
    slot_of: impl Fn(usize) -> Option<usize>,
) -> (usize, usize) {
    let d = b[i] - a[i];
    let (mut last, mut k) = (0, i + 1);
    while k < end && b[k].checked_sub(a[k]) == Some(d) && a[k] > a[i] {
        match slot_of((a[k] - a[i]) as usize) {
            Some(m) if m > last && m - last - 1 <= MAX_GAP => last = m,
            _ => break,
        }
        k += 1;
    }
    (k - i, last + 1)
}

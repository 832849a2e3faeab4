//! Candidates ordered into bands of their distance at the search, so that a substep's first pass
//! stops at the first band none of whose candidates can have come within their kept distance.

use super::max_or_infinite;

/// GapBands of distance a search's candidates are ordered into (see [`GapBands`]).
const GAP_BANDS: usize = 32;

/// Candidates of a search in bands of growing distance at the search: a substep's first pass
/// over them ([`Self::visit`]) stops at the first band none of whose candidates can have come
/// within their thickness since, and so do the farther bands after it. A resting pile's pass
/// visits only the candidates that were about touching.
#[derive(Debug, Clone, Default)]
pub(in crate::sim::contact) struct GapBands {
    /// The first candidate (its index in the ordered list).
    start: u32,
    /// The bands in order.
    list: Vec<GapBand>,
}

/// One band of [`GapBands`]: where its candidates end, their least distance and largest thickness.
#[derive(Debug, Clone, Copy)]
struct GapBand {
    /// The end of the band's candidates (exclusive).
    end: u32,
    /// The least distance at the search among them, m.
    least: f32,
    /// The largest thickness among them, m.
    thickness: f32,
}

impl GapBands {
    /// Orders the candidates `range` into [`GAP_BANDS`] bands of their distance at the search below
    /// `margin` (`pair(k)`: candidate `k`'s distance and thickness; those past the margin go to
    /// the last band), each band keeping their order: appends them to `order` in their new order
    /// and lists the bands.
    pub(in crate::sim::contact) fn order(
        &mut self,
        range: std::ops::Range<usize>,
        margin: f32,
        pair: impl Fn(usize) -> (f32, f32),
        order: &mut Vec<u32>,
    ) {
        let width = margin / GAP_BANDS as f32;
        // NaN and negative distances go to the first band.
        let band = |gap: f32| ((gap / width) as usize).min(GAP_BANDS - 1);
        let mut count = [0u32; GAP_BANDS];
        let mut list = [(f32::INFINITY, 0.0f32); GAP_BANDS];
        for k in range.clone() {
            let (gap, thickness) = pair(k);
            let b = band(gap);
            count[b] += 1;
            // A NaN distance is passed over: such a candidate never passes the filter.
            list[b] = (list[b].0.min(gap), list[b].1.max(thickness));
        }
        self.start = order.len() as u32;
        self.list.clear();
        let mut next = [0u32; GAP_BANDS];
        let mut end = self.start;
        for b in 0..GAP_BANDS {
            next[b] = end;
            end += count[b];
            if count[b] > 0 {
                let (least, thickness) = list[b];
                self.list.push(GapBand {
                    end,
                    least,
                    thickness,
                });
            }
        }
        order.resize(end as usize, 0);
        for k in range {
            let b = band(pair(k).0);
            order[next[b] as usize] = k as u32;
            next[b] += 1;
        }
    }

    /// Calls `f(k)` for the candidates in order, band by band, while a band may hold one that
    /// came within its thickness: particles of a candidate came closer by at most `closing` (m)
    /// since the search, and after `f(k)` by at most twice what it returns (the largest drift
    /// among its particles after it acted, or 0). Returns the bound at the end.
    pub(in crate::sim::contact) fn visit(
        &self,
        mut closing: f32,
        mut f: impl FnMut(usize) -> f32,
    ) -> f32 {
        let mut k = self.start as usize;
        for band in &self.list {
            if band.least - closing > band.thickness {
                break;
            }
            for k in k..band.end as usize {
                // Most candidates do not act (0): the bound is left alone rather than carried
                // through a `max` per candidate.
                let drift = f(k);
                if drift != 0.0 {
                    closing = max_or_infinite(closing, 2.0 * drift);
                }
            }
            k = band.end as usize;
        }
        closing
    }
}

/// Replaces `v` by its elements at `order`, building it in `scratch` (which keeps the old list).
pub(in crate::sim::contact) fn reorder<T: Copy>(
    v: &mut Vec<T>,
    scratch: &mut Vec<T>,
    order: impl Iterator<Item = usize>,
) {
    scratch.clear();
    scratch.extend(order.map(|k| v[k]));
    std::mem::swap(v, scratch);
}

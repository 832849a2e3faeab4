//! Items grouped by a number each: a patch's vertices, triangles and edges, a block's cubes.

/// Items grouped by a number each (a patch, a block): those of group `g` are
/// `items[start[g]..start[g + 1]]`.
#[derive(Debug, Clone, Default)]
pub(super) struct ItemsByGroup {
    pub(super) start: Vec<u32>,
    pub(super) items: Vec<u32>,
}

impl ItemsByGroup {
    /// Items `0..` grouped by `group` (of each item in order; one not below `groups` in none).
    pub(super) fn new(groups: usize, group: impl Iterator<Item = u32> + Clone) -> Self {
        let mut grouped = Self::default();
        grouped.regroup(groups, group);
        grouped
    }

    /// [`Self::new`] in place, keeping the allocations.
    pub(super) fn regroup(&mut self, groups: usize, group: impl Iterator<Item = u32> + Clone) {
        let (start, items) = (&mut self.start, &mut self.items);
        start.clear();
        start.resize(groups + 1, 0);
        for g in group.clone().filter(|&g| (g as usize) < groups) {
            start[g as usize + 1] += 1;
        }
        for g in 0..groups {
            start[g + 1] += start[g];
        }
        items.clear();
        items.resize(start[groups] as usize, 0);
        // Each group's start moves on as its items are placed, ending where the next begins;
        // then every start goes back one group.
        for (i, g) in group.enumerate().filter(|&(_, g)| (g as usize) < groups) {
            items[start[g as usize] as usize] = i as u32;
            start[g as usize] += 1;
        }
        start.copy_within(0..groups, 1);
        start[0] = 0;
    }

    /// The items of group `g`.
    pub(super) fn of(&self, g: u32) -> &[u32] {
        &self.items[self.range(g)]
    }

    /// Where group `g`'s items are in `items`.
    pub(super) fn range(&self, g: u32) -> std::ops::Range<usize> {
        self.start[g as usize] as usize..self.start[g as usize + 1] as usize
    }
}

//! When the candidates are found again, and when a check or a search is skipped.

use super::*;

#[test]
fn a_skipped_check_never_lets_particles_come_closer_than_the_reach() {
    // A 12×12 grid flying along fast and steadily, one half of it drifting off the other's
    // plane: no pair comes near, but the halves move apart (relative to each other) by a
    // little every substep, so the candidates must be found again now and then.
    let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
    let rest = &model.rest_positions;
    let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0).unwrap();
    let [a, b, d] = [0, 1, 12].map(|i| rest[i]);
    let normal = (b - a).cross(d - a).normalize();
    let at = |k: usize| -> Vec<Vec3> {
        let k = k as f32;
        rest.iter()
            .map(|p| {
                let lift = if p.distance(a) > 0.2 { 3e-4 * k } else { 0.0 };
                *p + Vec3::new(0.012, -0.004, 0.008) * k + normal * lift
            })
            .collect()
    };
    let w = vec![1.0; rest.len()];
    let (mut skipped, mut searches) = (0, 0);
    for k in 1..300 {
        let (start, mut x) = (at(k - 1), at(k));
        let mut v = vec![Vec3::ZERO; x.len()];
        resolve_within(&mut c, 0.01, &start, &mut x, &mut v, &w);
        if c.searches() > searches {
            searches = c.searches();
            continue;
        }
        skipped += usize::from(c.cubes.skipped > 0);
        // Kept candidates hold every pair that came within the larger of their cubes' limits
        // of each other (neighbours), the far limit (within a block's size) or the wide limit
        // (any two), relative to where they were found, and each edge's ends within twice
        // the reach.
        let x = at(k);
        let moved: Vec<Vec3> = x.iter().zip(&c.found).map(|(x, f)| *x - *f).collect();
        let cube = |p: usize| c.cubes.limit[c.cubes.of[p] as usize];
        for p in 0..x.len() {
            for q in p + 1..x.len() {
                let closer = moved[p].distance(moved[q]);
                let apart = c.found[p].distance(c.found[q]) / c.cubes.size;
                // Particles found farther apart than a cube's side may come closer by their
                // distance less two edges and the thickness (the far limit at a side).
                let limit = if apart < 1.0 {
                    cube(p).max(cube(q))
                } else {
                    c.far_limit + (apart - 1.0) * c.cubes.size
                };
                assert!(
                    closer <= limit,
                    "substep {k}: {p}, {q} came {closer} closer"
                );
            }
        }
        for &[a, b] in &c.edges {
            let closer = moved[a as usize].distance(moved[b as usize]);
            assert!(closer <= 2.0 * c.reach, "substep {k}: edge {a}, {b}");
        }
    }
    assert!(
        searches > 2 && skipped > 150,
        "{searches} searches, {skipped} skipped"
    );
}

#[test]
fn the_far_limit_holds_for_elements_with_particles_in_cubes_not_neighbouring() {
    // Two triangles whose long edges (4 cm; the shortest edge 1 cm) lie along x, the second
    // beyond the first and 5 mm above its line, so that the first edge's near end and the
    // second's far end lie in cubes two apart while the edges' facing ends are a cube's size
    // less two edges apart. Any two particles may come closer by the far limit before the
    // cubes' check asks for a search, so every pair of elements with such particles must be
    // farther apart than that plus the thickness.
    let place = |size: f32| {
        let a = Vec3::new(0.99 * size, 0.0, 0.0);
        let c = a + Vec3::new(1.02 * size - 0.04, 0.005, 0.0);
        vec![
            a,
            a + Vec3::new(0.04, 0.0, 0.0),
            a + Vec3::new(0.0, 0.0, -0.01),
            c,
            c + Vec3::new(0.04, 0.0, 0.0),
            c + Vec3::new(0.04, 0.0, 0.01),
        ]
    };
    let thickness = 0.001;
    // The cubes' size depends on the edges' lengths only.
    let size = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &place(0.1), thickness, 0.0)
        .unwrap()
        .cubes
        .size;
    let x = place(size);
    let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &x, thickness, 0.0).unwrap();
    assert!((c.cubes.size - size).abs() < 1e-6);
    let (mut moved, mut v, w) = (x.clone(), vec![Vec3::ZERO; 6], vec![1.0; 6]);
    resolve(&mut c, &x, &mut moved, &mut v, &w);
    assert_eq!(c.searches(), 1);
    let of = &c.cubes.of;
    let apart = |p: usize, q: usize| {
        let cell = |i: usize| cell_of(x[i], 1.0 / c.cubes.size);
        let (a, b) = (cell(p), cell(q));
        (0..3).any(|k| (a[k] - b[k]).abs() > 1)
    };
    assert!(
        apart(0, 4) && of[0] != of[4],
        "the ends are in cubes two apart"
    );
    let mut checked = 0;
    for e in &c.edges {
        for f in &c.edges {
            let quad = [e[0], e[1], f[0], f[1]].map(|i| i as usize);
            let far = (0..2).any(|i| (2..4).any(|j| apart(quad[i], quad[j])));
            if quad[..2].iter().any(|i| quad[2..].contains(i)) || !far {
                continue;
            }
            let [a, b, p, q] = quad.map(|i| x[i]);
            let (s, t) = closest_on_segments(a, b, p, q);
            let gap = a.lerp(b, s).distance(p.lerp(q, t));
            assert!(
                gap >= c.far_limit + thickness,
                "edges {e:?} and {f:?} are {gap} apart, the far limit {}",
                c.far_limit
            );
            checked += 1;
        }
    }
    assert!(checked > 0);
}

#[test]
fn particles_in_blocks_not_neighbouring_search_again_past_the_wide_limit() {
    // Two triangles (1 cm sides) ten cubes apart along x, in blocks that are not neighbours:
    // the second slides toward the first, rigidly, so only the bound over any two particles
    // sees it.
    let triangle = |at: f32| {
        let a = Vec3::new(at, 0.0, 0.0);
        [
            a,
            a + Vec3::new(0.01, 0.0, 0.0),
            a + Vec3::new(0.0, 0.0, 0.01),
        ]
    };
    let size = SelfContacts::new(&[0, 1, 2], &triangle(0.0), 0.001, 0.0)
        .unwrap()
        .cubes
        .size;
    let place = |shift: f32| -> Vec<Vec3> {
        triangle(0.0)
            .into_iter()
            .chain(triangle(10.0 * size - shift))
            .collect()
    };
    let w = vec![1.0; 6];
    // Searched where it starts, then slid over one substep (the first check after a search
    // takes the cubes' references from that substep, so only the slide counts).
    let slid = |by: f32| {
        let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &place(0.0), 0.001, 0.0).unwrap();
        let (start, mut x, mut v) = (place(0.0), place(0.0), vec![Vec3::ZERO; 6]);
        resolve(&mut c, &start, &mut x, &mut v, &w);
        assert_eq!(c.searches(), 1);
        let wide = c.wide_limit;
        assert!(wide > 0.0 && wide < 9.0 * size, "{wide}");
        let mut moved = place(by * wide);
        resolve(&mut c, &start, &mut moved, &mut v, &w);
        c.searches()
    };
    assert_eq!(slid(0.9), 1, "within the wide limit");
    assert_eq!(slid(1.1), 2, "past the wide limit");
}

#[test]
fn a_mesh_of_uneven_edges_at_rest_searches_once() {
    // An eight-sector disc: its hem edges are 0.39 of its spokes and its longest edges (the
    // quads' diagonals) 2.7 times its shortest, so cubes sized by the shortest edge alone
    // would leave no far limit, and every substep would search again.
    use crate::sim::DiscSpec;
    let disc = ClothModel::disc(&DiscSpec::new(8, 12, 0.5)).unwrap();
    let x = disc.rest_positions.clone();
    let mut c = SelfContacts::new(&disc.triangles, &x, 0.005, 0.0).unwrap();
    let w = vec![1.0; x.len()];
    for _ in 0..10 {
        let (mut moved, mut v) = (x.clone(), vec![Vec3::ZERO; x.len()]);
        resolve(&mut c, &x, &mut moved, &mut v, &w);
    }
    assert!(c.far_limit > 0.0, "{}", c.far_limit);
    assert_eq!(c.searches(), 1);
}

/// [`Vectors`] stored in another order: model particle `p` at `slot[p]`.
struct Reordered<'a> {
    inner: Vectors<'a>,
    slot: Vec<usize>,
}

impl ContactState for Reordered<'_> {
    fn len(&self) -> usize {
        self.inner.len()
    }
    fn inv_mass(&self, i: usize) -> f32 {
        self.inner.inv_mass(i)
    }
    fn slot(&self, p: u32) -> usize {
        self.slot[p as usize]
    }
    fn start(&self, i: usize) -> Vec3 {
        self.inner.start(i)
    }
    fn position(&self, i: usize) -> Vec3 {
        self.inner.position(i)
    }
    fn velocity(&self, i: usize) -> Vec3 {
        self.inner.velocity(i)
    }
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        self.inner.set(i, x, v);
    }
    fn clearances(&self, near: crate::sim::contact::Near, within: f32, out: &mut [f32]) {
        self.inner.clearances(near, within, out);
    }
}

#[test]
fn a_step_that_stores_the_particles_in_another_order_finds_its_pairs_again() {
    // A fixed triangle; free vertex 3 over it, and pinned vertex 4 (of another triangle) at
    // the same place. A step in the model's order finds the pair (3, triangle); the next step
    // stores 3 and 4 swapped and moves both through the triangle. Every particle moved alike
    // as far as the kept candidates can tell, so only noticing the new order makes the step
    // resolve particle 3 rather than the pinned particle now stored where 3 was.
    let over = Vec3::new(0.25, 0.006, 0.25);
    let start = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::Z,
        over,
        over,
        Vec3::new(3.0, 0.0, 3.0),
        Vec3::new(4.0, 0.0, 3.0),
    ];
    let triangles = [0, 1, 2, 3, 5, 6, 4, 6, 5];
    // At rest vertex 4 lies on the triangle, so the pair (4, triangle) is exempt: no pair
    // but (3, triangle) can reach particle 3.
    let mut rest = start.clone();
    rest[4].y = 0.0;
    let mut c = SelfContacts::new(&triangles, &rest, 0.005, 0.0).unwrap();
    let w = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; 7]);
    resolve_within(&mut c, 0.05, &start, &mut x, &mut v, &w);
    assert!(c.vt.contains(&(3, 0)), "{:?}", c.vt);
    // Stored order: 0 1 2 4 3 5 6.
    let order = [0, 1, 2, 4, 3, 5, 6];
    let swapped = |a: &[Vec3]| order.map(|p| a[p]).to_vec();
    let mut end = start.clone();
    end[3].y = -0.003;
    end[4].y = -0.003;
    let (stored_start, mut x) = (swapped(&end), swapped(&end));
    let stored_start: Vec<Vec3> = order
        .iter()
        .zip(&stored_start)
        .map(|(&p, e)| if p == 3 || p == 4 { over } else { *e })
        .collect();
    let mut v = vec![Vec3::ZERO; 7];
    let stored_w = order.map(|p| w[p]);
    c.begin_step(0.05);
    let mut state = Reordered {
        inner: Vectors {
            x: &mut x,
            v: &mut v,
            start: &stored_start,
            inv_mass: &stored_w,
            touches: None,
        },
        slot: vec![0, 1, 2, 4, 3, 5, 6],
    };
    c.resolve((1.0 / 1200.0, true), &mut state);
    // Back above the triangle by the thickness (its edges' pairs may lift it a little more).
    assert!(x[4].y > 0.005 - 1e-6, "particle 3 at {}", x[4]);
}

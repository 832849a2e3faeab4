//! The search: the pairs within the margin, through the hash or the patch pairs, up to the cap.

use super::*;

#[test]
fn the_broad_phase_finds_exactly_the_pairs_within_the_margin() {
    // A 12×12 grid crumpled by a pseudo-random jitter of half its spacing: the broad phase's
    // pairs equal a brute-force search's (every pair sharing no vertex, closer than the
    // margin), each once.
    let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
    let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    let jitter = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0 - 0.5;
    let x: Vec<Vec3> = model
        .rest_positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let fold = Vec3::new(0.0, (p.x * 40.0).sin() * 0.05, 0.0);
            *p + fold + 0.015 * Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2))
        })
        .collect();
    let margin = 0.02;
    c.find_candidates(&x, margin, usize::MAX, NO_CULL);
    let mut vt = c.vt.clone();
    let mut ee = c.ee.clone();
    vt.sort_unstable();
    ee.sort_unstable();
    let [expected_vt, expected_ee] = pairs_within(&c, &x, margin);
    assert!(!expected_vt.is_empty() && !expected_ee.is_empty());
    assert_eq!(vt, expected_vt);
    assert_eq!(ee, expected_ee);
    assert_eq!(c.ee.len(), expected_ee.len(), "each pair once");
}

#[test]
fn a_search_on_positions_that_are_not_finite_pairs_nothing() {
    // A crumpled grid with one particle at infinity and one NaN, searched through the patch
    // pairs and through the hash: no candidates (and no grid of cells spanning infinity).
    let model = ClothModel::grid(&GridSpec::new(12, 12, 0.02)).unwrap();
    let mut x: Vec<Vec3> = (model.rest_positions.iter())
        .map(|p| Vec3::new(p.x, (p.x * 30.0).sin() * 0.02, p.z))
        .collect();
    x[5].x = f32::INFINITY;
    x[40].y = f32::NAN;
    let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    for loose in [false, true] {
        c.loose = loose;
        c.find_candidates(&x, 0.015, usize::MAX, Some((move |_| 1.0, 0.0)));
        assert_eq!(c.candidate_count(), (0, 0), "loose {loose}");
    }
}

#[test]
fn the_patch_pairs_find_what_the_hash_finds() {
    // A crumpled grid and a folded one, searched through the patch pairs and through the hash
    // (the path of a mesh with a loose vertex), with some patches culled and with none: the
    // same candidates, each once.
    let model = ClothModel::grid(&GridSpec::new(24, 24, 0.02)).unwrap();
    let jitter = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0 - 0.5;
    let rest = &model.rest_positions;
    let crumpled: Vec<Vec3> = (rest.iter().enumerate())
        .map(|(i, p)| {
            let fold = Vec3::new(0.0, (p.x * 30.0).sin() * 0.04, 0.0);
            *p + fold + 0.01 * Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2))
        })
        .collect();
    let folded: Vec<Vec3> = rest
        .iter()
        .map(|p| {
            if p.x < 0.0 {
                *p
            } else {
                Vec3::new(-p.x, 0.012, p.z)
            }
        })
        .collect();
    let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0).unwrap();
    assert!(!c.loose);
    let search = |c: &mut SelfContacts, x: &[Vec3], flat: f32, loose: bool| {
        c.loose = loose;
        c.find_candidates(x, 0.015, usize::MAX, Some((move |_| flat, 0.0)));
        let (mut vt, mut ee) = (c.vt.clone(), c.ee.clone());
        vt.sort_unstable();
        ee.sort_unstable();
        (vt, ee)
    };
    for x in [&crumpled, &folded] {
        for flat in [1.0, -1.0] {
            let through_pairs = search(&mut c, x, flat, false);
            let through_hash = search(&mut c, x, flat, true);
            assert!(!through_hash.0.is_empty() && !through_hash.1.is_empty());
            assert_eq!(through_pairs, through_hash, "flat {flat}");
            let (vt, ee) = through_pairs;
            assert!(vt.windows(2).all(|w| w[0] != w[1]) && ee.windows(2).all(|w| w[0] != w[1]));
        }
    }
}

/// Every vertex–triangle and edge–edge pair of `c` at `x` sharing no vertex and closer than
/// `margin`, found by brute force.
fn pairs_within(c: &SelfContacts, x: &[Vec3], margin: f32) -> [Vec<(u32, u32)>; 2] {
    let mut vt = Vec::new();
    for p in 0..x.len() as u32 {
        for (t, tri) in c.tris.iter().enumerate() {
            let [a, b, d] = tri.map(|i| x[i as usize]);
            if !tri.contains(&p) && point_triangle_distance(x[p as usize], a, b, d) < margin {
                vt.push((p, t as u32));
            }
        }
    }
    let mut ee = Vec::new();
    for (e, &[a, b]) in c.edges.iter().enumerate() {
        for (f, &[d, g]) in c.edges.iter().enumerate().skip(e + 1) {
            if [d, g].iter().any(|v| *v == a || *v == b) {
                continue;
            }
            let [pa, pb, pd, pg] = [a, b, d, g].map(|i| x[i as usize]);
            let (s, t) = closest_on_segments(pa, pb, pd, pg);
            if pa.lerp(pb, s).distance(pd.lerp(pg, t)) < margin {
                ee.push((e as u32, f as u32));
            }
        }
    }
    [vt, ee]
}

/// `n` particles scattered in a cube `across` wide about the origin (a cloth crushed into a
/// ball), a different scatter for each `seed`.
fn crushed(n: usize, across: f32, seed: u64) -> Vec<Vec3> {
    (0..n)
        .map(|i| {
            let h = |k: u64| unit_interval(mix64((i as u64 * 3 + k) ^ (seed << 32)));
            across * (Vec3::new(h(0), h(1), h(2)) - 0.5)
        })
        .collect()
}

#[test]
fn a_full_list_ends_its_search_with_the_first_candidates() {
    // A 12×12 grid crushed into a ball a few millimetres across: every pair is within the
    // margin. Capped, each list holds exactly the first candidates of the uncapped search,
    // and a full list of one kind does not cut the other short.
    let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
    let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    let x = crushed(model.rest_positions.len(), 0.004, 0);
    let (margin, flat) = (0.02, 0.5);
    c.find_candidates(&x, margin, usize::MAX, Some((move |_| flat, 0.0)));
    assert!(
        !c.patches.pairs().is_empty(),
        "the ball is searched patch by patch"
    );
    let (vt, ee) = (c.vt.clone(), c.ee.clone());
    let vt_gaps = c.gap[..vt.len()].to_vec();
    let cap = vt.len() / 3;
    assert!(
        cap < ee.len() / 2 && ee.len() > vt.len(),
        "the cap binds both kinds"
    );
    c.find_candidates(&x, margin, cap, Some((move |_| flat, 0.0)));
    assert_eq!(c.vt, vt[..cap]);
    assert_eq!(c.ee, ee[..cap]);
    assert_eq!(c.gap[..cap], vt_gaps[..cap]);
    // A cap only the edge pairs reach leaves the vertex–triangle pairs whole.
    c.find_candidates(&x, margin, vt.len(), Some((move |_| flat, 0.0)));
    assert_eq!((c.vt.len(), c.ee.len()), (vt.len(), vt.len()));
    assert_eq!(c.ee, ee[..vt.len()]);
}

#[test]
fn a_full_list_is_searched_again_only_in_the_next_step() {
    // A 12×12 grid crushed into a ball 2 cm across, its particles jostled every substep by
    // more than the search's reach: both lists fill up at each search. Within a step the
    // candidates are kept; the next step searches again.
    let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
    let n = model.rest_positions.len();
    let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    let w = vec![1.0; n];
    let mut x = crushed(n, 0.02, 0);
    let mut v = vec![Vec3::ZERO; n];
    let mut count = 0;
    for step in 1..=3 {
        c.begin_step(0.001);
        for _ in 0..4 {
            count += 1;
            let start = x.clone();
            x = crushed(n, 0.02, count);
            substep(&mut c, (1.0 / 1200.0, true), &start, (&mut x, &mut v), &w);
            assert!(c.full(), "the crushed ball fills a list");
        }
        assert_eq!(c.searches(), step, "one search in step {step}");
    }
}

#[test]
fn flat_patches_are_not_searched_and_a_fold_is() {
    // A 16×16 grid (3 cm spacing) folded in half over a 1 cm radius: two flat layers 2 cm
    // apart (x is the arc length across the grid, centred on 0). With the normal-cone cull,
    // the flat layers are not searched against themselves, but every pair between the layers
    // within the margin is found.
    let model = ClothModel::grid(&GridSpec::new(16, 16, 0.03)).unwrap();
    let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    let margin = 0.025;
    let flat = 1.0;
    c.find_candidates(
        &model.rest_positions,
        margin,
        usize::MAX,
        Some((move |_| flat, 0.0)),
    );
    assert!(c.patches.pairs().is_empty(), "a flat cloth is not searched");
    assert_eq!(c.candidate_count(), (0, 0));

    let r = 0.01;
    let layer = |p: Vec3| (p.x > std::f32::consts::FRAC_PI_2 * r) as u8;
    let x = folded(&model.rest_positions, 0.0, r);
    c.find_candidates(&x, margin, usize::MAX, Some((move |_| flat, 0.0)));
    let (vt, ee) = (c.vt.clone(), c.ee.clone());
    let [all_vt, all_ee] = pairs_within(&c, &x, margin);
    let rest = &model.rest_positions;
    let across = |v: &[u32]| {
        v.iter()
            .any(|&i| layer(rest[i as usize]) != layer(rest[v[0] as usize]))
    };
    let mut crossing = 0;
    for &(p, t) in &all_vt {
        let [a, b, d] = c.tris[t as usize];
        if across(&[p, a, b, d]) {
            crossing += 1;
            assert!(
                vt.contains(&(p, t)),
                "vertex {p} over triangle {t} across the fold"
            );
        }
    }
    for &(e, f) in &all_ee {
        let ([a, b], [d, g]) = (c.edges[e as usize], c.edges[f as usize]);
        if across(&[a, b, d, g]) {
            crossing += 1;
            assert!(ee.contains(&(e, f)), "edges {e} and {f} across the fold");
        }
    }
    assert!(crossing > 100, "{crossing}");
    assert!(
        vt.len() + ee.len() < all_vt.len() + all_ee.len(),
        "nothing culled"
    );
}

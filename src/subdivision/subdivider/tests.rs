//! [`Subdivider::follow`] against a subdivider built afresh from the same torn mesh: the same
//! surface, faces, UVs and render layout, up to the order of the refined vertices.

use glam::{DVec3, Vec3};

use super::{Followed, Subdivider};
use crate::sim::{ClothModel, ClothSim, Cut, GridPlane, GridSpec, SolverSettings, Tearing};
use crate::subdivision::{BoundaryMode, PolyMesh, VertexRule};

/// Scattered control positions, so that no two refined vertices of the test meshes coincide.
fn scattered(n: usize) -> Vec<DVec3> {
    (0..n)
        .map(|i| {
            let h = crate::hash::splitmix(i as u64);
            let f = |k: u32| ((h >> (16 * k)) & 0xffff) as f64 / 65536.0;
            DVec3::new(f(0), f(1), f(2))
        })
        .collect()
}

/// Checks `followed` against a subdivider built from `mesh`: each refined face corner at the same
/// place with the same UV, corners sharing a refined vertex in one exactly where they do in the
/// other, the render layout drawing the same triangles, and the single-precision evaluation and
/// the composed stencils agreeing with the double-precision one.
fn assert_same_refinement(followed: &mut Subdivider, mesh: &PolyMesh) {
    let fresh = Subdivider::new(mesh, followed.level(), followed.rule(), followed.boundary())
        .expect("the torn mesh refines");
    let control = scattered(mesh.vertex_count());
    let eval = |s: &Subdivider| {
        let mut out = vec![DVec3::ZERO; s.refined_vertex_count()];
        s.apply_f64(&control, &mut out).unwrap();
        out
    };
    let (pf, pn) = (eval(followed), eval(&fresh));
    let (tf, tn) = (followed.topology(), fresh.topology());
    assert_eq!(tf.face_offsets(), tn.face_offsets());
    assert_eq!(tf.corner_uvs(), tn.corner_uvs());
    let mut to_followed = vec![u32::MAX; fresh.refined_vertex_count()];
    let mut to_fresh = vec![u32::MAX; followed.refined_vertex_count()];
    for (c, (&a, &b)) in tf.face_indices().iter().zip(tn.face_indices()).enumerate() {
        let gap = (pf[a as usize] - pn[b as usize]).length();
        assert!(gap < 1e-12, "corner {c}: {gap} apart");
        for (map, from, to) in [(&mut to_followed, b, a), (&mut to_fresh, a, b)] {
            let slot = &mut map[from as usize];
            assert!(
                *slot == u32::MAX || *slot == to,
                "corner {c}: vertices joined differently"
            );
            *slot = to;
        }
    }
    let corner_of_render = |s: &Subdivider, r: u32| {
        let layout = s.topology().render_mesh();
        let refined = match (r as usize).checked_sub(s.refined_vertex_count()) {
            None => r,
            Some(k) => layout.seam_vertices()[k],
        };
        (refined, layout.uvs().map(|uvs| uvs[r as usize]))
    };
    let (rf, rn) = (tf.render_mesh(), tn.render_mesh());
    assert_eq!(rf.triangle_indices().len(), rn.triangle_indices().len());
    for (&a, &b) in rf.triangle_indices().iter().zip(rn.triangle_indices()) {
        let ((va, uva), (vb, uvb)) = (corner_of_render(followed, a), corner_of_render(&fresh, b));
        assert_eq!(uva, uvb, "render vertex {a}'s UV");
        assert!((pf[va as usize] - pn[vb as usize]).length() < 1e-12);
    }
    for (&a, &b) in tf.control_vertex_map().iter().zip(tn.control_vertex_map()) {
        assert!((pf[a as usize] - pn[b as usize]).length() < 1e-12);
    }
    let control_f32: Vec<Vec3> = control.iter().map(|p| p.as_vec3()).collect();
    let mut single = vec![Vec3::ZERO; followed.refined_vertex_count()];
    followed.apply(&control_f32, &mut single).unwrap();
    let composed = followed.composed_stencils().unwrap();
    let mut through_composed = vec![DVec3::ZERO; composed.len()];
    composed.apply_f64(&control, &mut through_composed).unwrap();
    for (v, &p) in pf.iter().enumerate() {
        assert!(
            (single[v].as_dvec3() - p).length() < 1e-5,
            "vertex {v} in f32"
        );
        assert!(
            (through_composed[v] - p).length() < 1e-12,
            "vertex {v} composed"
        );
    }
}

/// A vertical `n`×`n` grid cloth, 2 cm apart, that tears only where it is cut.
fn grid(n: u32) -> ClothSim {
    let spec = GridSpec::new(n, n, 0.02).with_plane(GridPlane::Vertical);
    let settings = SolverSettings {
        tearing: Tearing {
            enabled: true,
            max_stretch: 10.0,
            ..Tearing::default()
        },
        ..SolverSettings::default()
    };
    ClothSim::new(ClothModel::grid(&spec).unwrap(), settings, |p| p).unwrap()
}

/// Cuts `sim` one after another and follows each torn mesh (its corner UVs set by `uvs`) with a
/// subdivider of each level, rule and boundary mode; returns how many follows were local.
fn follow_cuts(mut sim: ClothSim, cuts: &[Cut], uvs: impl Fn(PolyMesh) -> PolyMesh) -> usize {
    let mesh = uvs(sim.model().control_mesh().unwrap());
    let mut subdividers: Vec<Subdivider> = [1, 2, 3]
        .into_iter()
        .flat_map(|level| {
            [
                (VertexRule::Original, BoundaryMode::EdgeAndCorner),
                (VertexRule::Enhanced, BoundaryMode::EdgeOnly),
            ]
            .map(|(rule, boundary)| Subdivider::new(&mesh, level, rule, boundary).unwrap())
        })
        .collect();
    let mut local = 0;
    for cut in cuts {
        assert!(
            !sim.tear(&[*cut]).unwrap().is_empty(),
            "{cut:?} tore nothing"
        );
        let mesh = uvs(sim.model().control_mesh().unwrap());
        for sub in &mut subdividers {
            match sub.follow(&mesh).unwrap() {
                Followed::Locally { .. } => local += 1,
                Followed::Rebuilt => {}
                Followed::Unchanged => panic!("{cut:?} changed nothing"),
            }
            assert_same_refinement(sub, &mesh);
            assert_eq!(sub.follow(&mesh).unwrap(), Followed::Unchanged);
        }
    }
    local
}

#[test]
fn a_torn_grid_followed_refines_as_one_refined_afresh() {
    const N: u32 = 40;
    let sim = grid(N);
    let at = |i: u32, j: u32| sim.positions()[(i * N + j) as usize];
    let across = at(0, 1) - at(0, 0);
    let slit = |start: Vec3, end: Vec3| Cut::Segment {
        start,
        end,
        radius: 0.006,
    };
    let cuts = [
        // A slit from the left edge to the middle, then one crossing its end, a hole, and a slit
        // from the right edge along the same row.
        slit(at(16, 0) - across, at(16, 20) + 0.3 * across),
        slit(at(10, 20), at(22, 20)),
        Cut::Ray {
            origin: at(30, 10) - Vec3::Z,
            direction: Vec3::Z,
            radius: 0.05,
        },
        slit(at(16, N - 1) + across, at(16, 26)),
    ];
    let local = follow_cuts(sim.clone(), &cuts, |mesh| mesh);
    // The level-1 subdivider's patch outgrows a quarter of its vertices at the last cut.
    assert!(local >= 4 * 6 - 2, "only {local} of 24 follows were local");

    // The same with a UV seam down the middle column of faces (their UVs one to the right), which
    // the render layout draws with seam copies of the vertices there.
    let seamed = |mesh: PolyMesh| {
        let mut uvs = mesh.uvs().unwrap().to_vec();
        for (f, face) in uvs.chunks_exact_mut(4).enumerate() {
            if f % (N as usize - 1) == 20 {
                face.iter_mut().for_each(|uv| uv.x += 1.0);
            }
        }
        mesh.with_corner_uvs(uvs).unwrap()
    };
    let local = follow_cuts(sim, &cuts, seamed);
    assert!(local >= 4 * 6 - 2, "only {local} of 24 follows were local");
}

/// Random cuts, one after another, on a 32×32 grid: blades of random lengths and directions
/// and holes of random sizes, each followed at level 2 and compared with a refinement built
/// afresh, until the cloth is in tatters.
#[test]
fn random_cuts_followed_refine_as_refined_afresh() {
    const N: u32 = 32;
    for seed in 0..4u64 {
        let mut sim = grid(N);
        let mut sub = Subdivider::new(
            &sim.model().control_mesh().unwrap(),
            2,
            VertexRule::Original,
            BoundaryMode::EdgeAndCorner,
        )
        .unwrap();
        let mut draw = {
            let mut k = 0u64;
            move || {
                k += 1;
                let h = crate::hash::splitmix(seed << 32 | k);
                (h >> 40) as f32 / (1u64 << 24) as f32
            }
        };
        let mut local = 0;
        for cut in 0..12 {
            let p = |draw: &mut dyn FnMut() -> f32| {
                let at = (draw() * (N * N) as f32) as usize % (N * N) as usize;
                sim.positions()[at]
            };
            let cut = if cut % 3 == 2 {
                Cut::Ray {
                    origin: p(&mut draw) - Vec3::Z,
                    direction: Vec3::Z,
                    radius: 0.01 + 0.05 * draw(),
                }
            } else {
                Cut::Segment {
                    start: p(&mut draw),
                    end: p(&mut draw),
                    radius: 0.006,
                }
            };
            // A blade drawn from a particle to itself is no cut.
            if cut.validate().is_err() || sim.tear(&[cut]).unwrap().is_empty() {
                continue;
            }
            let mesh = sim.model().control_mesh().unwrap();
            if let Followed::Locally { .. } = sub.follow(&mesh).unwrap() {
                local += 1;
            }
            assert_same_refinement(&mut sub, &mesh);
        }
        assert!(local > 0, "seed {seed}: no follow was local");
    }
}

#[test]
fn a_torn_sphere_followed_refines_as_one_refined_afresh() {
    let model = ClothModel::icosphere(0.3, 3).unwrap();
    let sim = ClothSim::new(model, SolverSettings::default(), |p| p).unwrap();
    let cuts = [Cut::Segment {
        start: Vec3::new(-0.05, 0.4, 0.0),
        end: Vec3::new(0.05, 0.25, 0.0),
        radius: 0.05,
    }];
    let local = follow_cuts(sim, &cuts, |mesh| mesh);
    assert_eq!(local, 6, "every follow was local");
}

#[test]
fn other_changes_refine_the_whole_mesh() {
    let quads = |n: u32| -> Vec<u32> {
        (0..n - 1)
            .flat_map(|i| (0..n - 1).map(move |j| (i, j)))
            .flat_map(|(i, j)| {
                let v = i * n + j;
                [v, v + n, v + n + 1, v + 1]
            })
            .collect()
    };
    let positions = |n: u32| scattered((n * n) as usize);
    let mesh = PolyMesh::from_quads(positions(6), &quads(6)).unwrap();
    let mut sub =
        Subdivider::new(&mesh, 2, VertexRule::Original, BoundaryMode::EdgeAndCorner).unwrap();
    assert_eq!(sub.follow(&mesh).unwrap(), Followed::Unchanged);
    // Another grid: another face layout.
    let bigger = PolyMesh::from_quads(positions(7), &quads(7)).unwrap();
    assert_eq!(sub.follow(&bigger).unwrap(), Followed::Rebuilt);
    assert_same_refinement(&mut sub, &bigger);
    // Fewer vertices.
    let mut faces = quads(7);
    faces.truncate(faces.len() - 4);
    let fewer = PolyMesh::from_quads(positions(7).into_iter().take(48), &faces);
    let fewer = fewer.unwrap();
    let mut sub = Subdivider::new(
        &bigger,
        2,
        VertexRule::Original,
        BoundaryMode::EdgeAndCorner,
    )
    .unwrap();
    assert_eq!(sub.follow(&fewer).unwrap(), Followed::Rebuilt);
    assert_same_refinement(&mut sub, &fewer);
}

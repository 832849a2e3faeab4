use super::*;
use crate::subdivision::{BoundaryMode, VertexRule};

#[test]
fn grid_has_the_canonical_spring_counts() {
    let (nx, ny) = (5u32, 4u32);
    let m = ClothModel::grid(&GridSpec::new(nx, ny, 0.1)).unwrap();
    let [s, sh, b] = m.springs.count_by_kind();
    assert_eq!(s as u32, (nx - 1) * ny + nx * (ny - 1));
    assert_eq!(sh as u32, 2 * (nx - 1) * (ny - 1));
    assert_eq!(b as u32, (nx - 2) * ny + nx * (ny - 2));
    assert_eq!(m.triangles.len() as u32, (nx - 1) * (ny - 1) * 6);
    // particle (i, j) has index j * nx + i, spacing h along i and j.
    let p = |i: u32, j: u32| m.rest_positions[(j * nx + i) as usize];
    assert!((p(1, 0) - p(0, 0) - Vec3::new(0.1, 0.0, 0.0)).length() < 1e-6);
    assert!((p(0, 1) - p(0, 0) - Vec3::new(0.0, 0.0, 0.1)).length() < 1e-6);
}

#[test]
fn a_quad_grid_mesh_gets_exactly_the_canonical_grid_springs() {
    let g = ClothModel::grid(&GridSpec::new(6, 5, 0.1)).unwrap();
    assert_eq!(g.face_size, 4);
    let m = ClothModel::from_mesh(&g.rest_positions, None, &g.faces, 4).unwrap();
    let set = |s: &Springs| {
        let mut v: Vec<_> = (0..s.len())
            .map(|k| (s.a[k].min(s.b[k]), s.a[k].max(s.b[k]), s.kind[k] as u8))
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(set(&m.springs), set(&g.springs));
}

#[test]
fn a_subdivided_grid_is_the_refined_quad_grid_with_its_mass() {
    let (nx, ny) = (5u32, 4u32);
    let n = (nx * ny) as usize;
    let masses: Vec<f32> = (1..=n).map(|i| i as f32 * 0.01).collect();
    let m = ClothModel::grid(&GridSpec::new(nx, ny, 0.1))
        .unwrap()
        .with_particle_masses(masses.clone())
        .unwrap();
    let r = m
        .subdivided(1, VertexRule::Original, BoundaryMode::EdgeAndCorner)
        .unwrap();
    let (rx, ry) = (2 * nx - 1, 2 * ny - 1);
    assert_eq!(r.model.particle_count(), (rx * ry) as usize);
    assert_eq!(r.model.face_size, 4);
    assert_eq!(
        r.model.faces.len(),
        4 * 4 * (nx - 1) as usize * (ny - 1) as usize
    );
    let [structural, shear, _] = r.model.springs.count_by_kind();
    assert_eq!(structural as u32, (rx - 1) * ry + rx * (ry - 1));
    assert_eq!(shear as u32, 2 * (rx - 1) * (ry - 1));
    assert!((r.mass_scale - n as f32 / (rx * ry) as f32).abs() < 1e-7);
    // A flat uniform grid with fixed corners reproduces itself: every particle keeps its
    // rest position, now as the vertex point named by the map.
    assert_eq!(r.particle_map.len(), n);
    for (i, &j) in r.particle_map.iter().enumerate() {
        let d = m.rest_positions[i].distance(r.model.rest_positions[j as usize]);
        assert!(d < 1e-6, "particle {i} moved by {d}");
    }
    let refined = r
        .model
        .particle_masses
        .as_ref()
        .expect("masses carried over");
    let (before, after) = (masses.iter().sum::<f32>(), refined.iter().sum::<f32>());
    assert!((after / before - 1.0).abs() < 1e-5, "{before} vs {after}");
    assert!(refined.iter().all(|&m| m > 0.0));
    r.model.validate().unwrap();
}

#[test]
fn colours_never_share_a_particle() {
    let m = ClothModel::grid(&GridSpec::new(9, 7, 0.1)).unwrap();
    let s = &m.springs;
    for c in 0..s.color_count() {
        let mut seen = vec![false; m.particle_count()];
        for k in s.color_offsets[c] as usize..s.color_offsets[c + 1] as usize {
            for p in [s.a[k], s.b[k]] {
                assert!(!seen[p as usize], "colour {c} uses particle {p} twice");
                seen[p as usize] = true;
            }
        }
    }
    assert_eq!(*s.color_offsets.last().unwrap() as usize, s.len());
    assert!(s.color_count() <= 23, "{} colours", s.color_count());
}

#[test]
fn grid_normals_face_up() {
    let m = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
    let mut n = vec![Vec3::ZERO; m.particle_count()];
    compute_normals(&m.rest_positions, &m.triangles, &mut n);
    assert!(n.iter().all(|n| (*n - Vec3::Y).length() < 1e-6));
    let v = ClothModel::grid(&GridSpec::new(4, 4, 0.1).with_plane(GridPlane::Vertical)).unwrap();
    compute_normals(&v.rest_positions, &v.triangles, &mut n);
    assert!(n.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
}

#[test]
fn bad_grids_name_the_field() {
    let e = ClothModel::grid(&GridSpec::new(1, 4, 0.1)).unwrap_err();
    assert!(
        e.to_string().contains("nx") && e.to_string().contains('1'),
        "{e}"
    );
    let e = ClothModel::grid(&GridSpec::new(4, 0, 0.1)).unwrap_err();
    assert!(e.to_string().contains("ny"), "{e}");
    for h in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        let e = ClothModel::grid(&GridSpec::new(4, 4, h)).unwrap_err();
        assert!(e.to_string().contains("spacing"), "{e}");
    }
}

#[test]
fn mesh_cloth_from_two_triangles() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)];
    let m = ClothModel::from_mesh(&p, None, &[0, 2, 1, 1, 2, 3], 3).unwrap();
    // 5 edges, one interior edge (1-2) whose opposite vertices 0 and 3 get a bend spring.
    assert_eq!(m.springs.count_by_kind(), [5, 0, 1]);
    assert_eq!(m.triangles, vec![0, 2, 1, 1, 2, 3]);
}

#[test]
fn bad_meshes_are_errors() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::Z];
    assert!(matches!(
        ClothModel::from_mesh(&p, None, &[], 3),
        Err(ClothError::InvalidMesh { .. })
    ));
    assert!(matches!(
        ClothModel::from_mesh(&[], None, &[0, 1, 2], 3),
        Err(ClothError::InvalidMesh { .. })
    ));
    assert_eq!(
        ClothModel::from_mesh(&p, None, &[0, 1, 7], 3).unwrap_err(),
        ClothError::MeshIndexOutOfRange {
            index: 7,
            position: 2,
            count: 3
        }
    );
    assert!(ClothModel::from_mesh(&p, None, &[0, 1], 3).is_err());
}

#[test]
fn built_models_are_valid_and_broken_ones_are_errors() {
    let m = ClothModel::grid(&GridSpec::new(5, 4, 0.1)).unwrap();
    assert_eq!(m.validate(), Ok(()));
    let mut t = m.clone();
    t.triangles[4] = 99;
    assert!(matches!(
        t.validate(),
        Err(ClothError::MeshIndexOutOfRange { index: 99, .. })
    ));
    let mut u = m.clone();
    u.uvs.pop();
    assert!(u.validate().unwrap_err().to_string().contains("texture"));
    let mut s = m.clone();
    s.springs.rest[3] = 0.0;
    assert!(s.validate().unwrap_err().to_string().contains("spring 3"));
    let mut c = m.clone();
    let last = c.springs.color_offsets.len() - 1;
    c.springs.color_offsets[last] += 1;
    assert!(c.validate().unwrap_err().to_string().contains("partition"));
    // Two springs of colour 0 that share particle 0.
    let mut shared = m.clone();
    shared.springs.a[1] = shared.springs.a[0];
    let first_colour_len = shared.springs.color_offsets[1];
    assert!(first_colour_len >= 2);
    assert!(shared.validate().unwrap_err().to_string().contains("twice"));
    let mut f = m;
    f.face_size = 5;
    assert!(f.validate().unwrap_err().to_string().contains("3 or 4"));
}

#[test]
fn particle_masses_are_checked() {
    let m = ClothModel::grid(&GridSpec::new(2, 2, 0.1)).unwrap();
    assert_eq!(m.mass_of(1, 0.25), 0.25);
    assert!(m.clone().with_particle_masses(vec![1.0; 3]).is_err());
    let e = m
        .clone()
        .with_particle_masses(vec![1.0, 1.0, -2.0, 1.0])
        .unwrap_err();
    assert!(e.to_string().contains("particle_masses"), "{e}");
    let m = m.with_particle_masses(vec![1.0, 2.0, 3.0, 4.0]).unwrap();
    assert_eq!(m.mass_of(2, 0.25), 3.0);
}

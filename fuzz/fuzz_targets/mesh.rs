//! `ClothModel::from_mesh` on a triangle or quad mesh decoded from the fuzz bytes (with coincident
//! vertices, repeated and out-of-range indices, folded and non-manifold faces, non-finite values).
//! An accepted mesh must give a model whose springs all have a finite, positive rest length and
//! whose particles can be simulated; its control mesh is refined when subdivision accepts it.
#![no_main]

use bevy_cloth::sim::{ClothModel, ClothSim, SolverSettings};
use glam::{Vec2, Vec3};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fn coordinate(u: &mut Unstructured) -> Result<f32> {
    Ok(if u.ratio(1, 16)? {
        f32::from_bits(u.arbitrary()?)
    } else {
        u.int_in_range(-8i8..=8)? as f32 / 4.0
    })
}

fn decode(u: &mut Unstructured) -> Result<(Vec<Vec3>, Option<Vec<Vec2>>, Vec<u32>, usize)> {
    let vertices = u.int_in_range(0..=40usize)?;
    let positions = (0..vertices)
        .map(|_| Ok(Vec3::new(coordinate(u)?, coordinate(u)?, coordinate(u)?)))
        .collect::<Result<Vec<_>>>()?;
    let face_size = match u.int_in_range(0..=15u8)? {
        0 => u.int_in_range(0..=6usize)?,
        1..=7 => 3,
        _ => 4,
    };
    let len = u.int_in_range(0..=160usize)?;
    let indices = (0..len)
        .map(|_| {
            Ok(if u.ratio(1, 32)? {
                u.arbitrary()?
            } else {
                u.int_in_range(0..=vertices as u32)?
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let uvs = if u.arbitrary()? {
        let n = vertices + usize::from(u.ratio(1, 16)?);
        Some(
            (0..n)
                .map(|_| Ok(Vec2::new(coordinate(u)?, coordinate(u)?)))
                .collect::<Result<Vec<_>>>()?,
        )
    } else {
        None
    };
    Ok((positions, uvs, indices, face_size))
}

fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    let Ok((positions, uvs, indices, face_size)) = decode(&mut u) else {
        return;
    };
    let Ok(model) = ClothModel::from_mesh(&positions, uvs.as_deref(), &indices, face_size) else {
        return;
    };
    let s = &model.springs;
    for k in 0..s.len() {
        assert!(
            s.rest[k].is_finite() && s.rest[k] > 0.0,
            "spring {k} ({}, {}) has rest length {}",
            s.a[k],
            s.b[k],
            s.rest[k]
        );
    }
    if let Ok(control) = model.control_mesh() {
        common::refine_all(&control, 1);
    }
    let mut sim = ClothSim::new(model, SolverSettings::default(), |p| p)
        .expect("an accepted mesh builds a simulation");
    let _ = sim.step(1.0 / 60.0);
});

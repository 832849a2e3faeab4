//! A polygon mesh decoded from the fuzz bytes (vertex count, positions, face sizes and indices,
//! optional UVs), built through each public `PolyMesh` constructor and then refined to levels 0–2
//! with every rule and boundary mode. Errors are fine; panics are not.
#![no_main]

use bevy_cloth::subdivision::{PolyMesh, SubdivisionError};
use glam::{DVec3, Vec2};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

/// A coordinate: mostly small integers/8 (so that vertices coincide and faces fold), sometimes any
/// f64 bit pattern (NaN, infinities, huge values).
fn coordinate(u: &mut Unstructured) -> Result<f64> {
    Ok(if u.ratio(1, 16)? {
        f64::from_bits(u.arbitrary()?)
    } else {
        u.int_in_range(-16i8..=16)? as f64 / 8.0
    })
}

/// A vertex index: mostly in range (a few past the end), sometimes any u32.
fn index(u: &mut Unstructured, vertices: usize) -> Result<u32> {
    Ok(if u.ratio(1, 32)? {
        u.arbitrary()?
    } else {
        u.int_in_range(0..=vertices as u32 + 1)?
    })
}

fn build(u: &mut Unstructured) -> Result<std::result::Result<PolyMesh, SubdivisionError>> {
    let vertices = u.int_in_range(0..=48usize)?;
    let positions = (0..vertices)
        .map(|_| Ok(DVec3::new(coordinate(u)?, coordinate(u)?, coordinate(u)?)))
        .collect::<Result<Vec<_>>>()?;
    let faces = u.int_in_range(0..=48usize)?;
    let constructor = u.int_in_range(0..=3u8)?;
    let mesh = match constructor {
        // Uniform triangles or quads from a flat buffer (its length need not fit).
        0 | 1 => {
            let arity = 3 + constructor as usize;
            let len = faces * arity + if u.ratio(1, 16)? { 1 } else { 0 };
            let flat = (0..len)
                .map(|_| index(u, vertices))
                .collect::<Result<Vec<_>>>()?;
            if constructor == 0 {
                PolyMesh::from_triangles(positions, &flat)
            } else {
                PolyMesh::from_quads(positions, &flat)
            }
        }
        // Polygons of 0..=8 corners.
        2 => {
            let polys = (0..faces)
                .map(|_| {
                    let k = u.int_in_range(0..=8usize)?;
                    (0..k)
                        .map(|_| index(u, vertices))
                        .collect::<Result<Vec<_>>>()
                })
                .collect::<Result<Vec<_>>>()?;
            PolyMesh::from_polygons(positions, &polys)
        }
        // Raw CSR offsets (possibly malformed) and optional per-corner UVs.
        _ => {
            let corners = u.int_in_range(0..=192usize)?;
            let indices = (0..corners)
                .map(|_| index(u, vertices))
                .collect::<Result<Vec<_>>>()?;
            let mut offsets = vec![0u32];
            let mut at = 0u32;
            for _ in 0..faces {
                at = if u.ratio(1, 32)? {
                    u.arbitrary()?
                } else {
                    at.saturating_add(u.int_in_range(0..=6u32)?)
                };
                offsets.push(at);
            }
            if u.arbitrary()? {
                offsets.push(corners as u32);
            }
            let uvs = if u.arbitrary()? {
                let n = corners + usize::from(u.ratio(1, 16)?);
                Some(
                    (0..n)
                        .map(|_| {
                            Ok(if u.ratio(1, 32)? {
                                Vec2::new(f32::from_bits(u.arbitrary()?), 0.5)
                            } else {
                                Vec2::new(
                                    u.int_in_range(0..=8u8)? as f32,
                                    u.int_in_range(0..=8u8)? as f32,
                                ) / 8.0
                            })
                        })
                        .collect::<Result<Vec<_>>>()?,
                )
            } else {
                None
            };
            PolyMesh::new(positions, offsets, indices, uvs)
        }
    };
    // Per-vertex UVs on top of a valid mesh, sometimes of the wrong count.
    Ok(match mesh {
        Ok(m) if u.ratio(1, 4)? => {
            let n = m.vertex_count() + usize::from(u.ratio(1, 16)?);
            let uvs: Vec<Vec2> = (0..n).map(|i| Vec2::new(i as f32, 0.0)).collect();
            m.with_vertex_uvs(&uvs)
        }
        other => other,
    })
}

fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    let Ok(Ok(mesh)) = build(&mut u) else {
        return;
    };
    for level in 0..=2 {
        common::refine_all(&mesh, level);
    }
});

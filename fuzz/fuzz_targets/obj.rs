//! `parse_obj` on arbitrary bytes (decoded as lossy UTF-8, as a caller reading a file would); a mesh
//! that parses must round-trip through `write_obj` and refine to levels 1 and 2 with every rule
//! without panicking.
#![no_main]

use bevy_cloth::subdivision::{parse_obj, write_obj};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(mesh) = parse_obj(&text) else {
        return;
    };
    let back = parse_obj(&write_obj(&mesh, "fuzz")).expect("write_obj output parses");
    assert_eq!(back.vertex_count(), mesh.vertex_count());
    assert_eq!(back.face_indices(), mesh.face_indices());
    assert_eq!(back.positions(), mesh.positions());
    match (back.uvs(), mesh.uvs()) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(b) {
                assert!((*x - *y).abs().max_element() <= 1e-6 * y.abs().max_element().max(1.0));
            }
        }
        _ => panic!("UVs lost in the round trip"),
    }
    for level in 1..=2 {
        common::refine_all(&mesh, level);
    }
});

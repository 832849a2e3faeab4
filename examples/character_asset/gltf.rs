//! The character of the `character` example, as data and as a glTF 2.0 document: a skeleton of
//! four joints (hips, spine, two legs), rigid boxes for the body on those joints, two skinned
//! cloth meshes (a cape behind the back, a skirt around the hips) whose vertex colours' red
//! channel holds each vertex's target weight (0 where the cloth is held, 1 where it swings
//! most), and a walk cycle of 1.2 s. Everything is written into one `.gltf` file with its
//! binary buffer embedded as base64, so the asset is a single text file.
//!
//! Shared by the generator (`cargo run --example character_asset`) and the test that loads the
//! asset (`tests/character_asset.rs`).

use std::f32::consts::TAU;

use serde_json::{Value, json};

/// The skeleton's joints, in skin order: name, parent (index into this list), bind translation
/// relative to the parent (the root's relative to the character).
pub const JOINTS: [(&str, Option<usize>, [f32; 3]); 4] = [
    ("hips", None, [0.0, 1.0, 0.0]),
    ("spine", Some(0), [0.0, 0.25, 0.0]),
    ("leg.L", Some(0), [0.1, -0.05, 0.0]),
    ("leg.R", Some(0), [-0.1, -0.05, 0.0]),
];

/// Length of the walk cycle, s.
pub const CYCLE: f32 = 1.2;
/// Keyframes per cycle (plus one closing the loop).
const KEYS: usize = 24;

/// A skinned cloth mesh as the generator writes it.
#[derive(Debug, Clone, PartialEq)]
pub struct SkinnedPart {
    /// The glTF node and mesh name.
    pub name: &'static str,
    pub positions: Vec<[f32; 3]>,
    /// Smooth normals. (Without normals, Bevy's glTF loader computes flat ones and so gives
    /// every triangle its own vertices: a cloth would fall apart into loose triangles.)
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    /// Joint indices into [`JOINTS`], four per vertex.
    pub joints: Vec<[u16; 4]>,
    /// Joint weights, four per vertex, summing to 1.
    pub weights: Vec<[f32; 4]>,
    /// `COLOR_0`: red is the target weight.
    pub colors: Vec<[f32; 4]>,
    pub indices: Vec<u32>,
}

/// A rigid box on a joint: the joint it rides on, its centre in the joint's frame, half extents.
pub struct BodyPart {
    pub name: &'static str,
    pub joint: usize,
    pub centre: [f32; 3],
    pub half: [f32; 3],
}

/// The body's boxes.
pub fn body() -> Vec<BodyPart> {
    vec![
        BodyPart {
            name: "pelvis",
            joint: 0,
            centre: [0.0, 0.05, 0.0],
            half: [0.15, 0.1, 0.1],
        },
        BodyPart {
            name: "torso",
            joint: 1,
            centre: [0.0, 0.2, 0.0],
            half: [0.18, 0.25, 0.1],
        },
        BodyPart {
            name: "head",
            joint: 1,
            centre: [0.0, 0.6, 0.0],
            half: [0.09, 0.11, 0.1],
        },
        BodyPart {
            name: "thigh.L",
            joint: 2,
            centre: [0.0, -0.45, 0.0],
            half: [0.06, 0.45, 0.06],
        },
        BodyPart {
            name: "thigh.R",
            joint: 3,
            centre: [0.0, -0.45, 0.0],
            half: [0.06, 0.45, 0.06],
        },
    ]
}

/// Each joint's position in the bind pose, in the character's frame.
pub fn bind_positions() -> [[f32; 3]; 4] {
    let mut out = [[0.0; 3]; 4];
    for (j, (_, parent, t)) in JOINTS.iter().enumerate() {
        let base = parent.map_or([0.0; 3], |p| out[p]);
        out[j] = [base[0] + t[0], base[1] + t[1], base[2] + t[2]];
    }
    out
}

/// The inverse bind matrices (column-major): each joint's bind pose is a pure translation.
pub fn inverse_bind_matrices() -> Vec<[f32; 16]> {
    bind_positions()
        .iter()
        .map(|p| {
            [
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -p[0], -p[1], -p[2],
                1.0,
            ]
        })
        .collect()
}

/// Triangles of a grid of `nx` × `ny` vertices, row by row (`wrap`: the last column joins the
/// first, for a tube).
fn grid_indices(nx: usize, ny: usize, wrap: bool) -> Vec<u32> {
    let columns = if wrap { nx } else { nx - 1 };
    let mut indices = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..columns {
            let a = (j * nx + i) as u32;
            let b = (j * nx + (i + 1) % nx) as u32;
            let (c, d) = (a + nx as u32, b + nx as u32);
            indices.extend([a, c, b, b, c, d]);
        }
    }
    indices
}

/// Area-weighted vertex normals of a triangle mesh.
fn smooth_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[f32; 3]> {
    let mut sum = vec![[0.0f32; 3]; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        let (u, v) = (
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        for &i in t {
            for k in 0..3 {
                sum[i as usize][k] += n[k];
            }
        }
    }
    sum.iter()
        .map(|n| {
            let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-12);
            [n[0] / length, n[1] / length, n[2] / length]
        })
        .collect()
}

impl SkinnedPart {
    /// An empty part named `name` with triangles `indices`.
    fn new(name: &'static str, indices: Vec<u32>) -> Self {
        Self {
            name,
            positions: Vec::new(),
            normals: Vec::new(),
            uvs: Vec::new(),
            joints: Vec::new(),
            weights: Vec::new(),
            colors: Vec::new(),
            indices,
        }
    }

    /// Adds a vertex at `position` with texture coordinates `uv`, skinned to joints `joints`
    /// with `weights`, and target weight `target` (in `COLOR_0`'s red).
    fn push(
        &mut self,
        position: [f32; 3],
        uv: [f32; 2],
        (joints, weights): ([u16; 4], [f32; 4]),
        target: f32,
    ) {
        self.positions.push(position);
        self.uvs.push(uv);
        self.joints.push(joints);
        self.weights.push(weights);
        self.colors.push([target, 0.0, 0.0, 1.0]);
    }

    /// Computes the normals once every vertex is in.
    fn finish(mut self) -> Self {
        self.normals = smooth_normals(&self.positions, &self.indices);
        self
    }
}

/// The cape: 16 × 22 vertices behind the back, from the shoulders (y = 1.68) to below the knees
/// (y = 0.78), curved around the back; skinned to the spine at the collar and the hips at the
/// hem; target weight 0 along the collar, growing to 1 at the hem.
pub fn cape() -> SkinnedPart {
    let (nx, ny) = (16, 22);
    // Wound so that its normals face away from the back (the backstop lies behind them).
    let indices = grid_indices(nx, ny, false)
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[2], t[1]])
        .collect();
    let mut part = SkinnedPart::new("cape", indices);
    for j in 0..ny {
        let s = j as f32 / (ny - 1) as f32;
        for i in 0..nx {
            let u = i as f32 / (nx - 1) as f32;
            let x = -0.2 + 0.4 * u;
            let position = [x, 1.68 - 0.9 * s, -0.14 - 0.5 * x * x - 0.02 * s];
            part.push(position, [u, s], ([1, 0, 0, 0], [1.0 - s, s, 0.0, 0.0]), s);
        }
    }
    part.finish()
}

/// The skirt: a tube of radius 0.2 m, 28 vertices around and 9 down, from the waist (y = 1.0)
/// to y = 0.55, skinned to the hips; target weight 0 at the waist, 1 at the hem.
pub fn skirt() -> SkinnedPart {
    let (around, rows) = (28, 9);
    let mut part = SkinnedPart::new("skirt", grid_indices(around, rows, true));
    for j in 0..rows {
        let s = j as f32 / (rows - 1) as f32;
        for i in 0..around {
            let a = TAU * i as f32 / around as f32;
            let r = 0.2 + 0.04 * s;
            let position = [r * a.sin(), 1.0 - 0.45 * s, r * a.cos()];
            let uv = [2.0 * i as f32 / around as f32, 0.5 * s];
            part.push(position, uv, ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]), s);
        }
    }
    part.finish()
}

/// A joint's local rotation (x, y, z, w) at time `t` of the walk cycle: the legs swing ±35°
/// about X in opposite phase, the spine twists ±12° about Y against the legs.
pub fn walk_rotation(joint: usize, t: f32) -> [f32; 4] {
    let phase = TAU * t / CYCLE;
    let (axis, angle) = match joint {
        1 => (1, -12f32.to_radians() * phase.sin()),
        2 => (0, 35f32.to_radians() * phase.sin()),
        3 => (0, -35f32.to_radians() * phase.sin()),
        _ => (1, 0.0),
    };
    let (s, c) = (0.5 * angle).sin_cos();
    let mut q = [0.0, 0.0, 0.0, c];
    q[axis] = s;
    q
}

/// The hips' height at time `t` of the walk cycle: a bob of 2 cm twice per cycle.
pub fn walk_height(t: f32) -> f32 {
    JOINTS[0].2[1] + 0.02 * (2.0 * TAU * t / CYCLE).cos()
}

/// Appends little-endian data to the buffer, 4-byte aligned; returns (offset, length).
fn push(buffer: &mut Vec<u8>, bytes: &[u8]) -> (usize, usize) {
    while !buffer.len().is_multiple_of(4) {
        buffer.push(0);
    }
    let offset = buffer.len();
    buffer.extend_from_slice(bytes);
    (offset, bytes.len())
}

fn f32s(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// The document's buffer views and accessors as they are added.
struct Builder {
    buffer: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Adds an accessor of `count` elements of `kind` ("VEC3", …) and component type
    /// `component` (5126 float, 5123 unsigned short, 5125 unsigned int) over `bytes`; `bounds`
    /// gives min and max (required for positions).
    fn accessor(
        &mut self,
        bytes: &[u8],
        (count, kind, component): (usize, &str, u32),
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> usize {
        let (offset, length) = push(&mut self.buffer, bytes);
        self.views.push(json!({
            "buffer": 0,
            "byteOffset": offset,
            "byteLength": length,
        }));
        let mut accessor = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component,
            "count": count,
            "type": kind,
        });
        if let Some((min, max)) = bounds {
            accessor["min"] = json!(min);
            accessor["max"] = json!(max);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn positions(&mut self, positions: &[[f32; 3]]) -> usize {
        let mut min = vec![f32::MAX; 3];
        let mut max = vec![f32::MIN; 3];
        for p in positions {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        self.accessor(
            &f32s(positions.iter().flatten().copied()),
            (positions.len(), "VEC3", 5126),
            Some((min, max)),
        )
    }

    fn floats<const N: usize>(&mut self, values: &[[f32; N]], kind: &str) -> usize {
        self.accessor(
            &f32s(values.iter().flatten().copied()),
            (values.len(), kind, 5126),
            None,
        )
    }

    fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.accessor(&bytes, (indices.len(), "SCALAR", 5125), None)
    }
}

/// A box's 24 vertices (4 per face, with the face's normal) and 36 indices.
fn box_mesh(centre: [f32; 3], half: [f32; 3]) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>) {
    let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = centre;
                p[axis] += sign * half[axis];
                p[u] += a * half[u];
                p[v] += b * half[v];
                positions.push(p);
                let mut n = [0.0; 3];
                n[axis] = sign;
                normals.push(n);
            }
            // Counter-clockwise seen from outside.
            if sign > 0.0 {
                indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
            } else {
                indices.extend([base, base + 2, base + 1, base, base + 3, base + 2]);
            }
        }
    }
    (positions, normals, indices)
}

/// Standard base64 (with padding) of `bytes`.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The whole character as a glTF 2.0 document (pretty-printed JSON).
pub fn document() -> String {
    let mut b = Builder {
        buffer: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let mut nodes: Vec<Value> = Vec::new();
    let mut meshes: Vec<Value> = Vec::new();
    // Node 0: the character (the root the game moves); joints follow at 1 + j.
    nodes.push(json!({ "name": "character", "children": [1] }));
    for (name, _, t) in JOINTS {
        nodes.push(json!({ "name": name, "translation": t, "children": [] }));
    }
    for (j, (_, parent, _)) in JOINTS.iter().enumerate() {
        if let Some(p) = parent {
            nodes[1 + p]["children"]
                .as_array_mut()
                .expect("children")
                .push(json!(1 + j));
        }
    }
    // Body boxes: a mesh each, on a node under its joint.
    for part in body() {
        let (positions, normals, indices) = box_mesh(part.centre, part.half);
        let (p, n, i) = (
            b.positions(&positions),
            b.floats(&normals, "VEC3"),
            b.indices(&indices),
        );
        meshes.push(json!({
            "name": part.name,
            "primitives": [{
                "attributes": { "POSITION": p, "NORMAL": n },
                "indices": i,
                "material": 0,
            }],
        }));
        nodes.push(json!({ "name": part.name, "mesh": meshes.len() - 1 }));
        let node = nodes.len() - 1;
        nodes[1 + part.joint]["children"]
            .as_array_mut()
            .expect("children")
            .push(json!(node));
    }
    // The cloth parts: skinned meshes under the character.
    for part in [cape(), skirt()] {
        let attributes = json!({
            "POSITION": b.positions(&part.positions),
            "NORMAL": b.floats(&part.normals, "VEC3"),
            "TEXCOORD_0": b.floats(&part.uvs, "VEC2"),
            "JOINTS_0": b.accessor(
                &part.joints.iter().flatten().flat_map(|j| j.to_le_bytes()).collect::<Vec<_>>(),
                (part.joints.len(), "VEC4", 5123),
                None,
            ),
            "WEIGHTS_0": b.floats(&part.weights, "VEC4"),
            "COLOR_0": b.floats(&part.colors, "VEC4"),
        });
        let indices = b.indices(&part.indices);
        meshes.push(json!({
            "name": part.name,
            "primitives": [{ "attributes": attributes, "indices": indices, "material": 1 }],
        }));
        nodes.push(json!({ "name": part.name, "mesh": meshes.len() - 1, "skin": 0 }));
        let node = nodes.len() - 1;
        nodes[0]["children"]
            .as_array_mut()
            .expect("children")
            .push(json!(node));
    }
    let bind = b.floats(&inverse_bind_matrices(), "MAT4");
    // The walk: rotation channels for every joint, and the hips' bob.
    let times: Vec<f32> = (0..=KEYS).map(|k| CYCLE * k as f32 / KEYS as f32).collect();
    let time_accessor = b.accessor(
        &f32s(times.iter().copied()),
        (times.len(), "SCALAR", 5126),
        Some((vec![0.0], vec![CYCLE])),
    );
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for j in 0..JOINTS.len() {
        let rotations: Vec<[f32; 4]> = times.iter().map(|&t| walk_rotation(j, t)).collect();
        let output = b.floats(&rotations, "VEC4");
        samplers
            .push(json!({ "input": time_accessor, "output": output, "interpolation": "LINEAR" }));
        channels.push(json!({
            "sampler": samplers.len() - 1,
            "target": { "node": 1 + j, "path": "rotation" },
        }));
    }
    let bob: Vec<[f32; 3]> = times.iter().map(|&t| [0.0, walk_height(t), 0.0]).collect();
    let output = b.floats(&bob, "VEC3");
    samplers.push(json!({ "input": time_accessor, "output": output, "interpolation": "LINEAR" }));
    channels.push(json!({
        "sampler": samplers.len() - 1,
        "target": { "node": 1, "path": "translation" },
    }));
    let document = json!({
        "asset": {
            "version": "2.0",
            "generator": "bevy_cloth examples/character_asset",
        },
        "scene": 0,
        "scenes": [{ "name": "character", "nodes": [0] }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [
            {
                "name": "body",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.55, 0.6, 0.68, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.8,
                },
            },
            {
                "name": "cloth",
                "doubleSided": true,
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.7, 0.1, 0.1, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.9,
                },
            },
        ],
        "skins": [{
            "name": "body",
            "joints": (1..=JOINTS.len()).collect::<Vec<_>>(),
            "inverseBindMatrices": bind,
            "skeleton": 1,
        }],
        "animations": [{ "name": "walk", "samplers": samplers, "channels": channels }],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{
            "byteLength": b.buffer.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64(&b.buffer)),
        }],
    });
    let mut text = serde_json::to_string_pretty(&document).expect("JSON");
    text.push('\n');
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cloths_face_away_from_the_body() {
        // The backstop lies behind a target's normal: the cape's normals point away from the
        // back (−Z), the skirt's away from its axis.
        assert!(cape().normals.iter().all(|n| n[2] < -0.5));
        let skirt = skirt();
        for (p, n) in skirt.positions.iter().zip(&skirt.normals) {
            assert!(p[0] * n[0] + p[2] * n[2] > 0.0, "{p:?} {n:?}");
        }
    }

    #[test]
    fn base64_matches_known_values() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }
}

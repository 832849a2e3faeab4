//! Wavefront OBJ text in and out for [`PolyMesh`]: [`parse_obj`] and
//! [`write_obj`].
//!
//! This module holds the text format only. It must not hold mesh validation
//! (it delegates to [`PolyMesh::new`]) and must never panic on any input:
//! malformed or truncated text yields a [`SubdivisionError`] with a line number.
//!
//! Supported: `v x y z [w ...]` (extra components such as `w` or vertex
//! colours are ignored), `vt u [v [w]]`, and `f` with corners written `a`,
//! `a/b`, `a/b/c` or `a//c`, 1-based or negative (relative) indices. Comments
//! (`#` to end of line) and the statements `vn`, `vp`, `o`, `g`, `s`, `usemtl`,
//! `mtllib`, `l`, `p` and any other unknown keyword are ignored. Either every
//! face has texture coordinates or none does. A face may only reference `v`
//! and `vt` lines that come before it (as every common exporter writes).

use std::fmt::Write as _;

use glam::{DVec3, Vec2};

use super::{PolyMesh, SubdivisionError};

/// Parses OBJ text into a [`PolyMesh`] (positions in double precision,
/// per-corner UVs when the faces reference `vt`).
///
/// # Example
/// ```
/// use bevy_cloth::subdivision::parse_obj;
///
/// let mesh = parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")?;
/// assert_eq!((mesh.vertex_count(), mesh.face_count()), (4, 1));
/// # Ok::<(), bevy_cloth::subdivision::SubdivisionError>(())
/// ```
pub fn parse_obj(text: &str) -> Result<PolyMesh, SubdivisionError> {
    let mut positions: Vec<DVec3> = Vec::new();
    let mut texcoords: Vec<Vec2> = Vec::new();
    let mut offsets: Vec<u32> = vec![0];
    let mut indices: Vec<u32> = Vec::new();
    let mut corner_uvs: Vec<Vec2> = Vec::new();
    // Line of the first face, and whether it had texture coordinates.
    let mut uv_mode: Option<(usize, bool)> = None;

    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let mut xyz = [0.0f64; 3];
                for (k, slot) in xyz.iter_mut().enumerate() {
                    let tok = tokens.next().ok_or_else(|| {
                        syntax(line, format!("vertex needs 3 coordinates, found {k}"))
                    })?;
                    *slot = parse_float(tok, line)?;
                }
                for tok in tokens {
                    parse_float(tok, line)?;
                }
                positions.push(DVec3::from_array(xyz));
            }
            "vt" => {
                let mut uv = [0.0f64; 2];
                let mut count = 0;
                for tok in tokens {
                    let x = parse_float(tok, line)?;
                    if count < 2 {
                        uv[count] = x;
                    }
                    count += 1;
                }
                if count == 0 || count > 3 {
                    return Err(syntax(
                        line,
                        format!("texture coordinate needs 1 to 3 components, found {count}"),
                    ));
                }
                let uv32 = Vec2::new(uv[0] as f32, uv[1] as f32);
                if !uv32.is_finite() {
                    return Err(syntax(
                        line,
                        format!(
                            "texture coordinate ({}, {}) is not finite in f32",
                            uv[0], uv[1]
                        ),
                    ));
                }
                texcoords.push(uv32);
            }
            "f" => {
                let start = indices.len();
                let mut with_uv: Option<bool> = None;
                for tok in tokens {
                    let mut parts = tok.split('/');
                    let v = parts.next().unwrap_or("");
                    let vt = parts.next();
                    let vn = parts.next();
                    if parts.next().is_some() {
                        return Err(syntax(
                            line,
                            format!("face corner '{tok}' has more than 3 parts"),
                        ));
                    }
                    let vi = resolve(v, positions.len(), line, "vertex")?;
                    if let Some(n) = vn.filter(|s| !s.is_empty()) {
                        // Normals are ignored, but the index must be an integer.
                        n.parse::<i64>().map_err(|_| {
                            syntax(line, format!("normal index '{n}' is not an integer"))
                        })?;
                    }
                    let has_uv = matches!(vt, Some(s) if !s.is_empty());
                    if *with_uv.get_or_insert(has_uv) != has_uv {
                        return Err(syntax(
                            line,
                            "face mixes corners with and without texture coordinates".to_string(),
                        ));
                    }
                    if let Some(t) = vt.filter(|s| !s.is_empty()) {
                        let ti = resolve(t, texcoords.len(), line, "texture coordinate")?;
                        corner_uvs.push(texcoords[ti as usize]);
                    }
                    indices.push(vi);
                }
                let k = indices.len() - start;
                if k < 3 {
                    return Err(syntax(
                        line,
                        format!("face has {k} vertices; a face needs at least 3"),
                    ));
                }
                let has_uv = with_uv.unwrap_or(false);
                match uv_mode {
                    None => uv_mode = Some((line, has_uv)),
                    Some((first, mode)) if mode != has_uv => {
                        return Err(syntax(
                            line,
                            format!(
                                "face {} texture coordinates but the face on line {first} {}",
                                if has_uv { "has" } else { "lacks" },
                                if mode { "has them" } else { "does not" }
                            ),
                        ));
                    }
                    _ => {}
                }
                offsets.push(super::topology::corner_count(indices.len())?);
            }
            _ => {}
        }
    }
    let uvs = matches!(uv_mode, Some((_, true))).then_some(corner_uvs);
    PolyMesh::new(positions, offsets, indices, uvs)
}

/// Writes `mesh` as OBJ text: one `v` line per vertex (shortest round-trip
/// decimal), one `vt` per distinct UV when the mesh has UVs, and one `f` per
/// face with 1-based indices. `header` lines, if any, are written first as
/// comments. Parsing the output with [`parse_obj`] gives back the same mesh.
pub fn write_obj(mesh: &PolyMesh, header: &str) -> String {
    let mut out = String::with_capacity(mesh.vertex_count() * 40 + mesh.face_indices().len() * 8);
    for line in header.lines() {
        // Writing to a String cannot fail.
        let _ = writeln!(out, "# {line}");
    }
    for p in mesh.positions() {
        let _ = writeln!(out, "v {} {} {}", p.x, p.y, p.z);
    }
    let uv_index: Option<Vec<u32>> = mesh.uvs().map(|uvs| {
        let mut ids = std::collections::HashMap::new();
        uvs.iter()
            .map(|uv| {
                let key = uv.to_array().map(f32::to_bits);
                let next = ids.len() as u32;
                *ids.entry(key).or_insert_with(|| {
                    let _ = writeln!(out, "vt {} {}", uv.x, uv.y);
                    next
                })
            })
            .collect()
    });
    for w in mesh.face_offsets().windows(2) {
        out.push('f');
        for c in w[0] as usize..w[1] as usize {
            let v = mesh.face_indices()[c] + 1;
            match &uv_index {
                Some(t) => {
                    let _ = write!(out, " {v}/{}", t[c] + 1);
                }
                None => {
                    let _ = write!(out, " {v}");
                }
            }
        }
        out.push('\n');
    }
    out
}

fn syntax(line: usize, detail: String) -> SubdivisionError {
    SubdivisionError::ObjSyntax { line, detail }
}

fn parse_float(tok: &str, line: usize) -> Result<f64, SubdivisionError> {
    let x: f64 = tok
        .parse()
        .map_err(|_| syntax(line, format!("'{tok}' is not a number")))?;
    if !x.is_finite() {
        return Err(syntax(line, format!("'{tok}' is not a finite number")));
    }
    Ok(x)
}

/// Resolves a 1-based or negative OBJ index against `count` defined elements.
fn resolve(
    tok: &str,
    count: usize,
    line: usize,
    kind: &'static str,
) -> Result<u32, SubdivisionError> {
    let i: i64 = tok
        .parse()
        .map_err(|_| syntax(line, format!("{kind} index '{tok}' is not an integer")))?;
    let out_of_range = || SubdivisionError::ObjIndexOutOfRange {
        line,
        kind,
        index: i,
        count,
    };
    let zero_based = if i > 0 {
        i - 1
    } else if i < 0 {
        (count as i64).checked_add(i).ok_or_else(out_of_range)?
    } else {
        return Err(out_of_range());
    };
    if zero_based < 0 || zero_based >= count as i64 || zero_based >= u32::MAX as i64 {
        return Err(out_of_range());
    }
    Ok(zero_based as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn corner_forms_and_negative_indices() {
        let text = "# hi\no thing\ng grp\ns off\nusemtl m\nvn 0 0 1\n\
                    v 0 0 0\nv 1 0 0 1.0\nv 1 1 0\nv 0 1 0 # trailing comment\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                    f 1/1/1 2/2/1 3/3/1\nf -4/-4 -2/-2 -1/-1\n";
        let m = parse_obj(text).unwrap();
        assert_eq!(m.vertex_count(), 4);
        assert_eq!(m.face(1), Some(&[0u32, 2, 3][..]));
        assert_eq!(m.face_uvs(1).unwrap()[2], Vec2::new(0.0, 1.0));
        let m = parse_obj(&format!("{QUAD}f 1//1 2//1 3//1 4//1\n")).unwrap();
        assert!(m.uvs().is_none());
        assert_eq!(m.face(0), Some(&[0u32, 1, 2, 3][..]));
    }

    #[test]
    fn malformed_lines_report_line_numbers() {
        let cases: &[(&str, usize)] = &[
            ("v 1 2\n", 1),
            ("v 1 2 x\n", 1),
            ("v 1 2 nan\n", 1),
            ("v 1 2 inf\n", 1),
            ("vt\n", 1),
            ("vt a b\n", 1),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3),
            ("v 0 0 0\nf 1 2 3\n", 2),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3/1\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/ 2 x\n", 4),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2/3/4 2 3\n", 4),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n",
                4,
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9223372036854775808\n", 4),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1 3 2\n",
                6,
            ),
        ];
        for &(text, want) in cases {
            match parse_obj(text) {
                Err(SubdivisionError::ObjSyntax { line, .. })
                | Err(SubdivisionError::ObjIndexOutOfRange { line, .. }) => {
                    assert_eq!(line, want, "{text:?}")
                }
                other => panic!("{text:?} gave {other:?}"),
            }
        }
        // Topology errors come from mesh validation.
        assert!(matches!(
            parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n"),
            Err(SubdivisionError::RepeatedVertex { .. })
        ));
        assert!(matches!(
            parse_obj(""),
            Err(SubdivisionError::EmptyMesh { .. })
        ));
    }

    #[test]
    fn truncated_and_garbage_input_never_panics() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nf 1/1 2/2 3/1 4/2\n";
        for cut in 0..=text.len() {
            let _ = parse_obj(&text[..cut]);
        }
        for s in [
            "f",
            "f /",
            "f //",
            "f ///",
            "v",
            "vt 1 2 3 4",
            "\u{feff}v 1 2 3",
            "f -0 1 2",
        ] {
            let _ = parse_obj(s);
        }
    }

    #[test]
    fn random_token_soup_never_panics() {
        let tokens = [
            "v",
            "vt",
            "f",
            "1",
            "-1",
            "2/1",
            "3//2",
            "-2/-1/1",
            "0",
            "1.5",
            "nan",
            "/",
            "//",
            "#",
            "\n",
            "o",
            "9999999999",
            "-9223372036854775808",
            "1/2/3/4",
            "e",
            " ",
        ];
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..3000 {
            let mut text = String::new();
            for _ in 0..(state % 40) {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let t = tokens[(state % tokens.len() as u64) as usize];
                text.push_str(t);
                text.push(if state.is_multiple_of(5) { '\n' } else { ' ' });
            }
            let _ = parse_obj(&text);
        }
    }

    #[test]
    fn round_trip() {
        let text = format!("{QUAD}v 0.1 0.2 0.30000000000000004\nf 1 2 3 4\nf 3 2 5\n");
        let m = parse_obj(&text).unwrap();
        let back = parse_obj(&write_obj(&m, "round trip\ntest")).unwrap();
        assert_eq!(m, back);
        let uv = parse_obj(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.25\n\
             f 1/1 2/2 3/3 4/4\nf 2/5 5/2 3/3\n",
        )
        .unwrap();
        let back = parse_obj(&write_obj(&uv, "")).unwrap();
        assert_eq!(uv, back);
    }
}

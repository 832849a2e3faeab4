//! Analysis of the interior vertex rules: eigenvalues of the local
//! subdivision matrix ([`eigen_report`]) and a curvature proxy at an
//! extraordinary vertex measured on refined paraboloid discs
//! ([`curvature_proxy`]).
//!
//! This module holds measurements that explain the rules; it must not hold
//! anything the per-frame path needs, and it returns plain documented structs
//! (no printing, no files).
//!
//! # Local subdivision matrix
//! For an interior vertex `S` of valence `n` in an all-quad neighbourhood
//! with edge neighbours `eᵢ` and diagonal neighbours `dᵢ`, one Catmull-Clark
//! step maps the `2n+1` one-ring points to the one-ring of the child vertex.
//! The discrete Fourier transform over `i` block-diagonalizes this matrix:
//! frequency `k ≠ 0` gives a `2×2` block with eigenvalues
//! `[(5+c) ± √((c+1)(c+9))]/16`, `c = cos(2πk/n)` (independent of the vertex
//! rule), and frequency 0 gives the eigenvalue 1 plus the `2×2` block
//! `M₀ = [[1/2 − β, 1/8 − α], [1/2 − β, 1/4 − α]]` on `(ē − S, d̄ − S)`,
//! where `α`, `β` are the rule's total diagonal and edge-neighbour weights
//! ([`VertexRule::one_ring_weights`]). `λ` is the largest eigenvalue below 1
//! (frequency 1), `μ` the bowl eigenvalue of `M₀`. For bounded, non-zero
//! curvature at the vertex one wants `μ = λ²`; `μ > λ²` makes curvature grow
//! without bound, `μ < λ²` flattens the vertex, and a negative eigenvalue
//! makes the shape flip sign from level to level.

use std::f64::consts::PI;

use glam::DVec3;

use super::{
    BoundaryMode, PolyMesh, Subdivider, SubdivisionError, VertexRule, frequency_eigenvalues,
    subdominant_eigenvalue,
};

/// Smallest valence the analysis accepts.
pub const MIN_VALENCE: u32 = 3;
/// Largest valence the analysis accepts.
pub const MAX_VALENCE: u32 = 64;
/// The paraboloid the curvature discs lie on: `y = PARABOLOID_COEFFICIENT · r²`
/// (as the `star*` shapes of the shared test data).
pub const PARABOLOID_COEFFICIENT: f64 = 0.15;

/// Eigenvalues of the local subdivision matrix at one valence for one rule.
#[derive(Debug, Clone, PartialEq)]
pub struct EigenReport {
    /// Valence `n` of the interior vertex.
    pub valence: u32,
    /// The vertex rule analysed.
    pub rule: VertexRule,
    /// Subdominant eigenvalue `λ` (frequency 1; the same for every rule).
    pub lambda: f64,
    /// Bowl eigenvalue `μ`: the frequency-0 eigenvalue of `M₀` with the largest
    /// magnitude (the positive one on a tie). Real part if `frequency0_complex`.
    pub mu: f64,
    /// The other eigenvalue of `M₀`. Real part if `frequency0_complex`.
    pub nu: f64,
    /// Whether `M₀` has a complex-conjugate pair (never for the built-in rules
    /// at valences 3..=64); then `mu`, `nu` hold its real part.
    pub frequency0_complex: bool,
    /// `μ / λ²`: 1 means bounded non-zero curvature, above 1 unbounded growth,
    /// below 1 a flat spot.
    pub mu_over_lambda_squared: f64,
    /// All `2n+1` eigenvalues, largest first (real parts for a complex pair).
    pub eigenvalues: Vec<f64>,
    /// The negative eigenvalues (below `-1e-12`), most negative first.
    pub negative: Vec<f64>,
}

/// Computes the eigenvalues of the local subdivision matrix of an interior
/// vertex of `valence` (3..=64) in an all-quad neighbourhood under `rule`,
/// in closed form per Fourier frequency (see the module docs).
pub fn eigen_report(valence: u32, rule: VertexRule) -> Result<EigenReport, SubdivisionError> {
    check_valence(valence)?;
    let w = rule.one_ring_weights(valence);
    let (a, b) = (w.diagonal, w.edge);
    let trace = 0.75 - a - b;
    let det = (0.5 - b) / 8.0;
    let disc = trace * trace - 4.0 * det;
    let (r1, r2, complex) = if disc >= 0.0 {
        let s = disc.sqrt();
        ((trace + s) / 2.0, (trace - s) / 2.0, false)
    } else {
        (trace / 2.0, trace / 2.0, true)
    };
    let (mu, nu) = if r2.abs() > r1.abs() + 1e-12 {
        (r2, r1)
    } else {
        (r1, r2)
    };
    let lambda = subdominant_eigenvalue(valence);
    let mut eigenvalues = vec![1.0, r1, r2];
    for k in 1..valence {
        eigenvalues.extend_from_slice(&frequency_eigenvalues(valence, k));
    }
    eigenvalues.sort_by(|x, y| y.total_cmp(x));
    let mut negative: Vec<f64> = eigenvalues
        .iter()
        .copied()
        .filter(|&x| x < -1e-12)
        .collect();
    negative.sort_by(f64::total_cmp);
    Ok(EigenReport {
        valence,
        rule,
        lambda,
        mu,
        nu,
        frequency0_complex: complex,
        mu_over_lambda_squared: mu / (lambda * lambda),
        eigenvalues,
        negative,
    })
}

/// Where the control points of a curvature disc sit in the plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum DiscLayout {
    /// Edge neighbours on ring `r` at radius `r`, diagonal neighbours at
    /// radius `r·ρ(n)`, `ρ(n) = cos(π/n) / (2(λ − 1/4))`: the planar one-ring
    /// is then the frequency-1 eigenvector (the characteristic map's control
    /// net), so the measurement isolates the vertex rule. At `n = 4`,
    /// `ρ = √2` and the disc is a regular square grid.
    #[default]
    Characteristic,
    /// All ring points of ring `r` at radius `r`, as in the shared
    /// `star*.obj` shapes (at `n = 4` an octagon, not a square grid).
    UniformRadius,
}

/// Builds an open quad disc around one interior vertex of `valence`
/// (3..=64), with `rings` (≥ 1) rings of `2·valence` points each, all on the
/// paraboloid `y = 0.15 r²`, oriented so that normals point to `+y`.
///
/// Vertex 0 is the centre; ring `r` (1-based) holds vertices
/// `1 + (r−1)·2n .. 1 + r·2n` at angles `jπ/n`, even `j` being edge
/// neighbours ("spokes") and odd `j` diagonals. The centre has `n` quads
/// `(0, ring₁[2i+2], ring₁[2i+1], ring₁[2i])`; consecutive rings are joined by
/// quads.
pub fn paraboloid_disc(
    valence: u32,
    rings: u32,
    layout: DiscLayout,
) -> Result<PolyMesh, SubdivisionError> {
    check_valence(valence)?;
    let n = valence as usize;
    let rings = rings.clamp(1, 16) as usize;
    let rho = match layout {
        DiscLayout::Characteristic => {
            (PI / n as f64).cos() / (2.0 * (subdominant_eigenvalue(valence) - 0.25))
        }
        DiscLayout::UniformRadius => 1.0,
    };
    let m = 2 * n;
    let mut positions = vec![DVec3::ZERO];
    for r in 1..=rings {
        for j in 0..m {
            let radius = r as f64 * if j % 2 == 0 { 1.0 } else { rho };
            let t = j as f64 * PI / n as f64;
            positions.push(DVec3::new(
                radius * t.cos(),
                PARABOLOID_COEFFICIENT * radius * radius,
                radius * t.sin(),
            ));
        }
    }
    let ring = |r: usize, j: usize| (1 + (r - 1) * m + j % m) as u32;
    let mut faces: Vec<[u32; 4]> = Vec::with_capacity(n + (rings - 1) * m);
    for i in 0..n {
        faces.push([0, ring(1, 2 * i + 2), ring(1, 2 * i + 1), ring(1, 2 * i)]);
    }
    for r in 1..rings {
        for j in 0..m {
            faces.push([
                ring(r, j),
                ring(r, j + 1),
                ring(r + 1, j + 1),
                ring(r + 1, j),
            ]);
        }
    }
    PolyMesh::from_polygons(positions, &faces)
}

/// One level of a curvature measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvatureSample {
    /// Subdivision level (≥ 1).
    pub level: u32,
    /// Proxy at the extraordinary vertex: mean over its edge neighbours `e` of
    /// the osculating-circle curvature `2 (e − S)·N / |e − S|²`, `N` the unit
    /// area-weighted normal at `S`. For a sampled paraboloid `y = c r²` it
    /// approaches `2c = 0.3`.
    pub raw: f64,
    /// The same proxy at the centre of the valence-4 disc of the same layout
    /// and level (Original rule): the regular value.
    pub regular: f64,
    /// `raw / regular`: 1 is "as curved as a regular vertex"; a negative value
    /// is a dent where there should be a bowl.
    pub ratio: f64,
    /// `raw / (2 · PARABOLOID_COEFFICIENT)`: the proxy relative to the exact
    /// normal curvature `0.3` of the paraboloid at its apex.
    pub ratio_to_paraboloid: f64,
}

/// Curvature proxy at an extraordinary vertex for levels `1..=max_level`.
#[derive(Debug, Clone, PartialEq)]
pub struct CurvatureReport {
    /// Valence of the centre vertex.
    pub valence: u32,
    /// The vertex rule.
    pub rule: VertexRule,
    /// The disc layout used.
    pub layout: DiscLayout,
    /// One sample per level, level 1 first.
    pub samples: Vec<CurvatureSample>,
}

/// Refines a 2-ring [`paraboloid_disc`] of `valence` with `rule` to each
/// level `1..=max_level` (`max_level` ≤ [`MAX_LEVEL`](super::MAX_LEVEL)) and
/// measures the curvature proxy at the centre, normalized by the regular
/// (valence 4) value at the same level.
///
/// Levels are produced one refinement step at a time (each step is a level-1
/// [`Subdivider`] applied to the previous level), which by linearity equals
/// refining the control disc to each level directly.
pub fn curvature_proxy(
    valence: u32,
    rule: VertexRule,
    layout: DiscLayout,
    max_level: u32,
) -> Result<CurvatureReport, SubdivisionError> {
    if max_level > super::MAX_LEVEL {
        return Err(SubdivisionError::LevelTooHigh {
            level: max_level,
            max: super::MAX_LEVEL,
        });
    }
    let raw = centre_curvatures(&paraboloid_disc(valence, 2, layout)?, max_level, rule)?;
    let regular = centre_curvatures(
        &paraboloid_disc(4, 2, layout)?,
        max_level,
        VertexRule::Original,
    )?;
    let samples = raw
        .iter()
        .zip(&regular)
        .zip(1..)
        .map(|((&raw, &regular), level)| CurvatureSample {
            level,
            raw,
            regular,
            ratio: raw / regular,
            ratio_to_paraboloid: raw / (2.0 * PARABOLOID_COEFFICIENT),
        })
        .collect();
    Ok(CurvatureReport {
        valence,
        rule,
        layout,
        samples,
    })
}

/// Curvature proxy at the descendant of control vertex 0, for levels
/// `1..=max_level`.
fn centre_curvatures(
    disc: &PolyMesh,
    max_level: u32,
    rule: VertexRule,
) -> Result<Vec<f64>, SubdivisionError> {
    let mut mesh = disc.clone();
    let mut centre = 0u32;
    let mut out = Vec::with_capacity(max_level as usize);
    for _ in 0..max_level {
        let sub = Subdivider::new(&mesh, 1, rule, BoundaryMode::EdgeOnly)?;
        centre = sub.topology().control_vertex_map()[centre as usize];
        mesh = sub.refined_mesh(mesh.positions())?;
        out.push(vertex_curvature(&mesh, centre));
    }
    Ok(out)
}

/// Mean osculating-circle curvature `2 (e − S)·N / |e − S|²` over the edge
/// neighbours `e` of vertex `centre`, `N` its unit area-weighted normal.
fn vertex_curvature(mesh: &PolyMesh, centre: u32) -> f64 {
    let pos = mesh.positions();
    let s = pos[centre as usize];
    let mut normal = DVec3::ZERO;
    let mut neighbours: Vec<u32> = Vec::new();
    for face in mesh.faces() {
        let Some(j) = face.iter().position(|&v| v == centre) else {
            continue;
        };
        let k = face.len();
        let p0 = pos[face[0] as usize];
        for t in 1..k - 1 {
            normal += (pos[face[t] as usize] - p0).cross(pos[face[t + 1] as usize] - p0);
        }
        neighbours.push(face[(j + 1) % k]);
        neighbours.push(face[(j + k - 1) % k]);
    }
    neighbours.sort_unstable();
    neighbours.dedup();
    let normal = normal.normalize_or_zero();
    let sum: f64 = neighbours
        .iter()
        .map(|&e| {
            let d = pos[e as usize] - s;
            2.0 * d.dot(normal) / d.length_squared()
        })
        .sum();
    sum / neighbours.len().max(1) as f64
}

fn check_valence(valence: u32) -> Result<(), SubdivisionError> {
    if !(MIN_VALENCE..=MAX_VALENCE).contains(&valence) {
        return Err(SubdivisionError::ValenceOutOfRange {
            valence,
            min: MIN_VALENCE,
            max: MAX_VALENCE,
        });
    }
    Ok(())
}

//! The Catmull-Clark vertex and boundary rules: [`VertexRule`], [`BoundaryMode`]
//! and the per-valence weights they produce.
//!
//! This module holds formulas only (scalar weights as functions of valence).
//! It must not hold mesh traversal or stencil assembly; `refine` applies
//! these weights to a mesh.

use std::f64::consts::PI;

/// How the mesh boundary is refined (OpenSubdiv `VtxBoundaryInterpolation`).
///
/// In both modes boundary edges are cubic B-spline curves: a boundary edge
/// point is the edge midpoint and a boundary vertex moves to
/// `3/4 v + 1/8 (a + b)`, with `a`, `b` its two boundary neighbours. Boundary
/// vertices use this rule whatever the [`VertexRule`].
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
    bevy::reflect::Reflect,
)]
pub enum BoundaryMode {
    /// OpenSubdiv `VTX_BOUNDARY_EDGE_ONLY`: every boundary vertex, corners
    /// included, follows the boundary curve rule.
    #[default]
    EdgeOnly,
    /// OpenSubdiv `VTX_BOUNDARY_EDGE_AND_CORNER`: as `EdgeOnly`, but a boundary
    /// vertex with exactly one incident face (a valence-2 corner) stays fixed.
    EdgeAndCorner,
}

/// The rule that moves an interior (non-boundary) vertex.
///
/// All three rules are written in the general polygon ("face-point") form
///
/// `v' = w_F F̄ + w_R R̄ + w_S S`, with `w_F + w_R + w_S = 1`,
///
/// where `S` is the old vertex, `F̄` the mean of the face points (centroids) of
/// its `n` incident faces and `R̄` the mean of the midpoints of its `n`
/// incident edges. In an all-quad neighbourhood this equals the one-ring
/// ("vertex") form `v' = α Q̄ + β R̄ᵥ + γ S`, where `Q̄` is the mean of the `n`
/// diagonal neighbours and `R̄ᵥ` the mean of the `n` edge neighbours, with
/// `α = w_F/4`, `β = w_F/2 + w_R/2`, `γ = w_S + w_F/4 + w_R/2`.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
    bevy::reflect::Reflect,
)]
pub enum VertexRule {
    /// Standard Catmull-Clark (the OpenSubdiv rule):
    /// `v' = (F̄ + 2R̄ + (n−3) S) / n`, i.e. `w_F = 1/n`, `w_R = 2/n`,
    /// `w_S = (n−3)/n`. In one-ring form this is the source paper's Eq. 1 (with its
    /// denominator typo fixed): `α = 1/(4n)`, `β = 3/(2n)`, `γ = 1 − 7/(4n)`,
    /// so `α : β = 1 : 6`.
    #[default]
    Original,
    /// The source paper's "enhanced" rule (Eq. 2; the paper is named in the crate docs), used at interior vertices of
    /// valence `n > 4` only (Original elsewhere), exactly as published:
    ///
    /// `v' = Q/n + 6R/n + S(n−7)/n`.
    ///
    /// Reading chosen: `Q` is the mean of the face points (centroids of the
    /// incident faces) and `R` is the mean of the **midpoints** of the incident
    /// edges — not of the new Catmull-Clark edge points. The text supports
    /// this: the weights are described as "average surrounding face points"
    /// and "average surrounding edge point", the weights `1/n + 6/n + (n−7)/n`
    /// only sum to one if `Q`, `R` are averages, and the paper's Figure 3
    /// computes "Centroid = face point", "Center = midpoint of edges",
    /// "newEdge = average of midpoint of adjacent edges" and then the new
    /// vertex, i.e. the Catmull-Clark (1978) `F`/`R` quantities with new
    /// weights. So `w_F = 1/n`, `w_R = 6/n`, `w_S = (n−7)/n`; in one-ring form
    /// `α = 1/(4n)`, `β = 7/(2n)`, `γ = 1 − 15/(4n)`.
    ///
    /// At `n = 5` its frequency-0 block has a negative eigenvalue (≈ −0.158),
    /// which makes the surface near the vertex flip between bump and dent
    /// from level to level (the "dents and sharp points" the paper saw); at
    /// `n = 6` one eigenvalue is still negative (≈ −0.057), and for every
    /// `n > 4` the bowl eigenvalue falls below `λ²`, so the vertex flattens
    /// out (see [`analysis`](super::analysis)).
    Enhanced,
    /// A tuned rule: keep the paper's `1 : 6` ratio between the total
    /// diagonal weight `α` and the total edge-neighbour weight `β` of the
    /// one-ring form, and choose the weight per valence so that the bowl
    /// eigenvalue `μ` of the local subdivision matrix equals `λ²`, with `λ` the
    /// subdominant eigenvalue. Used at every interior vertex of valence
    /// `n ≠ 4` (at `n = 4` it coincides with Original).
    ///
    /// # Derivation
    /// For an interior vertex `S` with edge neighbours `eᵢ` and diagonal
    /// neighbours `dᵢ` (all-quad one-ring), the new one-ring is
    /// `S' = γS + βē + αd̄`, new edge points
    /// `e'ᵢ = 3/8 S + 3/8 eᵢ + (eᵢ₋₁+eᵢ₊₁)/16 + (dᵢ₋₁+dᵢ)/16` and face points
    /// `d'ᵢ = (S + eᵢ + eᵢ₊₁ + dᵢ)/4`. A discrete Fourier transform over `i`
    /// splits the `(2n+1)×(2n+1)` matrix into blocks. For frequency
    /// `k ≠ 0` (`θ = 2πk/n`, `c = cos θ`) the `2×2` block has trace
    /// `(5+c)/8` and determinant `1/16`, so its eigenvalues are
    /// `[(5+c) ± √((c+1)(c+9))]/16`; they do not depend on the vertex rule and
    /// `λ = [(5+c₁) + √((c₁+1)(c₁+9))]/16`, `c₁ = cos(2π/n)`
    /// (`λ(5) ≈ 0.549988`). Frequency 0 has eigenvalue 1 (affine invariance)
    /// and, on `(ē − S, d̄ − S)`, the `2×2` block
    /// `M₀ = [[1/2 − β, 1/8 − α], [1/2 − β, 1/4 − α]]`, with trace
    /// `3/4 − α − β` and determinant `(1/2 − β)/8`. With `β = 6α` its
    /// characteristic polynomial is `x² − (3/4 − 7α)x + (1/2 − 6α)/8`;
    /// requiring `x = λ²` to be a root and solving the linear equation in `α`:
    ///
    /// `α(n) = (3/4 λ² − λ⁴ − 1/16) / (7λ² − 3/4)`, `β = 6α`, `γ = 1 − 7α`.
    ///
    /// At `n = 4` (`λ = 1/2`) this gives `α = 1/16`, the B-spline rule. The
    /// other root `(1/2 − 6α)/(8λ²)` stays below `λ²` for every `n ≥ 3`, so
    /// `λ²` is indeed the bowl eigenvalue `μ`. In face-point form the rule is
    /// `v' = 4α (F̄ + 2R̄) + (1 − 12α) S` (Original has `4α = 1/n`). The
    /// weights are evaluated in closed form on the fly (a few flops).
    ///
    /// | n | α       | β = 6α  | γ = 1−7α | Original α = 1/(4n) |
    /// |---|---------|---------|----------|---------------------|
    /// | 3 | 0.082738 | 0.496427 | 0.420835 | 0.083333 |
    /// | 4 | 0.062500 | 0.375000 | 0.562500 | 0.062500 |
    /// | 5 | 0.053288 | 0.319729 | 0.626982 | 0.050000 |
    /// | 6 | 0.047813 | 0.286876 | 0.665311 | 0.041667 |
    /// | 7 | 0.044292 | 0.265752 | 0.689956 | 0.035714 |
    /// | 8 | 0.041906 | 0.251435 | 0.706659 | 0.031250 |
    Tuned,
}

/// Weights of an interior vertex rule in face-point form:
/// `v' = face · F̄ + midpoint · R̄ + vertex · S` (see [`VertexRule`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FacePointWeights {
    /// Weight of the mean face point `F̄`.
    pub face: f64,
    /// Weight of the mean incident-edge midpoint `R̄`.
    pub midpoint: f64,
    /// Weight of the old vertex `S`.
    pub vertex: f64,
}

/// Weights of an interior vertex rule in one-ring form for an all-quad
/// neighbourhood: `v' = diagonal · Q̄ + edge · R̄ᵥ + vertex · S`, where `Q̄` is
/// the mean diagonal neighbour and `R̄ᵥ` the mean edge neighbour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OneRingWeights {
    /// Total weight `α` of the `n` diagonal neighbours.
    pub diagonal: f64,
    /// Total weight `β` of the `n` edge neighbours.
    pub edge: f64,
    /// Weight `γ` of the vertex itself.
    pub vertex: f64,
}

impl VertexRule {
    /// All rules, in declaration order.
    pub const ALL: [VertexRule; 3] = [
        VertexRule::Original,
        VertexRule::Enhanced,
        VertexRule::Tuned,
    ];

    /// Face-point-form weights for an interior vertex with `valence` incident
    /// faces. Valence 0 yields the identity (`vertex = 1`).
    pub fn weights(self, valence: u32) -> FacePointWeights {
        if valence == 0 {
            return FacePointWeights {
                face: 0.0,
                midpoint: 0.0,
                vertex: 1.0,
            };
        }
        let n = f64::from(valence);
        match self {
            VertexRule::Enhanced if valence > 4 => FacePointWeights {
                face: 1.0 / n,
                midpoint: 6.0 / n,
                vertex: (n - 7.0) / n,
            },
            VertexRule::Tuned if valence >= 3 && valence != 4 => {
                let a = tuned_diagonal_weight(valence);
                FacePointWeights {
                    face: 4.0 * a,
                    midpoint: 8.0 * a,
                    vertex: 1.0 - 12.0 * a,
                }
            }
            _ => FacePointWeights {
                face: 1.0 / n,
                midpoint: 2.0 / n,
                vertex: (n - 3.0) / n,
            },
        }
    }

    /// One-ring-form weights (all-quad neighbourhood) for an interior vertex
    /// of the given valence.
    pub fn one_ring_weights(self, valence: u32) -> OneRingWeights {
        let w = self.weights(valence);
        OneRingWeights {
            diagonal: w.face / 4.0,
            edge: w.face / 2.0 + w.midpoint / 2.0,
            vertex: w.vertex + w.face / 4.0 + w.midpoint / 2.0,
        }
    }
}

/// Subdominant eigenvalue `λ` of the Catmull-Clark local subdivision matrix at
/// an interior vertex of valence `n` (all quads):
/// `λ = [(5+c) + √((c+1)(c+9))]/16` with `c = cos(2π/n)`.
///
/// It is the same for every [`VertexRule`] because the rules only change the
/// frequency-0 block. Valence 0 returns 0.
pub fn subdominant_eigenvalue(valence: u32) -> f64 {
    frequency_eigenvalues(valence, 1)[0]
}

/// The two eigenvalues (larger first) of the frequency-`k` block (`k ≠ 0`) of
/// the local subdivision matrix at valence `n`: `[(5+c) ± √((c+1)(c+9))]/16`,
/// `c = cos(2πk/n)`. Valence 0 returns zeros.
pub fn frequency_eigenvalues(valence: u32, k: u32) -> [f64; 2] {
    if valence == 0 {
        return [0.0, 0.0];
    }
    let c = (2.0 * PI * f64::from(k) / f64::from(valence)).cos();
    // (c+1) can round to a tiny negative value at c = -1.
    let disc = ((c + 1.0) * (c + 9.0)).max(0.0).sqrt();
    [((5.0 + c) + disc) / 16.0, ((5.0 + c) - disc) / 16.0]
}

/// Total diagonal weight `α(n)` of [`VertexRule::Tuned`]:
/// `α = (3/4 λ² − λ⁴ − 1/16) / (7λ² − 3/4)` with `λ` =
/// [`subdominant_eigenvalue`]`(n)`. Valences below 3 fall back to Original's
/// `1/(4n)` (or 0 for valence 0).
pub fn tuned_diagonal_weight(valence: u32) -> f64 {
    if valence < 3 {
        return if valence == 0 {
            0.0
        } else {
            0.25 / f64::from(valence)
        };
    }
    if valence == 4 {
        return 1.0 / 16.0;
    }
    let l2 = subdominant_eigenvalue(valence).powi(2);
    (0.75 * l2 - l2 * l2 - 1.0 / 16.0) / (7.0 * l2 - 0.75)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_sum_to_one() {
        for rule in VertexRule::ALL {
            for n in 1..=40 {
                let w = rule.weights(n);
                assert!((w.face + w.midpoint + w.vertex - 1.0).abs() < 1e-14);
                let r = rule.one_ring_weights(n);
                assert!((r.diagonal + r.edge + r.vertex - 1.0).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn original_one_ring_matches_paper_eq1() {
        for n in 3..=12 {
            let r = VertexRule::Original.one_ring_weights(n);
            let nf = f64::from(n);
            assert!((r.diagonal - 1.0 / (4.0 * nf)).abs() < 1e-15);
            assert!((r.edge - 3.0 / (2.0 * nf)).abs() < 1e-15);
            assert!((r.vertex - (1.0 - 7.0 / (4.0 * nf))).abs() < 1e-15);
        }
    }

    #[test]
    fn enhanced_is_eq2_above_valence_4_only() {
        assert_eq!(
            VertexRule::Enhanced.weights(4),
            VertexRule::Original.weights(4)
        );
        assert_eq!(
            VertexRule::Enhanced.weights(3),
            VertexRule::Original.weights(3)
        );
        let w = VertexRule::Enhanced.weights(5);
        assert!((w.face - 0.2).abs() < 1e-15);
        assert!((w.midpoint - 1.2).abs() < 1e-15);
        assert!((w.vertex + 0.4).abs() < 1e-15);
    }

    #[test]
    fn tuned_keeps_ratio_and_hits_lambda_squared() {
        for n in 3..=16 {
            let r = VertexRule::Tuned.one_ring_weights(n);
            assert!((r.edge - 6.0 * r.diagonal).abs() < 1e-14);
            let (a, b) = (r.diagonal, r.edge);
            let l2 = subdominant_eigenvalue(n).powi(2);
            let p = l2 * l2 - (0.75 - a - b) * l2 + (0.5 - b) / 8.0;
            assert!(p.abs() < 1e-14, "n={n}: p(λ²)={p}");
        }
        assert_eq!(
            VertexRule::Tuned.weights(4),
            VertexRule::Original.weights(4)
        );
    }

    #[test]
    fn lambda_values() {
        assert!((subdominant_eigenvalue(4) - 0.5).abs() < 1e-15);
        assert!((subdominant_eigenvalue(5) - 0.5500).abs() < 1e-4);
    }
}

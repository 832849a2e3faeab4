//! The canonical grid cloth's specification, [`GridSpec`].

use bevy::reflect::Reflect;
use glam::Vec2;
use serde::{Deserialize, Serialize};

use crate::error::{ClothError, positive};

/// Which plane a grid cloth lies in, in the cloth's local space. The grid is centred on the origin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum GridPlane {
    /// Particle `(i, j)` at `((i - (nx-1)/2) h, 0, (j - (ny-1)/2) h)`: a horizontal sheet, facing +Y.
    #[default]
    Horizontal,
    /// Particle `(i, j)` at `((i - (nx-1)/2) h, -(j - (ny-1)/2) h, 0)`: a hanging curtain, row 0 on
    /// top, facing +Z.
    Vertical,
}

pub use crate::limits::MAX_PARTICLES;

/// The canonical rectangular grid cloth (docs/guide.md, "The model").
///
/// Particle `(i, j)` has index `j * nx + i`. Springs: structural `(i,j)-(i+1,j)`, `(i,j)-(i,j+1)`;
/// shear `(i,j)-(i+1,j+1)`, `(i+1,j)-(i,j+1)`; bend `(i,j)-(i+2,j)`, `(i,j)-(i,j+2)`. Rest lengths are
/// the initial distances.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Particles along the first axis (`i`), at least 2.
    pub nx: u32,
    /// Particles along the second axis (`j`), at least 2.
    pub ny: u32,
    /// Distance between neighbouring particles, in metres.
    pub spacing: f32,
    /// Orientation of the sheet in local space.
    #[serde(default)]
    pub plane: GridPlane,
}

impl GridSpec {
    /// A horizontal `nx` × `ny` grid with the given spacing.
    pub fn new(nx: u32, ny: u32, spacing: f32) -> Self {
        Self {
            nx,
            ny,
            spacing,
            plane: GridPlane::Horizontal,
        }
    }

    /// The same grid in another plane.
    pub fn with_plane(mut self, plane: GridPlane) -> Self {
        self.plane = plane;
        self
    }

    /// Index of particle `(i, j)`.
    pub fn index(&self, i: u32, j: u32) -> u32 {
        j * self.nx + i
    }

    /// Checks the spec; the error names the bad field: `nx` and `ny` at least 2, at most
    /// [`MAX_PARTICLES`] particles, `spacing` finite and positive and small enough that the grid's
    /// diagonal is finite in `f32`.
    pub fn validate(&self) -> Result<(), ClothError> {
        if self.nx < 2 {
            return Err(ClothError::GridTooSmall {
                field: "nx",
                value: self.nx,
            });
        }
        if self.ny < 2 {
            return Err(ClothError::GridTooSmall {
                field: "ny",
                value: self.ny,
            });
        }
        if (self.nx as u64) * (self.ny as u64) > MAX_PARTICLES as u64 {
            return Err(ClothError::GridTooLarge {
                nx: self.nx,
                ny: self.ny,
            });
        }
        positive("spacing", self.spacing)?;
        // Every spring is shorter than the diagonal; its length must not overflow.
        let diagonal = Vec2::new(
            (self.nx - 1) as f32 * self.spacing,
            (self.ny - 1) as f32 * self.spacing,
        )
        .length();
        if !diagonal.is_finite() {
            return Err(ClothError::InvalidValue {
                field: "spacing",
                expected: "small enough that the grid's diagonal is finite",
                value: self.spacing as f64,
            });
        }
        Ok(())
    }
}

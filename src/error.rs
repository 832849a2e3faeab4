//! The crate's error type. Everything that takes user data (grid specs, meshes, configs, pins, scene
//! files) reports problems through [`ClothError`], whose messages name the offending field and value.
//! Nothing here depends on Bevy.

use thiserror::Error;

use crate::subdivision::SubdivisionError;

/// Everything that can be wrong with a cloth description or its settings.
///
/// Each message names the field and the offending value, so it can be shown to a user as is.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ClothError {
    /// A grid needs at least 2 particles along each side.
    #[error("grid {field} must be at least 2, got {value}")]
    GridTooSmall {
        /// `"nx"` or `"ny"`.
        field: &'static str,
        /// The value given.
        value: u32,
    },
    /// A grid larger than the index type can address.
    #[error("grid {nx}×{ny} has more particles than fit in a u32 index")]
    GridTooLarge {
        /// Particles along x.
        nx: u32,
        /// Particles along y.
        ny: u32,
    },
    /// A length, mass, time or stiffness that must be positive (or non-negative) and finite is not.
    #[error("{field} must be {expected}, got {value}")]
    InvalidValue {
        /// The field, e.g. `"spacing"` or `"stiffness.bend"`.
        field: &'static str,
        /// What the field must be, e.g. `"finite and > 0"`.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
    /// A count (substeps, iterations) out of its allowed range.
    #[error("{field} must be in {min}..={max}, got {value}")]
    CountOutOfRange {
        /// The field, e.g. `"substeps"`.
        field: &'static str,
        /// Smallest allowed value.
        min: u32,
        /// Largest allowed value.
        max: u32,
        /// The value given.
        value: u32,
    },
    /// A pin names a particle the cloth does not have.
    #[error("pin index {index} is out of range: the cloth has {count} particles")]
    PinOutOfRange {
        /// The pinned particle index.
        index: u32,
        /// Number of particles in the cloth.
        count: usize,
    },
    /// A mesh given as a cloth source lacks something the cloth needs, or is malformed.
    #[error("mesh {what}")]
    InvalidMesh {
        /// What is wrong, e.g. `"has no index buffer"`.
        what: String,
    },
    /// A vertex index in a mesh points past the end of its vertex list.
    #[error(
        "mesh index {index} at position {position} is out of range: the mesh has {count} vertices"
    )]
    MeshIndexOutOfRange {
        /// The bad index value.
        index: u32,
        /// Where in the index buffer it is.
        position: usize,
        /// Number of vertices.
        count: usize,
    },
    /// An explicit integrator ran past its stability limit `h ω_max < 2`: the cloth's energy grew
    /// step after step with nothing to explain it. The cloth is stopped before values overflow.
    #[error(
        "{integrator} is unstable at step {step}: substep {h} s × highest spring frequency \
         {omega_max} rad/s = {h_omega:.2} is past the limit 2 (energy grew {growth:.0}× in \
         {steps} steps); use at least {substeps_needed} substeps (auto_substeps), lower the \
         stiffness, or use XPBD or implicit Euler"
    )]
    Unstable {
        /// The integrator's name.
        integrator: &'static str,
        /// Fixed step counter at which the runaway was detected.
        step: u64,
        /// The substep length, s.
        h: f32,
        /// Gershgorin bound on the highest angular frequency of the springs, rad/s.
        omega_max: f32,
        /// `h · omega_max`.
        h_omega: f32,
        /// Substeps per frame that the stability bound asks for.
        substeps_needed: u32,
        /// Factor by which the kinetic plus elastic energy grew.
        growth: f64,
        /// Over how many steps.
        steps: u32,
    },
    /// The simulation produced a non-finite value; the cloth is stopped instead of spreading NaN.
    #[error(
        "simulation diverged at step {step}: particle {particle} became non-finite \
         (time step {dt} s over {substeps} substeps is too large for this stiffness and mass)"
    )]
    Diverged {
        /// Fixed step counter at which the divergence was detected.
        step: u64,
        /// First particle found with a non-finite position.
        particle: usize,
        /// The frame time step in seconds.
        dt: f32,
        /// Substeps per frame.
        substeps: u32,
    },
    /// A subdivision surface could not be built (see [`SubdivisionError`]).
    #[error("subdivision: {0}")]
    Subdivision(#[from] SubdivisionError),
    /// The f64 reference integrator could not reach its end time.
    #[error("reference integration failed: {what}")]
    Reference {
        /// What went wrong, e.g. `"step size underflow at t = 0.3 s"`.
        what: String,
    },
    /// A scene file could not be read or parsed.
    #[error("scene: {0}")]
    Scene(String),
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn positive(field: &'static str, value: f32) -> Result<(), ClothError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ClothError::InvalidValue {
            field,
            expected: "finite and > 0",
            value: value as f64,
        })
    }
}

/// Checks that `value` is finite and not negative.
pub(crate) fn non_negative(field: &'static str, value: f32) -> Result<(), ClothError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ClothError::InvalidValue {
            field,
            expected: "finite and >= 0",
            value: value as f64,
        })
    }
}

/// Checks that `value` lies in `min..=max`.
pub(crate) fn count_in(
    field: &'static str,
    value: u32,
    min: u32,
    max: u32,
) -> Result<(), ClothError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(ClothError::CountOutOfRange {
            field,
            min,
            max,
            value,
        })
    }
}

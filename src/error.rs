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
    /// A grid with more particles than [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES).
    #[error(
        "grid {nx}×{ny} has {} particles, more than the supported maximum {}",
        *.nx as u64 * *.ny as u64,
        crate::limits::MAX_PARTICLES
    )]
    GridTooLarge {
        /// Particles along x.
        nx: u32,
        /// Particles along y.
        ny: u32,
    },
    /// A count past a bound, found before anything of that size is allocated: more particles than
    /// [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES), more pins than particles, more springs at
    /// one particle than [`MAX_SPRINGS_PER_PARTICLE`](crate::sim::MAX_SPRINGS_PER_PARTICLE), … (the
    /// guide's "Bounds" lists them all).
    #[error("{field}: {count}, more than the bound {bound} ({why})")]
    TooMany {
        /// What is counted, e.g. `"particles"` or `"pins"`.
        field: &'static str,
        /// The count the input asks for.
        count: u64,
        /// The most allowed.
        bound: u64,
        /// Where the bound comes from and which inputs gave the count.
        why: String,
    },
    /// A length past a bound derived from the cloth's model, e.g. a self-collision thickness
    /// longer than the cloth's edges allow (see
    /// [`MAX_THICKNESS_PER_EDGE`](crate::sim::MAX_THICKNESS_PER_EDGE)).
    #[error("{field} is {value} m, more than the bound {bound} m ({why})")]
    TooLong {
        /// The field, e.g. `"self_collision.thickness"`.
        field: &'static str,
        /// The value given, m.
        value: f32,
        /// The most allowed for this cloth, m.
        bound: f32,
        /// Where the bound comes from.
        why: String,
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
    /// A cloth's targets ([`ClothTargets`](crate::ClothTargets)) cannot be built: weights that
    /// do not match the cloth, or a skin that does not match its mesh.
    #[error("targets: {what}")]
    InvalidTargets {
        /// What is wrong.
        what: String,
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
    /// An explicit integrator ran past its stability bound (`h ω_max ≥ 2`, or fewer substeps
    /// than its bound asks for, held back by `MAX_SUBSTEPS`): the cloth's energy grew step after
    /// step, or a millionfold within one, with nothing to explain it. The cloth is stopped before
    /// values overflow.
    #[error(
        "{integrator} is unstable at step {step}: substep {h} s × highest spring frequency \
         {omega_max} rad/s = {h_omega:.2} is past its stability bound (energy grew \
         {growth:.1e}× in {steps} steps); use at least {substeps_needed} substeps \
         (auto_substeps), lower the stiffness, or use XPBD or implicit Euler"
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
    /// A mesh face that cannot carry cloth: it uses a vertex twice, or it (or, for a quad, one of
    /// the two triangles it is drawn with) has no area because its corners are collinear.
    #[error("mesh face {face} (vertices {vertices:?}) is degenerate: {reason}")]
    DegenerateFace {
        /// Index of the face (the `face`-th group of `face_size` indices).
        face: usize,
        /// Its vertex indices.
        vertices: Vec<u32>,
        /// What is wrong, e.g. `"it uses vertex 4 more than once"`.
        reason: String,
    },
    /// Two distinct vertices at the same position are joined by an edge, so the spring along it
    /// would have no length and no direction.
    #[error("mesh face {face} has a zero-length edge: vertices {a} and {b} are both at {position}")]
    ZeroLengthEdge {
        /// Index of the face with the edge.
        face: usize,
        /// One end of the edge.
        a: u32,
        /// The other end.
        b: u32,
        /// Where both vertices are.
        position: glam::Vec3,
    },
    /// An edge shared by more than two faces (a fin or a "book" of pages): cloth is a surface, so
    /// each edge borders one face (a boundary) or two.
    #[error(
        "mesh edge ({a}, {b}) is shared by {} faces (faces {faces:?}); an edge of a cloth borders \
         at most two",
        .faces.len()
    )]
    NonManifoldEdge {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
        /// Every face that uses the edge, in index order.
        faces: Vec<usize>,
    },
    /// A cloth that must be a closed surface (one with [`Pressure`](crate::sim::Pressure)) is
    /// not one: see [`ClothModel::check_closed`](crate::sim::ClothModel::check_closed).
    #[error("the cloth is not a closed surface wound outward: {what}")]
    NotClosed {
        /// What is wrong and where, e.g. `"edge (3, 7) borders only triangle 12: …"`.
        what: String,
    },
    /// A cloth that has no coarse level of detail was asked to run at one (see
    /// [`ClothSim::set_coarse`](crate::sim::ClothSim::set_coarse)).
    #[error("the cloth has no coarse level: {what}")]
    NoCoarseLevel {
        /// Why, e.g. `"its particles are not rows and columns of a lattice"`.
        what: String,
    },
    /// The simulation produced a non-finite value; the cloth is stopped instead of spreading NaN.
    #[error(
        "simulation diverged at step {step}: particle {particle} became non-finite \
         (time step {dt} s over {substeps} substeps is too large for this stiffness and mass)"
    )]
    Diverged {
        /// Fixed step counter at which the divergence was detected.
        step: u64,
        /// First particle found with a non-finite position (or, if none, velocity).
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
    /// A scene file could not be read or parsed (the message has the parser's line and column).
    #[error("scene: {0}")]
    Scene(String),
    /// A bad value inside one item of a scene, e.g. the third collider: `location` says which
    /// (`"colliders[2]"`), `error` what is wrong with it.
    #[error("{location}: {error}")]
    InScene {
        /// Which item, e.g. `"colliders[2]"`.
        location: String,
        /// What is wrong with it.
        error: Box<ClothError>,
    },
}

impl ClothError {
    /// The error itself, or for [`ClothError::InScene`] the error inside (however deeply nested),
    /// so that callers can match on what went wrong regardless of where.
    ///
    /// ```
    /// use bevy_cloth::scene::ClothScene;
    /// use bevy_cloth::ClothError;
    ///
    /// let e = ClothScene::from_ron(
    ///     "(cloth: Grid((nx: 4, ny: 4, spacing: 0.1)), colliders: [(shape: Sphere(radius: -1.0))])",
    /// )
    /// .unwrap_err();
    /// assert!(e.to_string().starts_with("colliders[0]: collider.radius"));
    /// assert!(matches!(e.innermost(), ClothError::InvalidValue { field: "collider.radius", .. }));
    /// ```
    pub fn innermost(&self) -> &ClothError {
        match self {
            ClothError::InScene { error, .. } => error.innermost(),
            other => other,
        }
    }
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

/// Checks that every index in `indices` is below `count`; the error names the first that is not
/// and where it is.
pub(crate) fn indices_in_range(indices: &[u32], count: usize) -> Result<(), ClothError> {
    match indices
        .iter()
        .enumerate()
        .find(|(_, i)| **i as usize >= count)
    {
        Some((position, &index)) => Err(ClothError::MeshIndexOutOfRange {
            index,
            position,
            count,
        }),
        None => Ok(()),
    }
}

/// Checks that `value` is finite.
pub(crate) fn finite(field: &'static str, value: f32) -> Result<(), ClothError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ClothError::InvalidValue {
            field,
            expected: "finite",
            value: value as f64,
        })
    }
}

/// Checks that every component of `value` is finite; the error names the component
/// (`fields[0]` for x, `fields[1]` for y, `fields[2]` for z) and its value.
pub(crate) fn finite_vec3(fields: [&'static str; 3], value: glam::Vec3) -> Result<(), ClothError> {
    for (field, v) in fields.into_iter().zip(value.to_array()) {
        finite(field, v)?;
    }
    Ok(())
}

/// Checks that `value` lies in `0..=1`.
pub(crate) fn unit_interval(field: &'static str, value: f32) -> Result<(), ClothError> {
    if (0.0..=1.0).contains(&value) {
        Ok(())
    } else {
        Err(ClothError::InvalidValue {
            field,
            expected: "in 0..=1",
            value: value as f64,
        })
    }
}

/// Checks that `count` is at most `bound`; the error says `why` (where the bound comes from).
pub(crate) fn at_most(
    field: &'static str,
    count: usize,
    bound: usize,
    why: impl FnOnce() -> String,
) -> Result<(), ClothError> {
    if count <= bound {
        Ok(())
    } else {
        Err(ClothError::TooMany {
            field,
            count: count as u64,
            bound: bound as u64,
            why: why(),
        })
    }
}

/// Checks that a cloth of `count` particles (as `why` says they come about) is within
/// [`MAX_PARTICLES`](crate::limits::MAX_PARTICLES).
pub(crate) fn particles_within(count: u64, why: impl FnOnce() -> String) -> Result<(), ClothError> {
    let bound = crate::limits::MAX_PARTICLES as u64;
    if count <= bound {
        Ok(())
    } else {
        Err(ClothError::TooMany {
            field: "particles",
            count,
            bound,
            why: format!("MAX_PARTICLES; {}", why()),
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

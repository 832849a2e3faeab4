//! What the fuzzer knows about its world: the app, the cloths it spawned with the components it
//! gave them, the mesh assets with what they hold, and the other entities it may edit; and from
//! that, whether each cloth's components are valid together. It also builds the meshes it uses.

use bevy::app::App;
use bevy::asset::{Assets, Handle, RenderAssetUsages};
use bevy::ecs::prelude::*;
use bevy::mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues};

use crate::components::{ClothState, MAX_CLOTH_SUBDIVISION_LEVEL};
use crate::harness::character::Cape;

/// The fixed step of the fuzzer's app, s.
pub(super) const DT: f32 = 1.0 / 60.0;

/// Whether a cloth's components are valid together, as far as the fuzzer can tell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Validity {
    /// Every component is valid: the cloth must run, without any rejection.
    Valid,
    /// An input the plugin may accept or reject (both are right): only what holds either way is
    /// checked.
    Unknown,
    /// A component is invalid: the cloth must be reported.
    Invalid,
}

impl Validity {
    /// Both together: the worse of the two.
    pub(super) fn and(self, other: Self) -> Self {
        self.max(other)
    }
}

/// The kinds of cloth the fuzzer spawns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ClothKind {
    Grid,
    Mesh,
    Character,
}

/// A mesh asset the fuzzer made, and what its current contents hold.
#[derive(Debug, Clone)]
pub(super) struct MeshAsset {
    pub(super) handle: Handle<Mesh>,
    /// Vertex positions.
    pub(super) vertices: usize,
    /// Whether a cloth can be made of it.
    pub(super) validity: Validity,
    /// Whether it has `COLOR_0` (for weights from vertex colours).
    pub(super) colors: bool,
    /// Whether it has joint indices and weights (for a skin).
    pub(super) joints: bool,
    /// What it is, for traces.
    pub(super) label: String,
    /// Its shape, to build another of the same topology.
    pub(super) shape: Shape,
}

/// The shape of a mesh the fuzzer built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Shape {
    /// [`sheet`] of `nx` × `ny`, with colours or not.
    Sheet { nx: u32, ny: u32, colors: bool },
    /// [`cape`] of `nx` × `ny`.
    Cape { nx: u32, ny: u32 },
}

/// A cloth's source as the fuzzer gave it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Source {
    /// A grid; `ok` is false for a spec that cannot be built.
    Grid { nx: u32, ny: u32, ok: bool },
    /// A mesh asset, by index into [`Fixture::meshes`].
    Mesh(usize),
}

/// What a pin is anchored to, as far as validity goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Anchor {
    /// Rest, a finite world point, or an entity with a finite offset (live or not).
    Finite,
    /// A non-finite world point: invalid.
    NanWorld,
    /// An entity with a non-finite offset: the plugin may reject it or hold the pin still.
    NanOffset,
}

/// A cloth's targets as the fuzzer gave them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Targets {
    /// Weights listed: how many, and whether one is NaN.
    Values { len: usize, nan: bool },
    /// Weights from `COLOR_0`.
    Color,
}

/// A cloth the fuzzer spawned (and has not despawned), with the components it gave it.
#[derive(Debug, Clone)]
pub(super) struct TrackedCloth {
    pub(super) entity: Entity,
    pub(super) kind: ClothKind,
    pub(super) source: Source,
    /// Whether its `ClothConfig` is valid.
    pub(super) config_ok: bool,
    pub(super) pins: Vec<(u32, Anchor)>,
    pub(super) targets: Option<Targets>,
    /// Level and whether the simulation (not only the render mesh) is refined.
    pub(super) subdivision: Option<(u32, bool)>,
    /// Whether it has a skin (a character's root and spine joints).
    pub(super) skin: bool,
    /// Whether an edit of its topology (a new source, a swapped source mesh, simulation
    /// subdivision) may not have been built yet: one that was rejected or may have been waits
    /// for the cloth to become valid, and then rebuilds it from rest.
    pub(super) topology_pending: bool,
}

impl TrackedCloth {
    /// The particles of its unrefined source (what pins and weights index), if it can be built.
    pub(super) fn particles(&self, meshes: &[MeshAsset]) -> Option<usize> {
        match self.source {
            Source::Grid { nx, ny, ok } => ok.then_some((nx * ny) as usize),
            Source::Mesh(i) => {
                (meshes[i].validity != Validity::Invalid).then_some(meshes[i].vertices)
            }
        }
    }

    /// Whether its components are valid together.
    pub(super) fn validity(&self, meshes: &[MeshAsset]) -> Validity {
        let Some(count) = self.particles(meshes) else {
            return Validity::Invalid;
        };
        let mesh = match self.source {
            Source::Mesh(i) => Some(&meshes[i]),
            Source::Grid { .. } => None,
        };
        let mut v = mesh.map_or(Validity::Valid, |m| m.validity);
        if !self.config_ok {
            return Validity::Invalid;
        }
        for &(particle, anchor) in &self.pins {
            v = v.and(match anchor {
                _ if particle as usize >= count => Validity::Invalid,
                Anchor::Finite => Validity::Valid,
                Anchor::NanWorld => Validity::Invalid,
                Anchor::NanOffset => Validity::Unknown,
            });
        }
        if let Some((level, simulated)) = self.subdivision
            && (level > MAX_CLOTH_SUBDIVISION_LEVEL
                || simulated && level > 0 && self.targets.is_some())
        {
            return Validity::Invalid;
        }
        if let Some(targets) = self.targets {
            let weights_ok = match targets {
                Targets::Values { len, nan } => len == count && !nan,
                Targets::Color => mesh.is_some_and(|m| m.colors),
            };
            let skin_ok = !self.skin || mesh.is_some_and(|m| m.joints);
            if !(weights_ok && skin_ok) {
                return Validity::Invalid;
            }
        }
        v
    }
}

/// The app of one sequence and everything the fuzzer placed in it.
pub(super) struct Fixture {
    pub(super) app: App,
    /// Whether it has avian's physics.
    pub(super) avian: bool,
    /// Whether invalid cloth components and meshes are drawn too.
    pub(super) invalid: bool,
    pub(super) cloths: Vec<TrackedCloth>,
    pub(super) meshes: Vec<MeshAsset>,
    /// Entities pins may be anchored to (some may have been despawned).
    pub(super) anchors: Vec<Entity>,
    /// Characters' joints (root, spine), some perhaps despawned.
    pub(super) joints: Vec<(Entity, Entity)>,
    pub(super) colliders: Vec<Entity>,
    pub(super) zones: Vec<Entity>,
    /// avian bodies (none without the `avian` feature).
    #[cfg_attr(not(feature = "avian"), allow(dead_code))]
    pub(super) bodies: Vec<Entity>,
    /// Time of the characters' walk, s.
    pub(super) walk: f32,
}

impl Fixture {
    /// A fresh headless app (with avian's physics when `avian`) and no cloths yet;
    /// `invalid`: whether operations may draw invalid cloth components and meshes.
    pub(super) fn empty(avian: bool, invalid: bool) -> Self {
        let mut app = new_app(avian);
        crate::harness::use_single_threaded_frame(&mut app);
        Self {
            app,
            avian,
            invalid,
            cloths: Vec::new(),
            meshes: Vec::new(),
            anchors: Vec::new(),
            joints: Vec::new(),
            colliders: Vec::new(),
            zones: Vec::new(),
            bodies: Vec::new(),
            walk: 0.0,
        }
    }

    /// A line on every cloth: steps, or why it is not running.
    pub(super) fn describe(&self) -> String {
        let world = self.app.world();
        let mut parts = Vec::new();
        for c in &self.cloths {
            let e = world.entity(c.entity);
            let state = e
                .get::<ClothState>()
                .map(|s| format!("{} steps", s.steps()));
            let invalid = e
                .get::<crate::ClothInvalid>()
                .map(|i| format!("invalid: {}", i.0));
            let rejected = e
                .get::<crate::ClothEditRejected>()
                .map(|r| format!("rejected: {}", r.0));
            let status: Vec<String> = [state, invalid, rejected].into_iter().flatten().collect();
            parts.push(format!(
                "{} {:?} {:?} [{}]",
                c.entity,
                c.kind,
                c.validity(&self.meshes),
                status.join("; ")
            ));
        }
        parts.join(", ")
    }

    /// Adds a mesh asset and returns its index.
    pub(super) fn add_mesh(&mut self, built: BuiltMesh) -> usize {
        let handle = self
            .app
            .world_mut()
            .resource_mut::<Assets<Mesh>>()
            .add(built.mesh);
        self.meshes.push(MeshAsset {
            handle,
            vertices: built.vertices,
            validity: built.validity,
            colors: built.colors,
            joints: built.joints,
            label: built.label,
            shape: built.shape,
        });
        self.meshes.len() - 1
    }

    /// Replaces the contents of mesh asset `index` (same handle).
    pub(super) fn swap_mesh(&mut self, index: usize, built: BuiltMesh) {
        let id = self.meshes[index].handle.id();
        // The handle is alive (the fuzzer holds it), so the id is current.
        let _ = self
            .app
            .world_mut()
            .resource_mut::<Assets<Mesh>>()
            .insert(id, built.mesh);
        let asset = &mut self.meshes[index];
        asset.vertices = built.vertices;
        asset.validity = built.validity;
        asset.colors = built.colors;
        asset.joints = built.joints;
        asset.label = built.label;
        asset.shape = built.shape;
    }
}

#[cfg(feature = "avian")]
fn new_app(avian: bool) -> App {
    if avian {
        crate::harness::try_headless_app_with(
            DT,
            (
                avian3d::prelude::PhysicsPlugins::default(),
                crate::avian::ClothAvianPlugin,
            ),
        )
        .unwrap_or_else(|e| panic!("the fuzzer's step is valid: {e}"))
    } else {
        crate::harness::headless_app(DT)
    }
}

#[cfg(not(feature = "avian"))]
fn new_app(_avian: bool) -> App {
    crate::harness::headless_app(DT)
}

/// A mesh the fuzzer built, with what it holds.
pub(super) struct BuiltMesh {
    pub(super) mesh: Mesh,
    pub(super) vertices: usize,
    pub(super) validity: Validity,
    pub(super) colors: bool,
    pub(super) joints: bool,
    pub(super) label: String,
    pub(super) shape: Shape,
}

/// A sheet of `nx` × `ny` vertices, `spacing` apart in the XZ plane with a gentle wave of
/// `height`, as a triangle list with normals and UVs (and `COLOR_0` when `colors`).
pub(super) fn sheet(nx: u32, ny: u32, spacing: f32, height: f32, colors: bool) -> BuiltMesh {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (x, z) = (i as f32 * spacing, j as f32 * spacing);
            positions.push([x, height * (x * 7.0).sin() * (z * 5.0).cos(), z]);
            uvs.push([i as f32 / (nx - 1) as f32, j as f32 / (ny - 1) as f32]);
        }
    }
    let n = positions.len();
    let mut indices = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = j * nx + i;
            let (b, c, d) = (a + 1, a + nx, a + nx + 1);
            indices.extend([a, c, b, b, c, d]);
        }
    }
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n])
    .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
    .with_inserted_indices(Indices::U32(indices));
    if colors {
        let colors: Vec<[f32; 4]> = (0..n)
            .map(|k| [(k / nx as usize) as f32 / (ny - 1) as f32, 0.5, 0.0, 1.0])
            .collect();
        mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, colors);
    }
    BuiltMesh {
        mesh,
        vertices: n,
        validity: Validity::Valid,
        colors,
        joints: false,
        label: format!(
            "sheet {nx}×{ny}{}",
            if colors { " with colours" } else { "" }
        ),
        shape: Shape::Sheet { nx, ny, colors },
    }
}

/// The cape of [`Cape::new`] (joints, weights, colours), its hem pushed back by `lift` m.
pub(super) fn cape(nx: u32, ny: u32, lift: f32) -> (BuiltMesh, Cape) {
    let mut cape = Cape::new(nx as usize, ny as usize);
    if let Some(VertexAttributeValues::Float32x3(p)) =
        cape.mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
    {
        for (k, p) in p.iter_mut().enumerate() {
            p[2] -= lift * (k / nx as usize) as f32 / ny as f32;
        }
    }
    let built = BuiltMesh {
        mesh: cape.mesh.clone(),
        vertices: (nx * ny) as usize,
        validity: Validity::Valid,
        colors: true,
        joints: true,
        label: format!("cape {nx}×{ny}"),
        shape: Shape::Cape { nx, ny },
    };
    (built, cape)
}

/// The ways the fuzzer breaks a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Breakage {
    /// A normal attribute one shorter than the positions.
    ShortNormals,
    /// A UV attribute one shorter than the positions.
    ShortUvs,
    /// An index past the last vertex.
    IndexOutOfRange,
    /// A triangle that uses a vertex twice.
    Degenerate,
}

impl Breakage {
    pub(super) const ALL: [Breakage; 4] = [
        Breakage::ShortNormals,
        Breakage::ShortUvs,
        Breakage::IndexOutOfRange,
        Breakage::Degenerate,
    ];

    /// The operation kind of a swap to a mesh broken this way.
    pub(super) fn kind(self) -> &'static str {
        match self {
            Breakage::ShortNormals => "mesh swap: short normals",
            Breakage::ShortUvs => "mesh swap: short UVs",
            Breakage::IndexOutOfRange => "mesh swap: index out of range",
            Breakage::Degenerate => "mesh swap: degenerate triangle",
        }
    }

    /// `built` broken this way. A short normal attribute is something the plugin may reject or
    /// repair (it makes its own normals); the others cannot make a cloth.
    pub(super) fn apply(self, mut built: BuiltMesh) -> BuiltMesh {
        let n = built.vertices;
        let mesh = &mut built.mesh;
        match self {
            Breakage::ShortNormals => {
                mesh.insert_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n - 1]);
                built.validity = Validity::Unknown;
            }
            Breakage::ShortUvs => {
                mesh.insert_attribute(Mesh::ATTRIBUTE_UV_0, vec![[0.5f32, 0.5]; n - 1]);
                built.validity = Validity::Invalid;
            }
            Breakage::IndexOutOfRange | Breakage::Degenerate => {
                if let Some(Indices::U32(indices)) = mesh.indices_mut() {
                    let last = indices.len() - 1;
                    if self == Breakage::IndexOutOfRange {
                        indices[last] = n as u32 + 5;
                    } else {
                        indices[last] = indices[last - 1];
                    }
                }
                built.validity = Validity::Invalid;
            }
        }
        built.label = format!("{} ({self:?})", built.label);
        built
    }
}

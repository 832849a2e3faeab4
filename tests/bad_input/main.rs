//! Bad input everywhere it enters the crate: solver settings, grid specs, meshes (for the
//! simulation and for subdivision), OBJ text, RON scenes, colliders, wind and pins. Each class of
//! bad input gets a typed error whose message names the field or problem and where it is; in the
//! ECS a bad cloth is reported once and skipped while the others keep running. Headless.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_cloth::ClothError;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::ClothScene;
use bevy_cloth::sim::{
    ClothModel, ClothSim, Collider, Environment, MAX_ITERATIONS, MAX_PARTICLES, MAX_SUBSTEPS,
    PlacedWindZone, Pose, ScopedThread, SpringKind, WindField,
};
use bevy_cloth::subdivision::{
    BoundaryMode, PolyMesh, Subdivider, SubdivisionError, VertexRule, parse_obj,
};
use glam::{Affine3A, DVec3};

#[path = "../common/mod.rs"]
mod common;
use common::*;

mod colliders_wind;
mod ecs;
mod edits;
mod meshes;
mod settings;
mod text;

/// Asserts that `result` failed and that its message contains every one of `words`; returns the
/// error for further checks.
#[track_caller]
fn err_naming<T: std::fmt::Debug, E: std::fmt::Display>(result: Result<T, E>, words: &[&str]) -> E {
    let e = result.expect_err("bad input must be an error");
    let message = e.to_string();
    for w in words {
        assert!(message.contains(w), "{message:?} does not name {w:?}");
    }
    e
}

/// Asserts an `InvalidValue` error for `field`.
#[track_caller]
fn invalid_value(result: Result<(), ClothError>, field: &str) {
    let e = err_naming(result, &[field]);
    assert!(
        matches!(e.innermost(), ClothError::InvalidValue { field: f, .. } if *f == field),
        "{e:?}"
    );
}

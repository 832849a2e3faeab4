//! Solver settings and grid specs: every bad field named.

use super::*;

// ---------------------------------------------------------------------------------------------
// ClothConfig / SolverSettings
// ---------------------------------------------------------------------------------------------

/// Sets one field of the settings.
type Setter<T> = fn(&mut SolverSettings, T);

/// Every float field of the solver settings, with a setter.
fn float_fields() -> Vec<(&'static str, Setter<f32>)> {
    vec![
        ("stiffness.structural", |s, v| s.stiffness.structural = v),
        ("stiffness.shear", |s, v| s.stiffness.shear = v),
        ("stiffness.bend", |s, v| s.stiffness.bend = v),
        ("particle_mass", |s, v| s.particle_mass = v),
        ("damping", |s, v| s.damping = v),
        ("drag_coefficient", |s, v| s.drag_coefficient = v),
        ("lift_coefficient", |s, v| s.lift_coefficient = v),
        ("gravity.x", |s, v| s.gravity.x = v),
        ("gravity.y", |s, v| s.gravity.y = v),
        ("gravity.z", |s, v| s.gravity.z = v),
        ("accuracy.tolerance", |s, v| s.accuracy.tolerance = Some(v)),
    ]
}

#[test]
fn solver_settings_reject_nan_infinite_negative_and_zero_where_meaningless() {
    for (field, set) in float_fields() {
        let gravity = field.starts_with("gravity");
        for value in [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -1.0,
            -0.0,
            0.0,
            1.0,
        ] {
            let mut s = SolverSettings::default();
            set(&mut s, value);
            // What is legal: any finite gravity; zero stiffness, damping and aerodynamic
            // coefficients (the term is switched off); a mass and a tolerance must be positive.
            let legal = value.is_finite()
                && (gravity || value >= 0.0)
                && !(matches!(field, "particle_mass" | "accuracy.tolerance") && value <= 0.0);
            match s.validate() {
                Ok(()) => assert!(legal, "{field} = {value} was accepted"),
                Err(e) => {
                    assert!(!legal, "{field} = {value} was rejected: {e}");
                    assert!(
                        matches!(e, ClothError::InvalidValue { field: f, .. } if f == field),
                        "{field} = {value}: {e:?}"
                    );
                    let message = e.to_string();
                    assert!(message.contains(field), "{message}");
                    if !value.is_nan() {
                        assert!(message.contains(&value.to_string()), "{message}");
                    }
                }
            }
        }
    }
}

#[test]
fn solver_counts_out_of_range_name_the_field_and_bounds() {
    let cases: [(&str, u32, Setter<u32>); 6] = [
        ("substeps", 0, |s, v| s.substeps = v),
        ("substeps", MAX_SUBSTEPS + 1, |s, v| s.substeps = v),
        ("iterations", 0, |s, v| s.iterations = v),
        ("iterations", MAX_ITERATIONS + 1, |s, v| s.iterations = v),
        ("accuracy.max_substeps", 1, |s, v| {
            s.accuracy.max_substeps = v
        }),
        ("accuracy.max_substeps", MAX_SUBSTEPS + 1, |s, v| {
            s.accuracy.max_substeps = v
        }),
    ];
    for (field, value, set) in cases {
        let mut s = SolverSettings::default();
        set(&mut s, value);
        let e = err_naming(s.validate(), &[field, &value.to_string()]);
        assert!(
            matches!(e, ClothError::CountOutOfRange { field: f, value: v, .. } if f == field && v == value),
            "{e:?}"
        );
    }
    // The bounds themselves are fine.
    let s = SolverSettings {
        substeps: MAX_SUBSTEPS,
        iterations: MAX_ITERATIONS,
        ..Default::default()
    };
    assert!(s.validate().is_ok());
}

#[test]
fn a_rejected_settings_edit_leaves_the_simulation_as_it_was() {
    let model = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
    let mut sim = ClothSim::new(model.clone(), SolverSettings::default(), |p| p).unwrap();
    let bad = SolverSettings {
        particle_mass: f32::NAN,
        ..Default::default()
    };
    err_naming(sim.set_settings(bad), &["particle_mass"]);
    assert_eq!(sim.settings(), &SolverSettings::default());
    err_naming(ClothSim::new(model, bad, |p| p), &["particle_mass"]);
}

#[test]
fn a_velocity_that_is_not_finite_is_refused_and_changes_nothing() {
    let model = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
    let mut sim = ClothSim::new(model, SolverSettings::default(), |p| p).unwrap();
    for bad in [
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
        Vec3::new(0.0, 0.0, f32::NEG_INFINITY),
    ] {
        invalid_value(sim.set_velocities(bad), "velocity");
        assert!(sim.velocities().iter().all(|v| *v == Vec3::ZERO));
    }
    sim.set_velocities(Vec3::X).unwrap();
    assert!(sim.velocities().iter().all(|v| *v == Vec3::X));
}

// ---------------------------------------------------------------------------------------------
// Grid specs
// ---------------------------------------------------------------------------------------------

#[test]
fn grid_specs_name_the_bad_field() {
    for (nx, ny, field) in [(0, 4, "nx"), (1, 4, "nx"), (4, 0, "ny"), (4, 1, "ny")] {
        let e = err_naming(ClothModel::grid(&GridSpec::new(nx, ny, 0.1)), &[field]);
        assert!(matches!(e, ClothError::GridTooSmall { field: f, .. } if f == field));
    }
    for (nx, ny) in [(u32::MAX, u32::MAX), (4097, 4096), (u32::MAX, 2)] {
        let e = err_naming(
            ClothModel::grid(&GridSpec::new(nx, ny, 0.1)),
            &[&nx.to_string(), &MAX_PARTICLES.to_string()],
        );
        assert_eq!(e, ClothError::GridTooLarge { nx, ny });
    }
    assert!(GridSpec::new(1024, 1024, 0.1).validate().is_ok());
    for h in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.1, 0.0, -0.0] {
        invalid_value(GridSpec::new(4, 4, h).validate(), "spacing");
    }
    // Finite, but the grid's springs would be longer than f32 can measure.
    let e = err_naming(
        ClothModel::grid(&GridSpec::new(4, 4, 1e20)),
        &["spacing", "diagonal"],
    );
    assert!(matches!(
        e,
        ClothError::InvalidValue {
            field: "spacing",
            ..
        }
    ));
    // Large but measurable: every spring has a finite, positive rest length.
    let m = ClothModel::grid(&GridSpec::new(4, 4, 1e15)).unwrap();
    assert!(m.springs.rest.iter().all(|r| r.is_finite() && *r > 0.0));
}

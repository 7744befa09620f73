//! Tests of the muscle models: loading, closed forms, equilibrium, reference models, timing.

use super::*;
use crate::model::{ForceElement, Model, RawElement};
use std::hint::black_box;
use std::time::Instant;

fn leaf(tag: &str, text: &str) -> RawElement {
    RawElement {
        tag: tag.to_string(),
        name: None,
        text: text.to_string(),
        line: 1,
        children: vec![],
    }
}

/// A force element of class `kind` with number/boolean children and nested objects.
fn element(kind: &str, props: &[(&str, &str)], objects: Vec<RawElement>) -> ForceElement {
    let mut children: Vec<RawElement> = props.iter().map(|(t, v)| leaf(t, v)).collect();
    children.extend(objects);
    ForceElement {
        applies_force: true,
        actuator: None,
        name: "test_muscle".to_string(),
        kind: kind.to_string(),
        path: None,
        raw: std::sync::Arc::new(RawElement {
            tag: kind.to_string(),
            name: Some("test_muscle".to_string()),
            text: String::new(),
            line: 7,
            children,
        }),
        line: 7,
        file: "test.osim".into(),
    }
}

fn object(tag: &str, props: &[(&str, &str)]) -> RawElement {
    RawElement {
        tag: tag.to_string(),
        name: Some(format!("x_{tag}")),
        text: String::new(),
        line: 2,
        children: props.iter().map(|(t, v)| leaf(t, v)).collect(),
    }
}

const COMMON: [(&str, &str); 5] = [
    ("max_isometric_force", "800"),
    ("optimal_fiber_length", "0.12"),
    ("tendon_slack_length", "0.25"),
    ("pennation_angle_at_optimal", "0.3"),
    ("max_contraction_velocity", "10"),
];

fn with_common<'a>(extra: &[(&'a str, &'a str)]) -> Vec<(&'a str, &'a str)> {
    let mut v: Vec<(&str, &str)> = COMMON.to_vec();
    v.extend_from_slice(extra);
    v
}

fn thelen(extra: &[(&str, &str)]) -> HillMuscle {
    HillMuscle::from_force_element(&element("Thelen2003Muscle", &with_common(extra), vec![]))
        .unwrap()
}

fn millard(extra: &[(&str, &str)], tendon: &[(&str, &str)]) -> HillMuscle {
    HillMuscle::from_force_element(&element(
        "Millard2012EquilibriumMuscle",
        &with_common(extra),
        vec![object("TendonForceLengthCurve", tendon)],
    ))
    .unwrap()
}

fn degroote(extra: &[(&str, &str)]) -> HillMuscle {
    HillMuscle::from_force_element(&element(
        "DeGrooteFregly2016Muscle",
        &with_common(extra),
        vec![],
    ))
    .unwrap()
}

/// One muscle of each kind and tendon mode.
fn zoo() -> Vec<(&'static str, HillMuscle)> {
    vec![
        ("thelen", thelen(&[])),
        ("millard damped", millard(&[], &[])),
        ("millard undamped", millard(&[("fiber_damping", "0")], &[])),
        ("degroote", degroote(&[])),
        ("degroote damped", degroote(&[("fiber_damping", "0.05")])),
    ]
}

/// ℓ_MT at which the fiber would be at l̃ with the tendon at slack.
fn l_mt_at(m: &HillMuscle, norm_fiber_length: f64) -> f64 {
    let p = m.params();
    let l = norm_fiber_length * p.optimal_fiber_length;
    let h = p.optimal_fiber_length * p.pennation_angle_at_optimal.sin();
    (l * l - h * h).sqrt() + p.tendon_slack_length
}

fn reference_muscles(relative: &str) -> Option<Vec<ForceElement>> {
    match crate::reference::file(relative) {
        Some(path) => {
            let model = Model::from_osim_file(&path)
                .unwrap_or_else(|e| panic!("{relative} does not load: {e}"));
            Some(model.forces.into_iter().filter(|f| f.is_muscle()).collect())
        }
        None if crate::reference::required() => {
            panic!("reference file {relative} not found and MUSCULO_REQUIRE_REFERENCE is set")
        }
        None => {
            eprintln!("skipped: reference data not found ({relative})");
            None
        }
    }
}

#[test]
fn every_muscle_of_the_reference_models_loads() {
    let cases = [
        (
            "opensim-models/Models/Arm26/arm26.osim",
            MuscleKind::Thelen2003,
            6,
        ),
        (
            "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
            MuscleKind::Thelen2003,
            92,
        ),
        (
            "opensim-models/Models/Gait2392_Simbody/gait2392_millard2012muscle.osim",
            MuscleKind::Millard2012Equilibrium,
            92,
        ),
        (
            "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
            MuscleKind::Millard2012Equilibrium,
            80,
        ),
    ];
    for (file, kind, count) in cases {
        let Some(muscles) = reference_muscles(file) else {
            return;
        };
        assert_eq!(muscles.len(), count, "{file}");
        for fe in &muscles {
            let m = HillMuscle::from_force_element(fe).unwrap_or_else(|e| panic!("{file}: {e}"));
            assert_eq!(m.kind(), kind);
            assert_eq!(m.name(), fe.name);
            assert_eq!(
                m.params().max_isometric_force,
                fe.raw.number("max_isometric_force").unwrap()
            );
        }
        if file.ends_with("arm26.osim") {
            // TRIlong as written in the file, and Thelen's defaults where it is silent.
            let fe = muscles.iter().find(|f| f.name == "TRIlong").unwrap();
            let m = HillMuscle::from_force_element(fe).unwrap();
            let p = m.params();
            assert_eq!(p.max_isometric_force, 798.52);
            assert_eq!(p.optimal_fiber_length, 0.134);
            assert_eq!(p.tendon_slack_length, 0.143);
            assert_eq!(p.pennation_angle_at_optimal, 0.20943951);
            assert_eq!(p.activation_time_constant, 0.01);
            assert_eq!(p.minimum_activation, 0.01);
            assert!((p.maximum_pennation_angle - 0.1f64.acos()).abs() < 1e-15);
            let HillCurves::Thelen2003(c) = m.curves() else {
                panic!()
            };
            assert_eq!(
                (c.kshape_active, c.kshape_passive, c.af, c.flen),
                (0.5, 4.0, 0.3, 1.8)
            );
            assert_eq!(c.fmax_tendon_strain, 0.033);
            assert_eq!(c.fv_linear_extrap_threshold, 0.95);
        }
        if file.ends_with("Rajagopal2016.osim") {
            let fe = muscles.iter().find(|f| f.name == "addbrev_r").unwrap();
            let m = HillMuscle::from_force_element(fe).unwrap();
            assert!(m.params().ignore_tendon_compliance);
            assert_eq!(m.params().fiber_damping, 0.1);
            let HillCurves::Millard2012(c) = m.curves() else {
                panic!()
            };
            assert_eq!(
                c.active_force_length_params.min_norm_active_fiber_length,
                0.25
            );
            assert_eq!(c.active_force_length_params.minimum_value, 0.0);
            assert_eq!(c.tendon_force_length_params.strain_at_one_norm_force, 0.049);
            // Minimum fiber length: the active curve's lower end dominates here.
            assert!((m.params().minimum_fiber_length - 0.25 * 0.1031).abs() < 1e-15);
        }
    }
}

/// Every reference muscle reaches equilibrium across lengths, activations and speeds, and the
/// state satisfies the force balance.
#[test]
fn reference_muscles_reach_equilibrium_over_their_working_range() {
    let files = [
        "opensim-models/Models/Arm26/arm26.osim",
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Gait2392_Simbody/gait2392_millard2012muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ];
    let mut solves = 0;
    for file in files {
        let Some(muscles) = reference_muscles(file) else {
            return;
        };
        for fe in &muscles {
            let m = HillMuscle::from_force_element(fe).unwrap();
            let f_max = m.params().max_isometric_force;
            let v_scale = m.max_fiber_velocity();
            for l in [0.6, 0.9, 1.0, 1.2, 1.5] {
                // Tendon stretched a little beyond slack: the musculotendon is taut.
                let l_mt = l_mt_at(&m, l) + 0.02 * m.params().tendon_slack_length;
                for a in [0.01, 0.3, 1.0] {
                    for v in [-0.5, -0.05, 0.0, 0.05, 0.5] {
                        let s = m.state_equilibrium(a, l_mt, v * v_scale, &Default::default());
                        assert!(
                            matches!(s.status, MuscleStatus::Ok | MuscleStatus::FiberAtLowerBound),
                            "{} l̃ {l} a {a} v {v}: {:?}",
                            m.name(),
                            s.status
                        );
                        if s.status == MuscleStatus::Ok {
                            assert!(
                                s.equilibrium_residual().abs() <= 1e-9 * f_max,
                                "{} residual {}",
                                m.name(),
                                s.equilibrium_residual()
                            );
                            solves += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(solves > 10_000, "{solves}");
}

#[test]
fn invalid_parameters_are_errors_naming_the_property() {
    let cases: Vec<(ForceElement, &str)> = vec![
        (
            element("Thelen2003Muscle", &[("optimal_fiber_length", "0")], vec![]),
            "optimal_fiber_length",
        ),
        (
            element(
                "Millard2012EquilibriumMuscle",
                &[("optimal_fiber_length", "0")],
                vec![],
            ),
            "optimal_fiber_length",
        ),
        (
            element(
                "DeGrooteFregly2016Muscle",
                &[("optimal_fiber_length", "-0.1")],
                vec![],
            ),
            "optimal_fiber_length",
        ),
        (
            element("Thelen2003Muscle", &[("tendon_slack_length", "0")], vec![]),
            "tendon_slack_length",
        ),
        (
            element("Thelen2003Muscle", &[("Flen", "1.0")], vec![]),
            "Flen",
        ),
        (
            element("Thelen2003Muscle", &[("KshapeActive", "abc")], vec![]),
            "KshapeActive",
        ),
        (
            element("Thelen2003Muscle", &[("minimum_activation", "0")], vec![]),
            "minimum_activation",
        ),
        (
            element(
                "Thelen2003Muscle",
                &[("pennation_angle_at_optimal", "1.6")],
                vec![],
            ),
            "pennation_angle_at_optimal",
        ),
        (
            element(
                "Millard2012EquilibriumMuscle",
                &[("fiber_damping", "-1")],
                vec![],
            ),
            "fiber_damping",
        ),
        (
            element(
                "Millard2012EquilibriumMuscle",
                &[],
                vec![object("TendonForceLengthCurve", &[("curviness", "0.5")])],
            ),
            "all set or all absent",
        ),
        (
            element(
                "Millard2012EquilibriumMuscle",
                &[],
                vec![object("ForceVelocityCurve", &[("isometric_slope", "0.5")])],
            ),
            "isometric_slope",
        ),
        (
            element(
                "DeGrooteFregly2016Muscle",
                &[("active_force_width_scale", "0.5")],
                vec![],
            ),
            "active_force_width_scale",
        ),
        (
            element(
                "DeGrooteFregly2016Muscle",
                &[("ignore_passive_fiber_force", "maybe")],
                vec![],
            ),
            "ignore_passive_fiber_force",
        ),
        (
            element("RigidTendonMuscle", &[], vec![]),
            "not a Hill-type muscle",
        ),
    ];
    for (fe, needle) in cases {
        let err = HillMuscle::from_force_element(&fe).unwrap_err();
        assert!(err.contains(needle), "`{err}` should mention `{needle}`");
        assert!(
            err.contains("test_muscle"),
            "`{err}` should name the muscle"
        );
    }
}

#[test]
fn absent_properties_take_opensim_defaults() {
    let t = HillMuscle::from_force_element(&element("Thelen2003Muscle", &[], vec![])).unwrap();
    let p = t.params();
    assert_eq!(
        (
            p.max_isometric_force,
            p.optimal_fiber_length,
            p.tendon_slack_length
        ),
        (1000.0, 0.1, 0.2)
    );
    assert_eq!(
        (p.max_contraction_velocity, p.pennation_angle_at_optimal),
        (10.0, 0.0)
    );
    assert_eq!(
        (p.activation_time_constant, p.deactivation_time_constant),
        (0.015, 0.05)
    );
    assert_eq!((p.minimum_activation, p.fiber_damping), (0.01, 0.0));
    assert!(!p.ignore_tendon_compliance);
    assert_eq!(
        *match t.curves() {
            HillCurves::Thelen2003(c) => c,
            _ => panic!(),
        },
        Thelen2003Curves::default()
    );

    let m = HillMuscle::from_force_element(&element("Millard2012EquilibriumMuscle", &[], vec![]))
        .unwrap();
    let p = m.params();
    assert_eq!(
        (p.activation_time_constant, p.deactivation_time_constant),
        (0.01, 0.04)
    );
    assert_eq!((p.fiber_damping, p.minimum_activation), (0.1, 0.01));
    // Damped model: the active curve's floor and the force–velocity end slopes go to 0.
    let HillCurves::Millard2012(c) = m.curves() else {
        panic!()
    };
    assert_eq!(c.active_force_length_params.minimum_value, 0.0);
    assert_eq!(c.force_velocity_params.concentric_slope_at_vmax, 0.0);
    assert_eq!(
        c.tendon_force_length_params.stiffness_at_one_norm_force,
        1.375 / 0.049
    );
    assert_eq!(
        c.fiber_force_length_params.stiffness_at_one_norm_force,
        2.0 / 0.7
    );
    assert!((p.minimum_fiber_length - 0.1 * (0.47 - 0.0259)).abs() < 1e-16);

    // Undamped elastic tendon: the classic model raises the floor to 0.1.
    let u = HillMuscle::from_force_element(&element(
        "Millard2012EquilibriumMuscle",
        &[("fiber_damping", "0.0005")],
        vec![object("ActiveForceLengthCurve", &[("minimum_value", "0")])],
    ))
    .unwrap();
    assert_eq!(u.params().fiber_damping, 0.0);
    let HillCurves::Millard2012(c) = u.curves() else {
        panic!()
    };
    assert_eq!(c.active_force_length_params.minimum_value, 0.1);
    assert_eq!(c.force_velocity_params.concentric_slope_at_vmax, 0.125);

    let d =
        HillMuscle::from_force_element(&element("DeGrooteFregly2016Muscle", &[], vec![])).unwrap();
    let p = d.params();
    assert_eq!(
        (p.activation_time_constant, p.deactivation_time_constant),
        (0.015, 0.06)
    );
    assert_eq!(
        (
            p.minimum_activation,
            p.fiber_damping,
            p.minimum_fiber_length
        ),
        (0.0, 0.0, 0.0)
    );
    assert_eq!(p.activation_dynamics_smoothing, Some(0.1));
}

/// Thelen's curves written out from the paper, independently of the module's code.
fn thelen_paper_force(a: f64, l_mt: f64, v_mt: f64) -> (f64, f64) {
    let (f_max, l_opt, l_s, alpha0, v_max) = (800.0, 0.12, 0.25, 0.3f64, 10.0);
    let (gamma, k_pe, e0_m, af) = (0.45, 5.0, 0.6, 0.25);
    let h = l_opt * alpha0.sin();
    let l_at = l_mt - l_s;
    let l = (h * h + l_at * l_at).sqrt();
    let cos = l_at / l;
    let ln = l / l_opt;
    let fl = (-(ln - 1.0) * (ln - 1.0) / gamma).exp();
    let fpe = if ln > 1.0 {
        ((k_pe * (ln - 1.0) / e0_m).exp() - 1.0) / (k_pe.exp() - 1.0)
    } else {
        0.0
    };
    // Concentric Hill hyperbola (Thelen Eq. 6 inverted): f_V = (s + ṽ)/(s − ṽ/A_f).
    let v = v_mt * cos / (v_max * l_opt);
    let s = 0.25 + 0.75 * a;
    assert!(v <= 0.0 && v > -s);
    let fv = (s + v) / (s - v / af);
    ((a * fl * fv + fpe) * f_max * cos, l)
}

#[test]
fn rigid_tendon_force_equals_the_closed_form() {
    // Thelen against the paper's formulas.
    let t = thelen(&[]);
    for (a, ln, v) in [
        (1.0, 1.0, 0.0),
        (0.5, 0.8, -0.3),
        (0.2, 1.25, -0.05),
        (1.0, 1.4, -0.9),
    ] {
        let l_mt = l_mt_at(&t, ln);
        let v_mt = v * t.max_fiber_velocity();
        let (expected, l) = thelen_paper_force(a, l_mt, v_mt);
        let s = t.state_rigid_tendon(a, l_mt, v_mt);
        assert_eq!(s.status, MuscleStatus::Ok);
        assert!((s.fiber_length - l).abs() < 1e-15);
        assert!(
            (s.tendon_force - expected).abs() < 1e-10 * 800.0,
            "{} vs {expected}",
            s.tendon_force
        );
        assert_eq!(s.tendon_force, s.fiber_force_along_tendon);
    }
    // Every model against F = (a f_L f_V + f_PE + β ṽ) F_max cos α from its own curves.
    for (name, m) in zoo() {
        let p = *m.params();
        let h = p.optimal_fiber_length * p.pennation_angle_at_optimal.sin();
        for (a, ln, v) in [
            (1.0, 1.0, 0.0),
            (0.6, 0.7, -0.4),
            (0.3, 1.3, 0.6),
            (0.05, 1.1, -0.1),
        ] {
            let l_mt = l_mt_at(&m, ln);
            let v_mt = v * m.max_fiber_velocity();
            let l_at = l_mt - p.tendon_slack_length;
            let l = (h * h + l_at * l_at).sqrt();
            let cos = l_at / l;
            let vn = v_mt * cos / m.max_fiber_velocity();
            let c = m.curves();
            let fiber = a
                * c.active_force_length(l / p.optimal_fiber_length).value
                * c.force_velocity(a, vn).value
                + c.passive_force_length(l / p.optimal_fiber_length).value
                + p.fiber_damping * vn;
            let expected = fiber.max(0.0) * p.max_isometric_force * cos;
            let s = m.state_rigid_tendon(a, l_mt, v_mt);
            assert!(
                (s.tendon_force - expected).abs() < 1e-9 * p.max_isometric_force,
                "{name}: {} vs {expected}",
                s.tendon_force
            );
            assert!((s.normalized_fiber_velocity - vn).abs() < 1e-14);
            assert!((s.fiber_velocity_along_tendon - v_mt).abs() < 1e-14);
        }
        // At optimal length, isometric, full activation: F_max cos α_opt (f_PE(1) = 0 except
        // De Groote–Fregly, whose passive curve is already positive there).
        let s = m.state_rigid_tendon(1.0, l_mt_at(&m, 1.0), 0.0);
        let fpe1 = m.curves().passive_force_length(1.0).value;
        let expected = (m.curves().active_force_length(1.0).value + fpe1)
            * p.max_isometric_force
            * p.pennation_angle_at_optimal.cos();
        assert!(
            (s.tendon_force - expected).abs() < 1e-9 * p.max_isometric_force,
            "{name}"
        );
    }
}

#[test]
fn rigid_tendon_clamps_as_opensim() {
    // Millard: a fiber shorter than its minimum is held with zero force.
    let m = millard(&[("ignore_tendon_compliance", "true")], &[]);
    let s = m.state_rigid_tendon(1.0, m.params().tendon_slack_length + 0.01, -0.5);
    assert_eq!(s.status, MuscleStatus::FiberAtLowerBound);
    assert_eq!(s.tendon_force, 0.0);
    assert_eq!(s.fiber_length, m.params().minimum_fiber_length);
    // Millard: the damping force saturates so that a fast-shortening fiber does not push.
    let l_mt = l_mt_at(&m, 0.9);
    let cos = m.pennation().at(0.9 * m.params().optimal_fiber_length).cos;
    let s = m.state_rigid_tendon(0.05, l_mt, -0.95 / cos * m.max_fiber_velocity());
    assert!((s.normalized_fiber_velocity + 0.95).abs() < 1e-12);
    assert!(s.active_fiber_force > 0.0);
    assert_eq!(s.tendon_force, 0.0);
    assert!(s.damping_fiber_force < 0.0);
    assert!((s.active_fiber_force + s.passive_fiber_force + s.damping_fiber_force).abs() < 1e-9);
    // Activation is clamped to [minimum_activation, 1].
    assert_eq!(m.state_rigid_tendon(-1.0, l_mt, 0.0).activation, 0.01);
    assert_eq!(m.state_rigid_tendon(2.0, l_mt, 0.0).activation, 1.0);
    // De Groote–Fregly does not clamp activation.
    let d = degroote(&[]);
    assert_eq!(
        d.state_rigid_tendon(0.0, l_mt_at(&d, 1.0), 0.0).activation,
        0.0
    );
}

#[test]
fn compliant_equilibrium_balances_fiber_and_tendon_force() {
    for (name, m) in zoo() {
        let f_max = m.params().max_isometric_force;
        for split in [
            None,
            Some(VelocitySplit::Static),
            Some(VelocitySplit::RigidTendonVelocity),
            Some(VelocitySplit::Stiffness),
        ] {
            let settings = EquilibriumSettings {
                velocity_split: split,
                ..Default::default()
            };
            for a in [0.02, 0.5, 1.0] {
                for stretch in [0.005, 0.02, 0.05] {
                    for ln in [0.6, 1.0, 1.3] {
                        let l_mt = l_mt_at(&m, ln) + stretch * m.params().tendon_slack_length;
                        for v in [-0.6, -0.1, 0.0, 0.2, 0.7] {
                            let v_mt = v * m.max_fiber_velocity();
                            let s = m.state_equilibrium(a, l_mt, v_mt, &settings);
                            if s.status == MuscleStatus::NoEquilibrium
                                && m.kind() == MuscleKind::DeGrooteFregly2016
                            {
                                // Damping pushes harder than the weakly active fiber pulls
                                // even with the tendon at slack: no root with f_T ≥ 0 (OpenSim
                                // throws).
                                assert!(m.params().fiber_damping > 0.0 && v < 0.0, "{name}");
                                assert!(s.fiber_force < 0.0 && s.tendon_force.abs() < 1e-9 * f_max);
                                continue;
                            }
                            assert_eq!(s.status, MuscleStatus::Ok, "{name} {split:?} {a} {ln} {v}");
                            assert!(
                                s.equilibrium_residual().abs() <= 1e-9 * f_max,
                                "{name}: residual {}",
                                s.equilibrium_residual()
                            );
                            // Kinematics close: fiber along the tendon plus tendon = path.
                            assert!(
                                (s.fiber_length_along_tendon + s.tendon_length - l_mt).abs()
                                    < 1e-14
                            );
                            assert!(
                                (s.fiber_velocity_along_tendon + s.tendon_velocity - v_mt).abs()
                                    < 1e-12
                            );
                            let split = split.unwrap_or(VelocitySplit::opensim_default(m.kind()));
                            match split {
                                VelocitySplit::Static => assert_eq!(s.fiber_velocity, 0.0),
                                VelocitySplit::RigidTendonVelocity => {
                                    assert!(s.tendon_velocity.abs() < 1e-12)
                                }
                                VelocitySplit::Stiffness => {
                                    // The returned velocity is the split's fixed point.
                                    let again = m.stiffness_split_velocity(
                                        s.activation,
                                        l_mt,
                                        v_mt,
                                        s.fiber_length,
                                        s.normalized_fiber_velocity,
                                    );
                                    // Near a slack tendon (force ≲ 1e-3 F_max) both
                                    // stiffnesses are small and the split is ill-conditioned.
                                    let tol = if s.normalized_tendon_force > 1e-3 {
                                        1e-10
                                    } else {
                                        1e-6
                                    };
                                    assert!(
                                        (again - s.normalized_fiber_velocity).abs() < tol,
                                        "{name}: {again} vs {}",
                                        s.normalized_fiber_velocity
                                    );
                                    // The tendon takes a share in [−1, 1] of the speed (negative
                                    // on the descending limb, where K_M < 0), so the fiber
                                    // moves with ℓ̇_MT, at most twice as fast.
                                    let slack = 1e-6 * v_mt * v_mt;
                                    assert!(s.tendon_velocity.abs() <= v_mt.abs() + slack.sqrt());
                                    assert!(s.fiber_velocity_along_tendon * v_mt >= -slack);
                                    assert!(
                                        s.fiber_velocity_along_tendon.abs()
                                            <= 2.0 * v_mt.abs() + slack.sqrt()
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn stiff_tendon_equilibrium_approaches_the_rigid_tendon_force() {
    let stiff: Vec<(&str, HillMuscle)> = vec![
        ("thelen", thelen(&[("FmaxTendonStrain", "1e-6")])),
        (
            "millard",
            millard(&[], &[("strain_at_one_norm_force", "1e-6")]),
        ),
        (
            "millard undamped",
            millard(
                &[("fiber_damping", "0")],
                &[("strain_at_one_norm_force", "1e-6")],
            ),
        ),
        (
            "degroote",
            degroote(&[("tendon_strain_at_one_norm_force", "1e-6")]),
        ),
    ];
    for (name, m) in stiff {
        let f_max = m.params().max_isometric_force;
        for (a, ln, v) in [
            (1.0, 1.0, 0.0),
            (0.5, 0.8, 0.0),
            (0.7, 1.2, -0.2),
            (0.4, 0.9, 0.3),
        ] {
            // Thelen's minimum activation and Millard's classic floor would make the rigid
            // and compliant curves differ only through the tendon; the test compares the two
            // tendon treatments of one and the same muscle.
            let l_mt = l_mt_at(&m, ln);
            let v_mt = v * m.max_fiber_velocity();
            let rigid = m.state_rigid_tendon(a, l_mt, v_mt);
            let settings = EquilibriumSettings {
                velocity_split: Some(VelocitySplit::Stiffness),
                ..Default::default()
            };
            let elastic = m.state_equilibrium(a, l_mt, v_mt, &settings);
            assert_eq!(elastic.status, MuscleStatus::Ok, "{name}");
            assert!(
                (elastic.tendon_force - rigid.tendon_force).abs() < 2e-4 * f_max,
                "{name} a {a} l̃ {ln} v {v}: elastic {} rigid {}",
                elastic.tendon_force,
                rigid.tendon_force
            );
            assert!((elastic.fiber_length - rigid.fiber_length).abs() < 1e-6);
        }
    }
}

#[test]
fn state_at_fiber_length_recovers_the_equilibrium_velocity() {
    for (name, m) in zoo() {
        for (a, ln, stretch, v) in [
            (0.8, 1.0, 0.03, -0.3),
            (0.3, 0.8, 0.01, 0.4),
            (1.0, 1.2, 0.04, 0.05),
        ] {
            let l_mt = l_mt_at(&m, ln) + stretch * m.params().tendon_slack_length;
            let v_mt = v * m.max_fiber_velocity();
            let eq = m.state_equilibrium(a, l_mt, v_mt, &Default::default());
            assert_eq!(eq.status, MuscleStatus::Ok);
            let s = m.state_at_fiber_length(a, l_mt, v_mt, eq.fiber_length);
            assert_eq!(s.status, MuscleStatus::Ok, "{name}");
            assert_eq!(s.tendon_force, eq.tendon_force);
            assert!(
                (s.normalized_fiber_velocity - eq.normalized_fiber_velocity).abs() < 1e-9,
                "{name}: {} vs {}",
                s.normalized_fiber_velocity,
                eq.normalized_fiber_velocity
            );
            assert!(s.equilibrium_residual().abs() < 1e-9 * m.params().max_isometric_force);
        }
    }
}

/// OpenSim's Thelen initialisation shares ℓ̇_MT as ℓ̇_T = K_M / (K_M + K_T) ℓ̇_MT with
/// K_M = ∂F_AT/∂l · cos α at fixed fiber velocity and K_T = ∂F_T/∂l_T — on the descending
/// limb K_M < 0 and the tendon moves against the musculotendon (OpenSim 4.6 returns such
/// states; musculo clamped the share at 0 and differed by up to 3.5e-4 F_max in
/// muscles_compare.py). Stiffnesses here by central differences of the curves themselves.
#[test]
fn thelen_stiffness_split_keeps_a_negative_share_on_the_descending_limb() {
    let m = thelen(&[]);
    let p = *m.params();
    let h = p.optimal_fiber_length * p.pennation_angle_at_optimal.sin();
    let mut negative = 0;
    for (a, ln, v) in [
        (1.0, 1.3, 0.05),
        (1.0, 1.3, -0.05),
        (0.7, 1.25, 0.1),
        (0.5, 1.2, -0.1),
    ] {
        let l_mt = l_mt_at(&m, ln) + 0.03 * p.tendon_slack_length;
        let v_mt = v * m.max_fiber_velocity();
        let s = m.state_equilibrium(a, l_mt, v_mt, &Default::default());
        assert_eq!(s.status, MuscleStatus::Ok);
        let fiber_along = |l: f64| {
            let x = l / p.optimal_fiber_length;
            let c = m.curves();
            let f = s.activation
                * c.active_force_length(x).value
                * c.force_velocity(s.activation, s.normalized_fiber_velocity)
                    .value
                + c.passive_force_length(x).value;
            f * (1.0 - (h / l).powi(2)).sqrt()
        };
        let d = 1e-7 * p.optimal_fiber_length;
        let l = s.fiber_length;
        let k_m = (fiber_along(l + d) - fiber_along(l - d)) / (2.0 * d) * s.cos_pennation_angle;
        let tendon = |lt: f64| {
            m.curves()
                .tendon_force_length(lt / p.tendon_slack_length)
                .value
        };
        let dt = 1e-7 * p.tendon_slack_length;
        let k_t = (tendon(s.tendon_length + dt) - tendon(s.tendon_length - dt)) / (2.0 * dt);
        let share = k_m / (k_m + k_t);
        if share < 0.0 {
            negative += 1;
        }
        assert!(
            (s.tendon_velocity - share * v_mt).abs() < 1e-6 * v_mt.abs(),
            "a {a} l̃ {ln} v {v}: tendon velocity {} vs share {share} × {v_mt}",
            s.tendon_velocity
        );
    }
    assert!(negative >= 2, "the cases must reach the descending limb");
}

/// At the fiber length of a static equilibrium (fiber at rest, OpenSim Millard's
/// `computeInitialFiberEquilibrium`) the force balance holds at ṽ = 0, and a f_L f_V(ṽ) + β ṽ
/// increases strictly in ṽ: the velocity recovered from that fiber length must be 0, whatever
/// ℓ̇_MT. (Across the kink of Millard's f_V at 0 an unguarded Newton iteration oscillated and
/// returned ṽ ≈ 0.15 after 100 iterations; OpenSim 4.6 returns 0 there — muscles_compare.py.)
#[test]
fn state_at_a_static_equilibrium_fiber_length_has_the_fiber_at_rest() {
    let settings = EquilibriumSettings {
        velocity_split: Some(VelocitySplit::Static),
        ..Default::default()
    };
    for (name, m) in zoo() {
        for a in [0.05, 0.24, 0.6, 1.0] {
            for ln in [0.6, 0.76, 1.0, 1.3] {
                let l_mt = l_mt_at(&m, ln) + 0.02 * m.params().tendon_slack_length;
                for v in [-0.3, -0.02, 0.02, 0.3] {
                    let v_mt = v * m.max_fiber_velocity();
                    let eq = m.state_equilibrium(a, l_mt, v_mt, &settings);
                    if eq.status != MuscleStatus::Ok {
                        continue;
                    }
                    let s = m.state_at_fiber_length(a, l_mt, v_mt, eq.fiber_length);
                    assert_eq!(s.status, MuscleStatus::Ok, "{name} a {a} l̃ {ln} v {v}");
                    assert!(
                        s.normalized_fiber_velocity.abs() < 1e-9,
                        "{name} a {a} l̃ {ln} v {v}: ṽ = {}",
                        s.normalized_fiber_velocity
                    );
                }
            }
        }
    }
}

/// The Arm26 CMC use: a Thelen muscle's tendon force from the stored fiber length is
/// F_max f_T((ℓ_MT − l cos α)/l_s), whatever the activation.
#[test]
fn thelen_tendon_force_from_fiber_length_follows_the_tendon_curve() {
    let m = thelen(&[("FmaxTendonStrain", "0.033")]);
    let (f_max, l_opt, l_s, e0) = (800.0, 0.12, 0.25, 0.033);
    let h = l_opt * 0.3f64.sin();
    let e3 = 3.0f64.exp();
    let e_toe = 99.0 * e0 * e3 / (166.0 * e3 - 67.0);
    let k_lin = 0.67 / (e0 - e_toe);
    let ft = |strain: f64| {
        if strain > e_toe {
            k_lin * (strain - e_toe) + 0.33
        } else if strain > 0.0 {
            0.33 / (e3 - 1.0) * ((3.0 * strain / e_toe).exp() - 1.0)
        } else {
            0.0
        }
    };
    for (lce, l_mt) in [(0.12, 0.36), (0.10, 0.35), (0.14, 0.385), (0.11, 0.342)] {
        let cos = (1.0 - (h / lce) * (h / lce)).sqrt();
        let expected = f_max * ft((l_mt - lce * cos) / l_s - 1.0);
        for a in [0.02, 0.5, 1.0] {
            let s = m.state_at_fiber_length(a, l_mt, 0.0, lce);
            assert!(
                (s.tendon_force - expected).abs() < 1e-10,
                "{} vs {expected}",
                s.tendon_force
            );
            assert!(s.status == MuscleStatus::Ok || s.status == MuscleStatus::FiberAtLowerBound);
        }
    }
}

#[test]
fn isometric_force_is_the_full_activation_static_tendon_force() {
    let rigid = millard(&[("ignore_tendon_compliance", "true")], &[]);
    let p = *rigid.params();
    // Rigid: F_iso(l_opt cos α_opt + l_s) = F_max cos α_opt (f_L(1) = 1, f_PE(1) = 0).
    let f = rigid.isometric_force(l_mt_at(&rigid, 1.0));
    assert!((f - p.max_isometric_force * p.pennation_angle_at_optimal.cos()).abs() < 1e-9);
    // Elastic: the tendon stretches, the fiber shortens below optimal, the force is lower.
    for (name, m) in zoo() {
        let l_mt = l_mt_at(&m, 1.0);
        let f = m.isometric_force(l_mt);
        let s = m.state_equilibrium(1.0, l_mt, 0.0, &Default::default());
        assert_eq!(f, s.tendon_force, "{name}");
        assert!(
            f > 0.0 && f < m.state_rigid_tendon(1.0, l_mt, 0.0).tendon_force,
            "{name}"
        );
    }
}

#[test]
fn slack_musculotendon_is_reported_not_solved() {
    for (name, m) in zoo() {
        let l_mt = 0.5 * m.params().tendon_slack_length;
        let s = m.state_equilibrium(1.0, l_mt, 0.0, &Default::default());
        let expected = if m.kind() == MuscleKind::DeGrooteFregly2016 {
            MuscleStatus::NoEquilibrium
        } else {
            MuscleStatus::FiberAtLowerBound
        };
        assert_eq!(s.status, expected, "{name}");
        if expected == MuscleStatus::FiberAtLowerBound {
            assert_eq!(s.tendon_force, 0.0);
            assert_eq!(s.fiber_length, m.params().minimum_fiber_length);
        }
    }
}

#[test]
fn non_finite_inputs_give_invalid_input_status() {
    let m = thelen(&[]);
    let l = l_mt_at(&m, 1.0);
    assert_eq!(
        m.state_rigid_tendon(f64::NAN, l, 0.0).status,
        MuscleStatus::InvalidInput
    );
    assert_eq!(
        m.state_equilibrium(1.0, f64::INFINITY, 0.0, &Default::default())
            .status,
        MuscleStatus::InvalidInput
    );
    assert_eq!(
        m.state_at_fiber_length(1.0, l, 0.0, f64::NAN).status,
        MuscleStatus::InvalidInput
    );
    let d = degroote(&[]);
    // No activation, no damping: the fiber velocity is undetermined.
    assert_eq!(
        d.state_at_fiber_length(0.0, l_mt_at(&d, 1.0), 0.0, 0.12)
            .status,
        MuscleStatus::Singular
    );
}

/// Nanoseconds per call: the best of 5 runs of 4,000 calls (the machine may be shared).
fn time_per_call(mut f: impl FnMut(usize) -> f64) -> f64 {
    let n = 4_000;
    let mut acc = 0.0;
    for i in 0..n / 4 {
        acc += f(i);
    }
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        for i in 0..n {
            acc += f(i);
        }
        best = best.min(t.elapsed().as_secs_f64() / n as f64 * 1e9);
    }
    black_box(acc);
    best
}

#[test]
fn force_computation_timings() {
    eprintln!(
        "time per call (ns): rigid | at fiber length | equilibrium static | equilibrium moving | isometric"
    );
    for (name, m) in zoo() {
        let l0 = l_mt_at(&m, 1.0);
        let ls = m.params().tendon_slack_length;
        let vs = m.max_fiber_velocity();
        let l_mt = |i: usize| l0 + 0.03 * ls * ((i % 97) as f64 / 97.0);
        let v_mt = |i: usize| vs * (0.4 * ((i % 89) as f64 / 89.0) - 0.2);
        let rigid = time_per_call(|i| m.state_rigid_tendon(0.7, l_mt(i), v_mt(i)).tendon_force);
        let fiber = time_per_call(|i| {
            m.state_at_fiber_length(0.7, l_mt(i), v_mt(i), m.params().optimal_fiber_length)
                .tendon_force
        });
        let settings = EquilibriumSettings::default();
        let still = time_per_call(|i| {
            m.state_equilibrium(0.7, l_mt(i), 0.0, &settings)
                .tendon_force
        });
        let moving = time_per_call(|i| {
            m.state_equilibrium(0.7, l_mt(i), v_mt(i), &settings)
                .tendon_force
        });
        let iso = time_per_call(|i| m.isometric_force(l_mt(i)));
        eprintln!("{name:>18}: {rigid:8.0} | {fiber:8.0} | {still:8.0} | {moving:8.0} | {iso:8.0}");
        assert!(rigid.is_finite() && moving.is_finite());
    }
}

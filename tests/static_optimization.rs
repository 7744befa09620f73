//! Static optimization checked against independent references: the closed-form optimum of
//! Σx² under one equality, finite-difference virtual work for the generalized force of each
//! actuator type, OpenSim's control defaults, force-set files, and infeasible frames.

mod common;
use common::*;
use musculo::dynamics::{self, forward_kinematics};
use musculo::model::{ActuatorKind, ForceSetFiles, LoadOptions};
use musculo::solve::static_optimization::{
    SoFrame, SoStatus, SoWorkspace, StaticOptimization, StaticOptimizationOptions,
};
use musculo::spatial::{Mat3, Vec3};
use musculo::{Data, Model};

fn demo_with(force_set: &str) -> musculo::Result<Model> {
    Model::from_osim_str_with_force_sets(
        musculo::DEMO_MODEL_OSIM,
        "<demo>",
        &LoadOptions::default(),
        &ForceSetFiles {
            files: vec![(force_set.to_string(), "reserves.xml".to_string())],
            replace: false,
        },
    )
}

fn force_set(objects: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <ForceSet name="reserves">
    <objects>
{objects}
    </objects>
    <groups />
  </ForceSet>
</OpenSimDocument>"#
    )
}

fn coordinate_actuator(name: &str, coordinate: &str, optimal: f64, bounds: &str) -> String {
    format!(
        "<CoordinateActuator name=\"{name}\"><coordinate>{coordinate}</coordinate>\
         <optimal_force>{optimal}</optimal_force>{bounds}</CoordinateActuator>"
    )
}

/// Reserves on every independent coordinate of the demo model, plus extra actuators.
fn demo_reserves(extra: &str) -> String {
    let mut s = String::new();
    for c in [
        "pelvis_tilt",
        "pelvis_tx",
        "pelvis_ty",
        "hip_flexion",
        "knee_angle",
        "ankle_angle",
    ] {
        s += &coordinate_actuator(&format!("reserve_{c}"), c, 10.0, "");
    }
    force_set(&(s + extra))
}

/// Rotation vector of R (small angles): the axial vector of (R − Rᵀ)/2.
fn axial(r: &Mat3) -> Vec3 {
    Vec3::new(
        0.5 * (r[(2, 1)] - r[(1, 2)]),
        0.5 * (r[(0, 2)] - r[(2, 0)]),
        0.5 * (r[(1, 0)] - r[(0, 1)]),
    )
}

#[test]
fn generalized_forces_of_actuators_equal_finite_difference_virtual_work() {
    // Q_j = F · ∂p/∂q_j for a point force, T · ω_j for a torque (ω_j the rotation per unit
    // q_j), ∂c/∂q_j for a coordinate actuator (here on the coupled patella coordinate).
    let extra = r#"
<PointActuator name="push"><body>shank</body><point>0.02 -0.2 0.01</point>
  <direction>0.3 -1 0.2</direction><force_is_global>false</force_is_global>
  <optimal_force>7</optimal_force></PointActuator>
<PointActuator name="push_global"><body>/bodyset/foot</body><point>0.1 0.9 0.05</point>
  <point_is_global>true</point_is_global><direction>1 0 0</direction>
  <force_is_global>true</force_is_global><optimal_force>3</optimal_force></PointActuator>
<TorqueActuator name="twist"><bodyA>shank</bodyA><bodyB>thigh</bodyB>
  <axis>0.2 0.1 1</axis><torque_is_global>false</torque_is_global>
  <optimal_force>5</optimal_force></TorqueActuator>
<CoordinateActuator name="patella_drive"><coordinate>patella_angle</coordinate>
  <optimal_force>2</optimal_force></CoordinateActuator>"#;
    let model = demo_with(&demo_reserves(extra)).unwrap();
    let so = StaticOptimization::new(
        &model,
        StaticOptimizationOptions {
            use_muscle_physiology: false,
            ..Default::default()
        },
    )
    .unwrap();
    let n = model.nq();
    let mut rng = Rng::new(11);
    let q = random_q(&model, &mut rng);
    let qd = vec![0.0; n];
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &q).unwrap();
    dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
    let mut ws = SoWorkspace::new(&model, &so);
    so.assemble(&model, &data, &vec![0.0; n], &mut ws).unwrap();

    let h = 1e-6;
    let mut fd = Data::new(&model);
    let mut at = |qq: &[f64]| {
        forward_kinematics(&model, &mut fd, qq).unwrap();
        fd.clone()
    };
    for (k, act) in so.actuators.iter().enumerate() {
        for j in 0..n {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += h;
            qm[j] -= h;
            let (dp, dm) = (at(&qp), at(&qm));
            let expected = match &act.kind {
                ActuatorKind::Point {
                    body,
                    point,
                    point_is_global,
                    direction,
                    force_is_global,
                } => {
                    // A ground point becomes a station of the body at the current pose.
                    let (rot, origin) = data.body_pose(*body);
                    let station = if *point_is_global {
                        rot.transpose() * (point - origin)
                    } else {
                        *point
                    };
                    let d = if *force_is_global {
                        *direction
                    } else {
                        rot * direction
                    };
                    let dpdq = (dp.point_position(*body, &station)
                        - dm.point_position(*body, &station))
                        / (2.0 * h);
                    act.optimal_force * d.dot(&dpdq)
                }
                ActuatorKind::Torque {
                    body_a,
                    body_b,
                    axis,
                    ..
                } => {
                    let omega = |b: usize| {
                        let (rp, _) = dp.body_pose(b);
                        let (rm, _) = dm.body_pose(b);
                        axial(&(rp * rm.transpose())) / (2.0 * h)
                    };
                    let (ra, _) = data.body_pose(*body_a);
                    let t = ra * axis;
                    act.optimal_force * t.dot(&(omega(*body_a) - omega(*body_b)))
                }
                ActuatorKind::Coordinate { coordinate } => {
                    let (cp, cm) = (
                        dp.coordinate_values(&model)[*coordinate],
                        dm.coordinate_values(&model)[*coordinate],
                    );
                    act.optimal_force * (cp - cm) / (2.0 * h)
                }
                ActuatorKind::Muscle => {
                    // r = −∂ℓ/∂q, checked elsewhere; F = F_max without physiology.
                    continue;
                }
                ActuatorKind::Path => unreachable!(),
            };
            assert_close(
                ws.a.get(j, k).expect("entry"),
                expected,
                1e-6,
                &format!("{} on q[{j}]", act.name),
            );
        }
    }
}

#[test]
fn optimum_equals_the_closed_form_least_norm_solution() {
    // Three coordinate actuators on one coordinate (forces F_i, x unbounded):
    //   min Σ x_i² s.t. Σ F_i x_i = τ  ⇒  x_i = τ F_i / Σ F_k².
    // With x_1 ≤ u active: x_1 = u and the others share τ − F_1 u the same way.
    let extra = [
        coordinate_actuator("a1", "knee_angle", 40.0, "<max_control>0.5</max_control>"),
        coordinate_actuator("a2", "knee_angle", 25.0, ""),
        coordinate_actuator("a3", "knee_angle", 10.0, ""),
    ]
    .concat();
    let model = demo_with(&demo_reserves(&extra)).unwrap();
    let so = StaticOptimization::new(
        &model,
        StaticOptimizationOptions {
            use_muscle_physiology: false,
            ..Default::default()
        },
    )
    .unwrap();
    let n = model.nq();
    let q = vec![0.0, 0.0, 0.93, 0.3, -0.6, 0.1];
    let mut data = Data::new(&model);
    dynamics::rnea(&model, &mut data, &q, &vec![0.0; n], &vec![0.0; n]).unwrap();
    let mut ws = SoWorkspace::new(&model, &so);
    let mut frame = SoFrame::new(&so, &model);
    let knee = model.q_index("knee_angle").unwrap();
    let idx = |name: &str| so.names().position(|a| a == name).unwrap();
    let vasti = idx("vasti");
    let r_vasti = {
        so.assemble(&model, &data, &vec![0.0; n], &mut ws).unwrap();
        ws.a.get(knee, vasti).expect("entry")
    };
    for tau_knee in [6.0, 30.0, -20.0] {
        let mut tau = vec![0.0; n];
        tau[knee] = tau_knee;
        so.solve_frame(&model, &data, &tau, &mut ws, &mut frame)
            .unwrap();
        assert_eq!(frame.status, SoStatus::Solved);
        // The vasti muscle (x ∈ [0.01, 1], F = F_max) and the knee reserve (F = 10) also
        // act on the knee; the muscle's lower bound may be active.
        let cols: Vec<(usize, f64)> = ["a1", "a2", "a3", "reserve_knee_angle"]
            .iter()
            .map(|a| (idx(a), ws.a.get(knee, idx(a)).expect("entry")))
            .collect();
        // Solve the KKT conditions by hand over the bounds' cases.
        let mut best: Option<Vec<f64>> = None;
        for a1_at_bound in [false, true] {
            for vasti_free in [false, true] {
                let mut fixed = 0.0;
                let mut x = vec![0.0; so.actuators.len()];
                let mut free = cols.clone();
                if a1_at_bound {
                    x[idx("a1")] = 0.5;
                    fixed += 40.0 * 0.5;
                    free.retain(|(k, _)| *k != idx("a1"));
                }
                if vasti_free {
                    free.push((vasti, r_vasti));
                } else {
                    x[vasti] = 0.01;
                    fixed += r_vasti * 0.01;
                }
                let s2: f64 = free.iter().map(|(_, f)| f * f).sum();
                for &(k, f) in &free {
                    x[k] = (tau_knee - fixed) * f / s2;
                }
                let ok = x[idx("a1")] <= 0.5 + 1e-12 && (0.01..=1.0).contains(&x[vasti]);
                // The multiplier of a bound must push the right way (KKT).
                let lambda = (tau_knee - fixed) / s2;
                let kkt = (!a1_at_bound || 2.0 * 0.5 <= 2.0 * lambda * 40.0 + 1e-9)
                    && (vasti_free || 2.0 * 0.01 >= 2.0 * lambda * r_vasti - 1e-9);
                if ok && kkt {
                    best = Some(x);
                }
            }
        }
        let x = best.expect("one KKT case holds");
        for (k, a) in so.actuators.iter().enumerate() {
            assert_close(
                frame.controls[k],
                x[k],
                1e-8,
                &format!("τ_knee {tau_knee}: {}", a.name),
            );
            assert_close(
                frame.forces[k],
                frame.controls[k] * ws.unit_force[k],
                1e-14,
                "force = x F",
            );
        }
        assert!(frame.residual.iter().all(|r| r.abs() < 1e-8));
    }
}

#[test]
fn infeasible_frame_reports_the_unbalanced_coordinates_and_the_least_squares_controls() {
    // Every reserve bounded to |x| ≤ 1 with F = 10: a knee moment of 50 cannot be produced.
    // The least-squares controls saturate the knee actuators; the residual is what is left.
    let mut s = String::new();
    for c in [
        "pelvis_tilt",
        "pelvis_tx",
        "pelvis_ty",
        "hip_flexion",
        "knee_angle",
        "ankle_angle",
    ] {
        s += &coordinate_actuator(
            &format!("reserve_{c}"),
            c,
            10.0,
            "<min_control>-1</min_control><max_control>1</max_control>",
        );
    }
    let model = demo_with(&force_set(&s)).unwrap();
    let so = StaticOptimization::new(
        &model,
        StaticOptimizationOptions {
            use_muscle_physiology: false,
            ..Default::default()
        },
    )
    .unwrap();
    let n = model.nq();
    let q = vec![0.0, 0.0, 0.93, 0.3, -0.6, 0.1];
    let mut data = Data::new(&model);
    dynamics::rnea(&model, &mut data, &q, &vec![0.0; n], &vec![0.0; n]).unwrap();
    let mut ws = SoWorkspace::new(&model, &so);
    let mut frame = SoFrame::new(&so, &model);
    let knee = model.q_index("knee_angle").unwrap();
    let mut tau = vec![0.0; n];
    tau[knee] = 5000.0;
    tau[model.q_index("hip_flexion").unwrap()] = 3.0;
    so.solve_frame(&model, &data, &tau, &mut ws, &mut frame)
        .unwrap();
    assert_eq!(frame.status, SoStatus::Infeasible);
    let k = so.names().position(|a| a == "reserve_knee_angle").unwrap();
    assert_close(frame.controls[k], 1.0, 1e-9, "knee reserve saturated");
    let vasti = so.names().position(|a| a == "vasti").unwrap();
    assert_close(frame.controls[vasti], 1.0, 1e-9, "vasti saturated");
    let produced = ws.a.get(knee, k).expect("entry") + ws.a.get(knee, vasti).expect("entry");
    assert_close(
        frame.residual[knee],
        5000.0 - produced,
        1e-9,
        "knee residual",
    );
    // The other coordinates are balanced to the solver's infeasibility tolerance.
    for j in (0..n).filter(|&j| j != knee) {
        assert!(
            frame.residual[j].abs() <= 1e-6 * frame.residual[knee].abs(),
            "q[{j}] balanced: residual {}",
            frame.residual[j]
        );
    }
    // The next frame, feasible, is solved again.
    tau[knee] = 2.0;
    so.solve_frame(&model, &data, &tau, &mut ws, &mut frame)
        .unwrap();
    assert_eq!(frame.status, SoStatus::Solved);
}

#[test]
fn control_defaults_are_opensims_and_disabled_actuators_are_left_out() {
    let extra = r#"
<CoordinateActuator name="off"><appliesForce>false</appliesForce><coordinate>hip_flexion</coordinate></CoordinateActuator>
<CoordinateActuator name="plain"><coordinate>hip_flexion</coordinate></CoordinateActuator>
<CoordinateActuator name="bounded"><coordinate>hip_flexion</coordinate><min_control>-Inf</min_control><max_control>2.5</max_control><optimal_force>300</optimal_force></CoordinateActuator>"#;
    let model = demo_with(&demo_reserves(extra)).unwrap();
    let get = |name: &str| {
        model
            .forces
            .iter()
            .find(|f| f.name == name)
            .unwrap()
            .actuator
            .clone()
            .unwrap()
    };
    // Thelen 2003: OpenSim sets min_control to the default minimum activation 0.01.
    let vasti = get("vasti");
    assert_eq!((vasti.min_control, vasti.max_control), (0.01, 1.0));
    let plain = get("plain");
    assert_eq!(
        (plain.min_control, plain.max_control, plain.optimal_force),
        (f64::NEG_INFINITY, f64::INFINITY, 1.0)
    );
    let bounded = get("bounded");
    assert_eq!(
        (
            bounded.min_control,
            bounded.max_control,
            bounded.optimal_force
        ),
        (f64::NEG_INFINITY, 2.5, 300.0)
    );
    let so = StaticOptimization::new(&model, Default::default()).unwrap();
    let names: Vec<&str> = so.names().collect();
    assert!(!names.contains(&"off"));
    assert!(names.contains(&"plain") && names.contains(&"vasti"));
}

#[test]
fn bad_force_set_files_and_problems_are_clear_errors() {
    let unknown_body = force_set(
        "<PointActuator name=\"p\"><body>tibia</body><direction>1 0 0</direction></PointActuator>",
    );
    let e = demo_with(&unknown_body).unwrap_err().to_string();
    assert!(
        e.contains("reserves.xml:5:") && e.contains("unknown body `tibia`"),
        "{e}"
    );
    let duplicate = force_set(&coordinate_actuator("vasti", "knee_angle", 1.0, ""));
    let e = demo_with(&duplicate).unwrap_err().to_string();
    assert!(e.contains("already in the model"), "{e}");
    let bad_bounds = force_set(&coordinate_actuator(
        "r",
        "knee_angle",
        1.0,
        "<min_control>2</min_control><max_control>1</max_control>",
    ));
    let e = demo_with(&bad_bounds).unwrap_err().to_string();
    assert!(e.contains("min_control"), "{e}");
    let unknown_coordinate = force_set(&coordinate_actuator("r", "knee", 1.0, ""));
    let e = demo_with(&unknown_coordinate).unwrap_err().to_string();
    assert!(e.contains("unknown coordinate `knee`"), "{e}");
    let not_a_force_set =
        "<OpenSimDocument Version=\"40000\"><Model name=\"m\"/></OpenSimDocument>";
    let e = demo_with(not_a_force_set).unwrap_err().to_string();
    assert!(e.contains("<ForceSet>"), "{e}");

    // Fewer actuators than coordinates: OpenSim's over-constrained system.
    let e = StaticOptimization::new(&Model::demo(), Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("1 actuators for 6 coordinates"), "{e}");
    let e = StaticOptimization::new(
        &demo_with(&demo_reserves("")).unwrap(),
        StaticOptimizationOptions {
            activation_exponent: 1.0,
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("activation_exponent"), "{e}");
}

//! Every joint type and function type the reader supports, checked against the transform
//! OpenSim/Simbody defines for it, plus the dynamics identities on a chain that uses them all.

mod common;
use common::*;
use musculo::spatial::{Mat3, Transform, Vec3, rotation_about_axis, rotation_vector};
use musculo::{Data, Model, dynamics};
use nalgebra::{DMatrix, DVector};

fn offset_frame(name: &str, parent: &str, t: [f64; 3], o: [f64; 3]) -> String {
    format!(
        "<PhysicalOffsetFrame name=\"{name}\"><socket_parent>{parent}</socket_parent>\
         <translation>{} {} {}</translation><orientation>{} {} {}</orientation></PhysicalOffsetFrame>",
        t[0], t[1], t[2], o[0], o[1], o[2]
    )
}

/// (type, number of coordinates, X_FM(q) as Simbody defines the mobilizer).
type JointDef = (&'static str, usize, fn(&[f64]) -> Transform);

fn rx(a: f64) -> Mat3 {
    rotation_about_axis(&Vec3::x(), a)
}
fn ry(a: f64) -> Mat3 {
    rotation_about_axis(&Vec3::y(), a)
}
fn rz(a: f64) -> Mat3 {
    rotation_about_axis(&Vec3::z(), a)
}

const JOINTS: [JointDef; 8] = [
    // Slider: translation along the x axis of F.
    ("SliderJoint", 1, |q| {
        Transform::new(Mat3::identity(), Vec3::new(q[0], 0.0, 0.0))
    }),
    // Ball and Gimbal: body-fixed X-Y-Z rotation (OpenSim uses Euler angles for the Ball).
    ("BallJoint", 3, |q| {
        Transform::new(rx(q[0]) * ry(q[1]) * rz(q[2]), Vec3::zeros())
    }),
    ("GimbalJoint", 3, |q| {
        Transform::new(rx(q[0]) * ry(q[1]) * rz(q[2]), Vec3::zeros())
    }),
    // Universal: about x, then about the new y.
    ("UniversalJoint", 2, |q| {
        Transform::new(rx(q[0]) * ry(q[1]), Vec3::zeros())
    }),
    // Planar: coordinates (rz, tx, ty); translation in F, then rotation about z.
    ("PlanarJoint", 3, |q| {
        Transform::new(rz(q[0]), Vec3::new(q[1], q[2], 0.0))
    }),
    // Free: coordinates (rx, ry, rz, tx, ty, tz); translation in F.
    ("FreeJoint", 6, |q| {
        Transform::new(rx(q[0]) * ry(q[1]) * rz(q[2]), Vec3::new(q[3], q[4], q[5]))
    }),
    ("WeldJoint", 0, |_| Transform::identity()),
    // Pin: rotation about the z axis of F.
    ("PinJoint", 1, |q| Transform::new(rz(q[0]), Vec3::zeros())),
];

/// A chain ground → b0 → b1 → … with one joint of each type; every joint has offset frames
/// with translations and orientations on both sides.
fn chain_model() -> (Model, Vec<(Transform, Transform)>) {
    let mut rng = Rng::new(99);
    let mut bodies = String::new();
    let mut joints = String::new();
    let mut offsets = Vec::new();
    let mut r3 = |s: f64| [rng.uniform(-s, s), rng.uniform(-s, s), rng.uniform(-s, s)];
    for (i, (kind, nc, _)) in JOINTS.iter().enumerate() {
        let b = format!("b{i}");
        let parent = if i == 0 {
            "/ground".to_string()
        } else {
            format!("/bodyset/b{}", i - 1)
        };
        bodies += &body(
            &b,
            1.0 + 0.3 * i as f64,
            r3(0.1),
            [0.03, 0.025, 0.02, 0.001, -0.002, 0.0015],
        );
        let (tp, op, tc, oc) = (r3(0.2), r3(1.0), r3(0.1), r3(1.0));
        offsets.push((
            Transform::from_translation_xyz_body(Vec3::from(tp), Vec3::from(op)),
            Transform::from_translation_xyz_body(Vec3::from(tc), Vec3::from(oc)),
        ));
        let coords: String = (0..*nc)
            .map(|k| coordinate(&format!("{b}_q{k}"), [-1.2, 1.2]))
            .collect();
        joints += &format!(
            "<{kind} name=\"j{i}\"><socket_parent_frame>p</socket_parent_frame><socket_child_frame>c</socket_child_frame>\
             <coordinates>{coords}</coordinates><frames>{}{}</frames></{kind}>",
            offset_frame("p", &parent, tp, op),
            offset_frame("c", &format!("/bodyset/{b}"), tc, oc),
        );
    }
    let model =
        Model::from_osim_str(&osim(&bodies, &joints, "", [0.0, -9.81, 0.0]), "chain").unwrap();
    (model, offsets)
}

#[test]
fn every_joint_type_moves_its_child_as_simbody_defines_it() {
    let (model, offsets) = chain_model();
    assert_eq!(model.nq(), JOINTS.iter().map(|j| j.1).sum::<usize>());
    let mut data = Data::new(&model);
    let mut rng = Rng::new(3);
    for _ in 0..20 {
        let q = random_q(&model, &mut rng);
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        // X_G,child = X_G,parent · X_PF · X_FM(q) · X_MC⁻¹
        let mut x = Transform::identity();
        let mut k = 0;
        for (i, (kind, nc, xfm)) in JOINTS.iter().enumerate() {
            let (xpf, xcm) = &offsets[i];
            x = x
                .compose(xpf)
                .compose(&xfm(&q[k..k + nc]))
                .compose(&xcm.inverse());
            k += nc;
            let b = model.body_index(&format!("b{i}")).unwrap();
            let (r, p) = data.body_pose(b);
            assert!(
                (r - x.rot).amax() < 1e-13 && (p - x.pos).amax() < 1e-13,
                "{kind}: pose differs"
            );
        }
    }
}

#[test]
fn dynamics_identities_hold_on_a_chain_of_every_joint_type() {
    let (model, _) = chain_model();
    let n = model.nq();
    let mut data = Data::new(&model);
    let mut d2 = Data::new(&model);
    let mut rng = Rng::new(4);
    for _ in 0..50 {
        let q = random_q(&model, &mut rng);
        let qd = random_vec(n, 2.0, &mut rng);
        let qdd = random_vec(n, 10.0, &mut rng);
        let m = dynamics::crba(&model, &mut data, &q).unwrap().clone();
        assert!(m.clone().cholesky().is_some());
        let bias = dynamics::nonlinear_effects(&model, &mut data, &q, &qd)
            .unwrap()
            .clone();
        let tau = dynamics::rnea(&model, &mut data, &q, &qd, &qdd)
            .unwrap()
            .clone();
        let e =
            (&tau - (&m * DVector::from_column_slice(&qdd) + &bias)).norm() / tau.norm().max(1.0);
        assert!(e < 1e-12, "ID vs M q̈ + bias: {e:e}");
        let g = dynamics::gravity(&model, &mut data, &q).unwrap().clone();
        let zeros = vec![0.0; n];
        let id0 = dynamics::rnea(&model, &mut data, &q, &zeros, &zeros)
            .unwrap()
            .clone();
        assert!((&g - &id0).norm() < 1e-12 * g.norm().max(1.0));
        // Body Jacobians against finite differences of the poses.
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        let h = 1e-6;
        let mut j = DMatrix::zeros(6, n);
        for b in 1..model.bodies.len() {
            dynamics::body_jacobian(&model, &data, b, &mut j).unwrap();
            for c in 0..n {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[c] += h;
                qm[c] -= h;
                dynamics::forward_kinematics(&model, &mut d2, &qp).unwrap();
                let (rp, pp) = d2.body_pose(b);
                dynamics::forward_kinematics(&model, &mut d2, &qm).unwrap();
                let (rm, pm) = d2.body_pose(b);
                let w = rotation_vector(&(rp * rm.transpose())) / (2.0 * h);
                let v = (pp - pm) / (2.0 * h);
                for k in 0..3 {
                    assert!((j[(k, c)] - w[k]).abs() < 1e-7 && (j[(3 + k, c)] - v[k]).abs() < 1e-7);
                }
            }
        }
        // ½ q̇ᵀ M q̇ against the bodies' kinetic energy.
        dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
        let qdv = DVector::from_column_slice(&qd);
        let ke = dynamics::kinetic_energy(&model, &data).unwrap();
        assert!((0.5 * qdv.dot(&(&m * &qdv)) - ke).abs() < 1e-12 * ke.max(1.0));
    }
}

#[test]
fn every_function_type_drives_a_transform_axis_as_written() {
    // A CustomJoint whose three translations are driven by functions of one coordinate whose
    // values are known in closed form, and a second joint driven through a
    // MultiplierFunction and a PolynomialFunction:
    // - NaturalCubicSpline (read as OpenSim's SimmSpline) through samples of a cubic
    //   reproduces that cubic;
    // - GCVSpline of half order 3 through samples of a quadratic reproduces the quadratic
    //   (a natural quintic spline reproduces polynomials of degree < 3, also outside its knots);
    // - PiecewiseLinearFunction interpolates linearly;
    // - MultiplierFunction(scale, LinearFunction), PolynomialFunction.
    let cubic = |t: f64| 0.01 + 0.02 * t - 0.03 * t * t + 0.015 * t * t * t;
    let quad = |t: f64| -0.02 + 0.05 * t + 0.04 * t * t;
    let knots = [-1.0, -0.6, -0.1, 0.3, 0.8, 1.0];
    let list = |f: &dyn Fn(f64) -> f64| {
        knots
            .iter()
            .map(|&t| format!("{:.17e}", f(t)))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let xs = knots
        .iter()
        .map(|t| t.to_string())
        .collect::<Vec<_>>()
        .join(" ");
    let ncs = format!(
        "<NaturalCubicSpline><x>{xs}</x><y>{}</y></NaturalCubicSpline>",
        list(&cubic)
    );
    let gcv = format!(
        "<GCVSpline><half_order>3</half_order><x>{xs}</x><y>{}</y></GCVSpline>",
        list(&quad)
    );
    let pwl =
        "<PiecewiseLinearFunction><x>-1 0 1</x><y>0.1 -0.05 0.2</y></PiecewiseLinearFunction>";
    let st1 = spatial_transform([
        ("", [0.0, 0.0, 1.0], ZERO),
        ("", [1.0, 0.0, 0.0], ZERO),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("t", [1.0, 0.0, 0.0], &ncs),
        ("t", [0.0, 1.0, 0.0], &gcv),
        ("t", [0.0, 0.0, 1.0], pwl),
    ]);
    let mult = "<MultiplierFunction><function><LinearFunction><coefficients>2 0.1</coefficients></LinearFunction></function><scale>0.5</scale></MultiplierFunction>";
    let poly = "<PolynomialFunction><coefficients>0.3 -0.2 0.1</coefficients></PolynomialFunction>";
    let st2 = spatial_transform([
        ("u", [0.0, 0.0, 1.0], mult),
        ("", [1.0, 0.0, 0.0], ZERO),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("u", [1.0, 0.0, 0.0], poly),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("", [0.0, 0.0, 1.0], ZERO),
    ]);
    let bodies = body("a", 1.0, [0.0; 3], [0.01, 0.01, 0.01, 0.0, 0.0, 0.0])
        + &body("b", 1.0, [0.0; 3], [0.01, 0.01, 0.01, 0.0, 0.0, 0.0]);
    let joints = joint(
        "CustomJoint",
        "ja",
        "/ground",
        [0.0; 3],
        "/bodyset/a",
        &[coordinate("t", [-1.5, 1.5])],
        &st1,
    ) + &joint(
        "CustomJoint",
        "jb",
        "/ground",
        [0.0; 3],
        "/bodyset/b",
        &[coordinate("u", [-1.0, 1.0])],
        &st2,
    );
    let model =
        Model::from_osim_str(&osim(&bodies, &joints, "", [0.0, -9.81, 0.0]), "functions").unwrap();
    let mut data = Data::new(&model);
    let pwl_at = |t: f64| {
        if t < 0.0 {
            0.1 + (t + 1.0) * -0.15
        } else {
            -0.05 + t * 0.25
        }
    };
    for t in [-1.4, -1.0, -0.77, -0.2, 0.0, 0.25, 0.61, 0.99, 1.3] {
        let u = t / 1.5;
        dynamics::forward_kinematics(&model, &mut data, &[t, u]).unwrap();
        let (_, p) = data.body_pose(model.body_index("a").unwrap());
        if (-1.0..=1.0).contains(&t) {
            assert_close(p.x, cubic(t), 1e-14, &format!("NaturalCubicSpline at {t}"));
        }
        assert_close(p.y, quad(t), 1e-12, &format!("GCVSpline at {t}"));
        let pwl_expected = if t < -1.0 {
            0.1 + (t + 1.0) * -0.15
        } else if t > 1.0 {
            0.2 + (t - 1.0) * 0.25
        } else {
            pwl_at(t)
        };
        assert_close(
            p.z,
            pwl_expected,
            1e-14,
            &format!("PiecewiseLinearFunction at {t}"),
        );
        let (r, p) = data.body_pose(model.body_index("b").unwrap());
        assert_close(
            p.x,
            0.3 * u * u - 0.2 * u + 0.1,
            1e-14,
            "PolynomialFunction",
        );
        let angle = 0.5 * (2.0 * u + 0.1);
        assert!((r - rz(angle)).amax() < 1e-14, "MultiplierFunction");
    }
}

//! OpenSim's `MultivariatePolynomialFunction`: its coefficient order and values against
//! OpenSim 4.6's own numbers, a coordinate coupled to two coordinates by one (the shoulder
//! rhythm pattern) with its kinematics and derivatives against finite differences and
//! OpenSim's poses, scaling, the MJCF export, and the reader's errors.
//!
//! The OpenSim numbers are in `tests/data/multivariate_polynomial_opensim.txt`, written by
//! `validation/opensim/multivariate_polynomial_reference.py` from OpenSim 4.6's Python API.

mod common;
use common::*;

use musculo::dynamics::{self, RneaDerivatives};
use musculo::model::function::MultivariatePolynomial;
use musculo::solve::scale::{ScaleOptions, ScaleSet, scale_osim};
use musculo::spatial::Vec3;
use musculo::{Data, Model};
use nalgebra::DMatrix;

const MODEL: &str = include_str!("data/multivariate_coupler.osim");
const OPENSIM: &str = include_str!("data/multivariate_polynomial_opensim.txt");

/// The numbers of the table's lines of `kind`.
fn rows(kind: &str) -> Vec<Vec<f64>> {
    OPENSIM
        .lines()
        .filter_map(|l| l.strip_prefix(kind)?.strip_prefix(' '))
        .map(|l| l.split_whitespace().map(|t| t.parse().unwrap()).collect())
        .collect()
}

fn load(xml: &str) -> musculo::Result<Model> {
    Model::from_osim_str(xml, "multivariate_coupler.osim")
}

#[test]
fn values_and_first_derivatives_match_opensim() {
    // OpenSim's calcValue and calcDerivative([a]) of random polynomials (dimension 2 and 3,
    // order 1 to 4) at random points, with the coefficients in OpenSim's order.
    let mut checked = 0;
    let mut current: Option<MultivariatePolynomial> = None;
    for line in OPENSIM.lines().filter(|l| !l.starts_with('#')) {
        let mut it = line.split_whitespace();
        let kind = it.next().unwrap_or("#");
        let v: Vec<f64> = it.map(|t| t.parse().unwrap()).collect();
        match kind {
            "function" => {
                let (n, order) = (v[0] as usize, v[1] as usize);
                current = Some(MultivariatePolynomial::new(n, order, v[2..].to_vec()).unwrap());
            }
            "point" => {
                let p = current.as_ref().unwrap();
                let n = p.dimension();
                let (x, value, d) = (&v[..n], v[n], &v[n + 1..]);
                let (mut g, mut h) = (vec![0.0; n], vec![0.0; n * n]);
                let got = p.eval(x, &mut g, &mut h);
                assert_close(got, value, 1e-13 * (1.0 + value.abs()), "calcValue");
                for a in 0..n {
                    let what = format!("calcDerivative([{a}])");
                    assert_close(g[a], d[a], 1e-13 * (1.0 + d[a].abs()), &what);
                }
                checked += 1;
            }
            _ => {}
        }
    }
    assert_eq!(checked, 30);
}

#[test]
fn coupled_shoulder_poses_match_opensim() {
    let model = load(MODEL).unwrap();
    assert_eq!(model.q_names(), vec!["arm_flex", "arm_add", "elbow_flex"]);
    let elev = model.coordinate_index("elev").unwrap();
    let bodies = [
        model.body_index("humerus").unwrap(),
        model.body_index("forearm").unwrap(),
    ];
    let mut data = Data::new(&model);
    let mut markers = vec![Vec3::zeros(); model.markers.len()];
    let states = rows("state");
    assert_eq!(states.len(), 8);
    for s in &states {
        dynamics::forward_kinematics(&model, &mut data, &s[..3]).unwrap();
        assert_close(data.coordinate_values(&model)[elev], s[3], 1e-14, "elev");
        for (k, &b) in bodies.iter().enumerate() {
            let (rot, pos) = data.body_pose(b);
            let o = 4 + 12 * k;
            for i in 0..3 {
                assert_close(pos[i], s[o + i], 1e-14, "body origin");
                for j in 0..3 {
                    assert_close(rot[(i, j)], s[o + 3 + 3 * i + j], 1e-14, "body rotation");
                }
            }
        }
        data.marker_positions(&model, &mut markers).unwrap();
        for i in 0..3 {
            assert_close(markers[0][i], s[28 + i], 1e-14, "wrist marker");
        }
    }
}

#[test]
fn a_constant_multivariate_axis_is_a_fixed_offset() {
    // all but the constant term zero: the axis is a fixed translation of 0.01 along y
    let from = "<coefficients>0.01 -0.02 0.015 0.03 -0.01 0.005</coefficients>";
    assert!(MODEL.contains(from));
    let xml = MODEL.replacen(from, "<coefficients>0.01 0 0 0 0 0</coefficients>", 1);
    let (model, reference) = (load(&xml).unwrap(), load(MODEL).unwrap());
    assert_eq!(model.n_full(), reference.n_full() - 1);
    let humerus = model.body_index("humerus").unwrap();
    let mut data = Data::new(&model);
    let mut rng = Rng::new(3);
    for _ in 0..5 {
        let q = [rng.uniform(-1.0, 2.0), rng.uniform(-1.2, 0.8), 0.3];
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        let pos = data.body_pose(humerus).1;
        assert_close(pos.y, 1.41, 1e-15, "humerus origin height");
    }
}

/// θ at q (full coordinates).
fn theta(model: &Model, data: &mut Data, q: &[f64]) -> Vec<f64> {
    dynamics::forward_kinematics(model, data, q).unwrap();
    data.theta(model).to_vec()
}

#[test]
fn kinematic_derivatives_match_finite_differences() {
    // Φ = ∂θ/∂q, Φ̇q̇ = d²θ(q + t q̇)/dt² at t = 0, the wrist's Jacobian, and ∂τ/∂q and ∂τ/∂q̇
    // of inverse dynamics (whose reduction tangents carry the cubic coupler's third
    // derivatives), against central differences.
    let model = load(MODEL).unwrap();
    let (n, nf) = (model.nq(), model.n_full());
    let forearm = model.body_index("forearm").unwrap();
    let wrist = Vec3::new(0.01, -0.25, 0.02);
    let mut data = Data::new(&model);
    let mut rng = Rng::new(11);
    let mut derivs = RneaDerivatives::new(&model);
    let mut jac = DMatrix::zeros(3, n);
    for _ in 0..10 {
        let q = [
            rng.uniform(-1.0, 2.0),
            rng.uniform(-1.2, 0.8),
            rng.uniform(0.0, 2.5),
        ];
        let qd: Vec<f64> = (0..n).map(|_| rng.uniform(-2.0, 2.0)).collect();
        let qdd: Vec<f64> = (0..n).map(|_| rng.uniform(-5.0, 5.0)).collect();
        dynamics::forward_kinematics(&model, &mut data, &q).unwrap();
        let phi = data.phi_matrix(&model);
        dynamics::point_jacobian(&model, &data, forearm, &wrist, &mut jac).unwrap();
        dynamics::forward_kinematics_velocity(&model, &mut data, &q, &qd).unwrap();
        let phi_dot_qd = data.phi_dot_qd(&model).to_vec();
        let h = 1e-6;
        for j in 0..n {
            let (mut qp, mut qm) = (q.to_vec(), q.to_vec());
            qp[j] += h;
            qm[j] -= h;
            let (tp, tm) = (theta(&model, &mut data, &qp), theta(&model, &mut data, &qm));
            for d in 0..nf {
                let fd = (tp[d] - tm[d]) / (2.0 * h);
                assert_close(phi[(d, j)], fd, 1e-8, &format!("Φ[{d}][{j}]"));
            }
            dynamics::forward_kinematics(&model, &mut data, &qp).unwrap();
            let pp = data.point_position(forearm, &wrist);
            dynamics::forward_kinematics(&model, &mut data, &qm).unwrap();
            let pm = data.point_position(forearm, &wrist);
            for i in 0..3 {
                let fd = (pp[i] - pm[i]) / (2.0 * h);
                assert_close(jac[(i, j)], fd, 1e-8, &format!("J[{i}][{j}]"));
            }
        }
        let h2 = 1e-4;
        let along = |t: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + t * b).collect() };
        let (tp, t0, tm) = (
            theta(&model, &mut data, &along(h2)),
            theta(&model, &mut data, &q),
            theta(&model, &mut data, &along(-h2)),
        );
        for d in 0..nf {
            let fd = (tp[d] - 2.0 * t0[d] + tm[d]) / (h2 * h2);
            assert_close(phi_dot_qd[d], fd, 1e-5, &format!("Φ̇q̇[{d}]"));
        }
        dynamics::rnea_derivatives(&model, &mut data, &q, &qd, &qdd, &mut derivs).unwrap();
        let mut tau = |q: &[f64], qd: &[f64]| -> Vec<f64> {
            dynamics::rnea(&model, &mut data, q, qd, &qdd)
                .unwrap()
                .as_slice()
                .to_vec()
        };
        for j in 0..n {
            let (mut qp, mut qm) = (q.to_vec(), q.to_vec());
            qp[j] += h;
            qm[j] -= h;
            let (fp, fm) = (tau(&qp, &qd), tau(&qm, &qd));
            let (mut vp, mut vm) = (qd.clone(), qd.clone());
            vp[j] += h;
            vm[j] -= h;
            let (gp, gm) = (tau(&q, &vp), tau(&q, &vm));
            for i in 0..n {
                let fd = (fp[i] - fm[i]) / (2.0 * h);
                let tol = 1e-6 * (1.0 + fd.abs());
                assert_close(derivs.dtau_dq[(i, j)], fd, tol, &format!("∂τ{i}/∂q{j}"));
                let fd = (gp[i] - gm[i]) / (2.0 * h);
                let tol = 1e-6 * (1.0 + fd.abs());
                assert_close(derivs.dtau_dqd[(i, j)], fd, tol, &format!("∂τ{i}/∂q̇{j}"));
            }
        }
    }
}

#[test]
fn scaling_multiplies_a_multivariate_translation() {
    // A CustomJoint whose translation is a multivariate polynomial of its two coordinates,
    // from a body scaled by 1.3: the scaled function is 1.3 times the original (the
    // coefficients are multiplied, as OpenSim's MultiplierFunction would).
    let mv = "<MultivariatePolynomialFunction><coefficients>0.01 -0.02 0.015 0.03 -0.01 0.005\
              </coefficients><dimension>2</dimension><order>2</order></MultivariatePolynomialFunction>";
    let st = spatial_transform([
        ("a", [0.0, 0.0, 1.0], IDENTITY),
        ("b", [1.0, 0.0, 0.0], IDENTITY),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("a b", [1.0, 0.0, 0.0], mv),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("", [0.0, 0.0, 1.0], ZERO),
    ]);
    let inertia = [0.01, 0.01, 0.01, 0.0, 0.0, 0.0];
    let bodies = body("base", 1.0, [0.0; 3], inertia) + &body("link", 1.0, [0.0; 3], inertia);
    let joints = joint(
        "WeldJoint",
        "weld",
        "/ground",
        [0.0; 3],
        "/bodyset/base",
        &[],
        "",
    ) + &joint(
        "CustomJoint",
        "two_dof",
        "/bodyset/base",
        [0.0; 3],
        "/bodyset/link",
        &[coordinate("a", [-1.0, 1.0]), coordinate("b", [-1.0, 1.0])],
        &st,
    );
    let xml = osim(&bodies, &joints, "", [0.0, -9.81, 0.0]);
    let model = Model::from_osim_str(&xml, "two_dof").unwrap();
    let mut scales = ScaleSet::identity(&model);
    scales.set("base", Vec3::new(1.3, 1.3, 1.3));
    let scaled = scale_osim(&xml, "two_dof", &model, &scales, &ScaleOptions::default()).unwrap();
    let d = (0..model.n_full())
        .find(|&d| model.dofs[d].name.ends_with("translation1"))
        .unwrap();
    let (mut a, mut b) = (Data::new(&model), Data::new(&scaled.model));
    let mut rng = Rng::new(5);
    for _ in 0..10 {
        let q = [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)];
        let before = theta(&model, &mut a, &q)[d];
        let after = theta(&scaled.model, &mut b, &q)[d];
        assert_close(after, 1.3 * before, 1e-15, "scaled translation");
    }
}

#[test]
fn mjcf_export_leaves_multivariate_couplings_free_with_a_note() {
    // MJCF's joint equalities couple two joints by a quartic of one: an axis that depends on
    // two independent coordinates (through the coupler or its own function) is left free and
    // listed in the export's notes.
    let model = load(MODEL).unwrap();
    let export = musculo::mjcf::to_mjcf(&model);
    for axis in ["translation1", "translation2", "translation3"] {
        let name = format!("shoulder/{axis}");
        assert!(
            export
                .notes
                .iter()
                .any(|n| n.contains(&format!("`{name}` depends on 2 independent coordinates"))),
            "{axis}: {:?}",
            export.notes
        );
        assert!(!export.xml.contains(&format!("joint1=\"{name}\"")));
    }
}

/// The reader's message for `xml`, which must be refused.
fn refused(xml: &str) -> String {
    match load(xml) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_multivariate_polynomials_are_refused_clearly() {
    let coupler = "<coefficients>0.1 0.3 -0.2 0.05 0.6 0.15 -0.1 -0.12 0.08 0.03</coefficients>";
    assert!(MODEL.contains(coupler));
    let cases: [(&str, &str, &[&str]); 9] = [
        (
            "<dimension>2</dimension>\n                <order>2</order>",
            "<order>2</order>",
            &["translation2", "missing <dimension>"],
        ),
        (
            coupler,
            "<coefficients>0.1 0.3 -0.2 0.05 0.6 0.15 -0.1 -0.12 0.08</coefficients>",
            &[
                "MultivariatePolynomialFunction",
                "9 values",
                "C(2 + 3, 3) = 10",
            ],
        ),
        (
            coupler,
            "<coefficients>0.1 0.3 -0.2 0.05 0.6 0.15 -0.1 -0.12 0.08 nan</coefficients>",
            &["coefficients", "`nan` is not a finite number"],
        ),
        (
            "<independent_coordinate_names>arm_flex arm_add</independent_coordinate_names>",
            "<independent_coordinate_names>arm_flex</independent_coordinate_names>",
            &["function of 2 argument(s) given 1 independent coordinate(s)"],
        ),
        (
            "<coordinates>arm_flex arm_add</coordinates>",
            "<coordinates>arm_flex arm_add elbow_flex</coordinates>",
            &["MultivariatePolynomialFunction of 2 argument(s) driven by 3 coordinate(s)"],
        ),
        (
            "<dimension>2</dimension>\n                <order>2</order>",
            "<dimension>0</dimension>\n                <order>2</order>",
            &["translation2", "<dimension> must be at least 1"],
        ),
        (
            "<order>3</order>",
            "<order>-1</order>",
            &["<order> must be a non-negative integer, found -1"],
        ),
        (
            "<order>3</order>",
            "<order>2.5</order>",
            &["<order> must be a non-negative integer, found 2.5"],
        ),
        (
            coupler,
            "<coefficients>0.1 0.3 -0.2 0.05 0.6 0.15 -0.1 -0.12 0.08 1e300</coefficients>",
            &["CoordinateCouplerConstraint \"shoulder_rhythm\"", "beyond"],
        ),
    ];
    for (from, to, expected) in cases {
        assert!(MODEL.contains(from), "{from}");
        let message = refused(&MODEL.replacen(from, to, 1));
        for e in expected {
            assert!(message.contains(e), "{to}: {message}");
        }
    }
    // a dimension far beyond any model, and an absurd order, are refused without work
    for (from, to) in [
        (
            "<dimension>2</dimension>\n              <order>3</order>",
            "<dimension>1e18</dimension>\n              <order>3</order>",
        ),
        ("<order>3</order>", "<order>1e18</order>"),
    ] {
        assert!(MODEL.contains(from), "{from}");
        let message = refused(&MODEL.replacen(from, to, 1));
        assert!(
            message.contains("MultivariatePolynomialFunction"),
            "{message}"
        );
    }
}

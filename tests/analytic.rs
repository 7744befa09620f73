//! Closed-form checks: the mass matrix, bias forces and inverse dynamics of small mechanisms
//! whose equations of motion are derived by hand (Lagrange's equations), to 1e-12.

mod common;
use common::*;
use musculo::{Data, Model, dynamics};

const G: f64 = 9.81;
const TOL: f64 = 1e-12;

/// M, bias = C q̇ + G, C q̇, G and τ = ID(q, q̇, q̈) of a model at one state.
struct Computed {
    m: nalgebra::DMatrix<f64>,
    bias: Vec<f64>,
    coriolis: Vec<f64>,
    gravity: Vec<f64>,
    tau: Vec<f64>,
}

fn compute(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Computed {
    let mut d = Data::new(model);
    Computed {
        m: dynamics::crba(model, &mut d, q).unwrap().clone(),
        bias: dynamics::nonlinear_effects(model, &mut d, q, qd)
            .unwrap()
            .as_slice()
            .to_vec(),
        coriolis: dynamics::coriolis(model, &mut d, q, qd)
            .unwrap()
            .as_slice()
            .to_vec(),
        gravity: dynamics::gravity(model, &mut d, q)
            .unwrap()
            .as_slice()
            .to_vec(),
        tau: dynamics::rnea(model, &mut d, q, qd, qdd)
            .unwrap()
            .as_slice()
            .to_vec(),
    }
}

/// Compares every computed quantity with the closed forms (m, c q̇, g) and τ = M q̈ + c + g.
fn check(name: &str, got: &Computed, m: &[&[f64]], cqd: &[f64], g: &[f64], qdd: &[f64]) {
    let n = cqd.len();
    for i in 0..n {
        for j in 0..n {
            assert_close(got.m[(i, j)], m[i][j], TOL, &format!("{name}: M[{i}][{j}]"));
        }
        assert_close(got.coriolis[i], cqd[i], TOL, &format!("{name}: (C q̇)[{i}]"));
        assert_close(got.gravity[i], g[i], TOL, &format!("{name}: G[{i}]"));
        assert_close(
            got.bias[i],
            cqd[i] + g[i],
            TOL,
            &format!("{name}: bias[{i}]"),
        );
        let tau: f64 = (0..n).map(|j| m[i][j] * qdd[j]).sum::<f64>() + cqd[i] + g[i];
        assert_close(got.tau[i], tau, TOL, &format!("{name}: τ[{i}]"));
    }
}

#[test]
fn single_pendulum_matches_closed_form() {
    // A PinJoint about z at the ground origin; centre of mass at distance l below the pivot.
    //   M = I_zz + m l²,  C q̇ = 0,  G = m g l sin θ.
    let (m, l, izz) = (1.7, 0.45, 0.031);
    let xml = osim(
        &body(
            "link",
            m,
            [0.0, -l, 0.0],
            [0.025, 0.012, izz, 0.001, -0.002, 0.003],
        ),
        &joint(
            "PinJoint",
            "pin",
            "/ground",
            [0.0; 3],
            "/bodyset/link",
            &[coordinate("theta", [-3.0, 3.0])],
            "",
        ),
        "",
        [0.0, -G, 0.0],
    );
    let model = Model::from_osim_str(&xml, "pendulum").unwrap();
    let mut rng = Rng::new(1);
    for _ in 0..20 {
        let (th, thd, thdd) = (
            rng.uniform(-3.0, 3.0),
            rng.uniform(-5.0, 5.0),
            rng.uniform(-20.0, 20.0),
        );
        let got = compute(&model, &[th], &[thd], &[thdd]);
        check(
            "pendulum",
            &got,
            &[&[izz + m * l * l]],
            &[0.0],
            &[m * G * l * th.sin()],
            &[thdd],
        );
    }
}

#[test]
fn double_pendulum_matches_closed_form() {
    // Two PinJoints about z; link 1 hangs from the ground origin, link 2 from the point
    // (0, −L1, 0) of link 1; centres of mass at lc1, lc2 along each link; θ2 is relative.
    //   M11 = I1 + I2 + m1 lc1² + m2 (L1² + lc2² + 2 L1 lc2 cos θ2)
    //   M12 = I2 + m2 (lc2² + L1 lc2 cos θ2),  M22 = I2 + m2 lc2²
    //   C q̇ = [h (2 θ̇1 θ̇2 + θ̇2²), −h θ̇1²],  h = −m2 L1 lc2 sin θ2
    //   G = [(m1 lc1 + m2 L1) g sin θ1 + m2 g lc2 sin(θ1+θ2), m2 g lc2 sin(θ1+θ2)]
    let (m1, m2, l1, lc1, lc2, i1, i2) = (2.0, 1.3, 0.6, 0.27, 0.33, 0.05, 0.021);
    let bodies = body(
        "a",
        m1,
        [0.0, -lc1, 0.0],
        [0.045, 0.012, i1, 0.0, 0.004, 0.0],
    ) + &body(
        "b",
        m2,
        [0.0, -lc2, 0.0],
        [0.02, 0.008, i2, 0.0, 0.0, -0.001],
    );
    let joints = joint(
        "PinJoint",
        "j1",
        "/ground",
        [0.0; 3],
        "/bodyset/a",
        &[coordinate("t1", [-3.0, 3.0])],
        "",
    ) + &joint(
        "PinJoint",
        "j2",
        "/bodyset/a",
        [0.0, -l1, 0.0],
        "/bodyset/b",
        &[coordinate("t2", [-3.0, 3.0])],
        "",
    );
    let model =
        Model::from_osim_str(&osim(&bodies, &joints, "", [0.0, -G, 0.0]), "double").unwrap();
    let mut rng = Rng::new(2);
    for _ in 0..20 {
        let q = [rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0)];
        let qd = [rng.uniform(-4.0, 4.0), rng.uniform(-4.0, 4.0)];
        let qdd = [rng.uniform(-10.0, 10.0), rng.uniform(-10.0, 10.0)];
        let c2 = q[1].cos();
        let m11 = i1 + i2 + m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2.0 * l1 * lc2 * c2);
        let m12 = i2 + m2 * (lc2 * lc2 + l1 * lc2 * c2);
        let m22 = i2 + m2 * lc2 * lc2;
        let h = -m2 * l1 * lc2 * q[1].sin();
        let cqd = [
            h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]),
            -h * qd[0] * qd[0],
        ];
        let s12 = (q[0] + q[1]).sin();
        let g = [
            (m1 * lc1 + m2 * l1) * G * q[0].sin() + m2 * G * lc2 * s12,
            m2 * G * lc2 * s12,
        ];
        check(
            "double pendulum",
            &compute(&model, &q, &qd, &qdd),
            &[&[m11, m12], &[m12, m22]],
            &cqd,
            &g,
            &qdd,
        );
    }
}

#[test]
fn free_floating_body_matches_newton_euler_closed_form() {
    // A FreeJoint body with its centre of mass at the body origin. Coordinates: body-fixed
    // X-Y-Z angles α = (a, b, c) and the origin p in ground. The body angular velocity is
    // ω = E(α) α̇ with
    //   E = [[cos b cos c, sin c, 0], [−cos b sin c, cos c, 0], [sin b, 0, 1]],
    // so M = diag(Eᵀ I E, m 1₃), τ_rot = Eᵀ (I (E α̈ + Ė α̇) + ω × I ω), τ_trans = m (p̈ − g).
    let mass = 3.2;
    let ib = nalgebra::Matrix3::new(0.12, 0.01, -0.02, 0.01, 0.09, 0.015, -0.02, 0.015, 0.07);
    let coords: Vec<String> = ["rx", "ry", "rz", "tx", "ty", "tz"]
        .iter()
        .map(|n| coordinate(n, [-1.4, 1.4]))
        .collect();
    let xml = osim(
        &body(
            "b",
            mass,
            [0.0; 3],
            [
                ib[(0, 0)],
                ib[(1, 1)],
                ib[(2, 2)],
                ib[(0, 1)],
                ib[(0, 2)],
                ib[(1, 2)],
            ],
        ),
        &joint(
            "FreeJoint",
            "free",
            "/ground",
            [0.0; 3],
            "/bodyset/b",
            &coords,
            "",
        ),
        "",
        [0.0, -G, 0.0],
    );
    let model = Model::from_osim_str(&xml, "free").unwrap();
    assert_eq!(model.nq(), 6);
    let mut rng = Rng::new(3);
    for _ in 0..20 {
        let q = random_vec(6, 1.4, &mut rng);
        let qd = random_vec(6, 2.0, &mut rng);
        let qdd = random_vec(6, 5.0, &mut rng);
        let (b, c) = (q[1], q[2]);
        let (bd, cd) = (qd[1], qd[2]);
        let e = nalgebra::Matrix3::new(
            b.cos() * c.cos(),
            c.sin(),
            0.0,
            -b.cos() * c.sin(),
            c.cos(),
            0.0,
            b.sin(),
            0.0,
            1.0,
        );
        let ed = nalgebra::Matrix3::new(
            -b.sin() * bd * c.cos() - b.cos() * c.sin() * cd,
            c.cos() * cd,
            0.0,
            b.sin() * bd * c.sin() - b.cos() * c.cos() * cd,
            -c.sin() * cd,
            0.0,
            b.cos() * bd,
            0.0,
            0.0,
        );
        let ad = nalgebra::Vector3::new(qd[0], qd[1], qd[2]);
        let w = e * ad;
        let m_rot = e.transpose() * ib * e;
        let c_rot = e.transpose() * (ib * ed * ad + w.cross(&(ib * w)));
        let mut m = vec![vec![0.0; 6]; 6];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = m_rot[(i, j)];
            }
            m[3 + i][3 + i] = mass;
        }
        let cqd = [c_rot[0], c_rot[1], c_rot[2], 0.0, 0.0, 0.0];
        let g = [0.0, 0.0, 0.0, 0.0, mass * G, 0.0];
        let rows: Vec<&[f64]> = m.iter().map(|r| r.as_slice()).collect();
        check(
            "free body",
            &compute(&model, &q, &qd, &qdd),
            &rows,
            &cqd,
            &g,
            &qdd,
        );
    }
}

#[test]
fn coupled_slider_crank_and_function_driven_axis_match_closed_form() {
    // Two independent mechanisms in one model, two independent coordinates (θ, φ):
    // 1. A crank (PinJoint about z, centre of mass at lc along its x axis) drives a slider
    //    that translates along u = (cos α, sin α, 0) by s = σ P(θ), P a cubic polynomial, through
    //    a CoordinateCouplerConstraint. With T = ½ (I_c + m1 lc² + m2 σ² P'²) θ̇² and
    //    V = m1 g lc sin θ + m2 g sin α σ P:
    //      M = I_c + m1 lc² + m2 σ² P'²,  C q̇ = m2 σ² P' P'' θ̇²,  G = m1 g lc cos θ + m2 g sin α σ P'.
    // 2. A CustomJoint rotating by φ about z whose origin also slides along x by Q(φ) (a
    //    function-driven translation, like a knee). With r = R_z(φ) c the centre of mass offset:
    //      M = m (Q'² − 2 Q' r_y + |c|²) + I_zz,  C q̇ = m (Q' Q'' − Q'' r_y − Q' r_x) φ̇²,  G = m g r_x.
    let (m1, lc, ic, m2, alpha, sigma) = (1.5, 0.12, 0.01, 2.5, 0.4_f64, 0.8);
    let p = [0.02, -0.05, 0.3, 0.1]; // P(θ) = 0.02θ³ − 0.05θ² + 0.3θ + 0.1 (highest power first)
    let (m3, cx, cy, izz) = (1.1, 0.07, -0.2, 0.013);
    let qp = [-0.01, 0.03, 0.02, -0.004]; // Q(φ)
    let bodies = body(
        "crank",
        m1,
        [lc, 0.0, 0.0],
        [0.012, 0.015, ic, 0.0, 0.0, 0.0],
    ) + &body(
        "slider",
        m2,
        [0.01, 0.02, 0.0],
        [0.01, 0.01, 0.01, 0.0, 0.0, 0.0],
    ) + &body(
        "shank",
        m3,
        [cx, cy, 0.0],
        [0.014, 0.004, izz, 0.0, 0.0, 0.0],
    );
    let poly = |c: &[f64; 4]| {
        format!(
            "<PolynomialFunction><coefficients>{} {} {} {}</coefficients></PolynomialFunction>",
            c[0], c[1], c[2], c[3]
        )
    };
    let u = [alpha.cos(), alpha.sin(), 0.0];
    let slider_st = spatial_transform([
        ("", [0.0, 0.0, 1.0], ZERO),
        ("", [1.0, 0.0, 0.0], ZERO),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("s", u, IDENTITY),
        ("", [-u[1], u[0], 0.0], ZERO),
        ("", [0.0, 0.0, 1.0], ZERO),
    ]);
    let knee_st = spatial_transform([
        ("phi", [0.0, 0.0, 1.0], IDENTITY),
        ("", [1.0, 0.0, 0.0], ZERO),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("phi", [1.0, 0.0, 0.0], &poly(&qp)),
        ("", [0.0, 1.0, 0.0], ZERO),
        ("", [0.0, 0.0, 1.0], ZERO),
    ]);
    let joints = joint(
        "PinJoint",
        "crank_pin",
        "/ground",
        [0.0; 3],
        "/bodyset/crank",
        &[coordinate("theta", [-2.0, 2.0])],
        "",
    ) + &joint(
        "CustomJoint",
        "slide",
        "/ground",
        [0.3, 0.0, 0.0],
        "/bodyset/slider",
        &[coordinate("s", [-1.0, 1.0])],
        &slider_st,
    ) + &joint(
        "CustomJoint",
        "knee",
        "/ground",
        [0.0, 1.0, 0.0],
        "/bodyset/shank",
        &[coordinate("phi", [-2.0, 2.0])],
        &knee_st,
    );
    let coupler = format!(
        "<CoordinateCouplerConstraint name=\"crank_drives_slider\"><isEnforced>true</isEnforced>\
         <coupled_coordinates_function>{}</coupled_coordinates_function>\
         <independent_coordinate_names>theta</independent_coordinate_names>\
         <dependent_coordinate_name>s</dependent_coordinate_name><scale_factor>{sigma}</scale_factor>\
         </CoordinateCouplerConstraint>",
        poly(&p)
    );
    let model = Model::from_osim_str(
        &osim(&bodies, &joints, &coupler, [0.0, -G, 0.0]),
        "slider-crank",
    )
    .unwrap();
    assert_eq!(model.q_names(), vec!["theta", "phi"]);
    let cubic = |c: &[f64; 4], x: f64| {
        (
            ((c[0] * x + c[1]) * x + c[2]) * x + c[3],
            (3.0 * c[0] * x + 2.0 * c[1]) * x + c[2],
            6.0 * c[0] * x + 2.0 * c[1],
        )
    };
    let mut rng = Rng::new(4);
    for _ in 0..20 {
        let q = [rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)];
        let qd = [rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0)];
        let qdd = [rng.uniform(-10.0, 10.0), rng.uniform(-10.0, 10.0)];
        let (th, ph) = (q[0], q[1]);
        let (_, p1, p2) = cubic(&p, th);
        let m_crank = ic + m1 * lc * lc + m2 * sigma * sigma * p1 * p1;
        let c_crank = m2 * sigma * sigma * p1 * p2 * qd[0] * qd[0];
        let g_crank = m1 * G * lc * th.cos() + m2 * G * alpha.sin() * sigma * p1;
        let (_, q1, q2) = cubic(&qp, ph);
        let (rx, ry) = (cx * ph.cos() - cy * ph.sin(), cx * ph.sin() + cy * ph.cos());
        let m_knee = m3 * (q1 * q1 - 2.0 * q1 * ry + cx * cx + cy * cy) + izz;
        let c_knee = m3 * (q1 * q2 - q2 * ry - q1 * rx) * qd[1] * qd[1];
        let g_knee = m3 * G * rx;
        check(
            "slider-crank",
            &compute(&model, &q, &qd, &qdd),
            &[&[m_crank, 0.0], &[0.0, m_knee]],
            &[c_crank, c_knee],
            &[g_crank, g_knee],
            &qdd,
        );
    }
}

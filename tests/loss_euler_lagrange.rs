//! The Euler–Lagrange loss: every gradient against central differences of the loss on the
//! default model (its contact spheres), gait2392 and Rajagopal2016; a consistent motion has
//! zero loss, and perturbing τ or q̈ by δ raises it by w_j δ² and δ² ‖M v‖² (M from `crba`).

mod common;
use common::*;
use musculo::dynamics::{contact_jacobian, crba, forward_kinematics, rnea};
use musculo::loss::{EulerLagrange, EulerLagrangeBatch, EulerLagrangeOutput, LossContact};
use musculo::solve::contact::ContactSet;
use musculo::spatial::Vec3;
use musculo::{Data, Model};
use nalgebra::{DMatrix, DVector};

#[derive(Clone)]
struct Inputs {
    frames: usize,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
    lambda: Vec<f64>,
}

impl Inputs {
    fn random(model: &Model, loss: &EulerLagrange, frames: usize, seed: u64) -> Inputs {
        let (n, p) = (model.nq(), loss.contacts.len());
        let mut rng = Rng::new(seed);
        Inputs {
            frames,
            q: random_vec(frames * n, 0.8, &mut rng),
            qd: random_vec(frames * n, 2.0, &mut rng),
            qdd: random_vec(frames * n, 5.0, &mut rng),
            tau: random_vec(frames * n, 50.0, &mut rng),
            lambda: random_vec(frames * 3 * p, 200.0, &mut rng),
        }
    }

    /// q, q̇, q̈, τ, λ by index.
    fn field(&mut self, k: usize) -> &mut Vec<f64> {
        match k {
            0 => &mut self.q,
            1 => &mut self.qd,
            2 => &mut self.qdd,
            3 => &mut self.tau,
            _ => &mut self.lambda,
        }
    }

    fn batch(&self) -> EulerLagrangeBatch<'_> {
        EulerLagrangeBatch {
            frames: self.frames,
            q: &self.q,
            qd: &self.qd,
            qdd: &self.qdd,
            tau: &self.tau,
            lambda: &self.lambda,
        }
    }
}

fn loss_of(model: &Model, loss: &EulerLagrange, x: &Inputs) -> f64 {
    let mut out = EulerLagrangeOutput::default();
    loss.evaluate(model, &x.batch(), false, &mut out).unwrap();
    out.loss
}

/// max over inputs of |analytic − central difference| / max |gradient of that input|.
fn worst_gradient_error(model: &Model, loss: &EulerLagrange, seed: u64) -> f64 {
    let x = Inputs::random(model, loss, 2, seed);
    let mut out = EulerLagrangeOutput::default();
    loss.evaluate(model, &x.batch(), true, &mut out).unwrap();
    let mut worst: f64 = 0.0;
    let grads = [
        out.grad_q,
        out.grad_qd,
        out.grad_qdd,
        out.grad_tau,
        out.grad_lambda,
    ];
    let mut x = x;
    for (k, g) in grads.iter().enumerate() {
        let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (i, gi) in g.iter().enumerate() {
            // a relative step: the loss is a polynomial of degree 2 in τ, λ and q̈
            let v0 = x.field(k)[i];
            let h = 1e-6 * v0.abs().max(1.0);
            x.field(k)[i] = v0 + h;
            let lp = loss_of(model, loss, &x);
            x.field(k)[i] = v0 - h;
            let lm = loss_of(model, loss, &x);
            x.field(k)[i] = v0;
            let fd = (lp - lm) / (2.0 * h);
            worst = worst.max((gi - fd).abs() / scale);
        }
    }
    worst
}

fn default_loss(model: &Model) -> EulerLagrange {
    EulerLagrange::new().with_contact_set(&ContactSet::from_model(model).unwrap())
}

#[test]
fn gradients_equal_finite_differences_on_the_default_model() {
    let model = Model::default_fullbody();
    let mut loss = default_loss(&model);
    assert!(loss.contacts.len() >= 4, "{} contacts", loss.contacts.len());
    let e = worst_gradient_error(&model, &loss, 41);
    eprintln!(
        "default model ({} contacts): worst {e:.2e}",
        loss.contacts.len()
    );
    assert!(e < 1e-6, "worst relative error {e:.2e}");
    let mut rng = Rng::new(5);
    loss.weights = (0..model.nq()).map(|_| rng.uniform(0.1, 3.0)).collect();
    let e = worst_gradient_error(&model, &loss, 42);
    eprintln!("default model, random weights: worst {e:.2e}");
    assert!(e < 1e-6, "weighted: worst relative error {e:.2e}");
}

#[test]
fn gradients_equal_finite_differences_on_gait2392_and_rajagopal2016() {
    for rel in [
        "opensim-models/Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
        "opensim-models/Models/Rajagopal/Rajagopal2016.osim",
    ] {
        let Some(path) = reference_file(rel) else {
            return;
        };
        let model = Model::from_osim_file(&path).unwrap();
        // spheres of 3 cm under the heels and toes (these models have no contact geometry)
        let contacts = ["calcn_r", "calcn_l", "toes_r", "toes_l"]
            .iter()
            .map(|b| LossContact {
                name: b.to_string(),
                body: model.body_index(b).unwrap(),
                location_in_body: Vec3::new(0.05, -0.01, 0.0),
                offset_in_ground: Vec3::new(0.0, -0.03, 0.0),
            })
            .collect();
        let loss = EulerLagrange {
            contacts,
            weights: vec![],
        };
        let e = worst_gradient_error(&model, &loss, 43);
        eprintln!("{rel} ({} contacts): worst {e:.2e}", loss.contacts.len());
        assert!(e < 1e-6, "{rel}: worst relative error {e:.2e}");
    }
}

#[test]
fn a_consistent_motion_has_zero_loss_and_perturbations_raise_it_as_expected() {
    let model = Model::default_fullbody();
    let loss = default_loss(&model);
    let (n, p) = (model.nq(), loss.contacts.len());
    let mut x = Inputs::random(&model, &loss, 3, 44);
    // τ = τ_ID − J_cᵀ λ with J_c of the lowest points of the spheres, built independently
    let mut data = Data::new(&model);
    for f in 0..x.frames {
        let r = f * n..(f + 1) * n;
        let tau_id = rnea(
            &model,
            &mut data,
            &x.q[r.clone()],
            &x.qd[r.clone()],
            &x.qdd[r.clone()],
        )
        .unwrap()
        .clone();
        forward_kinematics(&model, &mut data, &x.q[r.clone()]).unwrap();
        let points: Vec<(usize, Vec3)> = loss
            .contacts
            .iter()
            .map(|c| {
                let rot = data.body_pose(c.body).0;
                (
                    c.body,
                    c.location_in_body + rot.transpose() * c.offset_in_ground,
                )
            })
            .collect();
        let mut jc = DMatrix::zeros(3 * p, n);
        contact_jacobian(&model, &data, &points, &mut jc).unwrap();
        let lambda = DVector::from_column_slice(&x.lambda[f * 3 * p..(f + 1) * 3 * p]);
        let tau = tau_id - jc.transpose() * lambda;
        x.tau[r].copy_from_slice(tau.as_slice());
    }
    let l0 = loss_of(&model, &loss, &x);
    let scale: f64 = x.tau.iter().map(|v| v * v).sum();
    eprintln!("consistent motion: L = {l0:.3e} (Σ τ² = {scale:.3e})");
    assert!(l0 < 1e-20 * scale, "L = {l0:.3e}");

    // τ_j + δ on frame 1: L = δ²
    let (delta, j) = (0.7, 6);
    let mut y = x.clone();
    y.tau[n + j] += delta;
    let l = loss_of(&model, &loss, &y);
    assert!(
        (l - delta * delta).abs() < 1e-9,
        "τ + δ: L = {l}, expected {}",
        delta * delta
    );

    // q̈ + δ v on frame 2: L = δ² ‖M v‖²
    let mut rng = Rng::new(45);
    let v = DVector::from_vec(random_vec(n, 1.0, &mut rng));
    let mut y = x.clone();
    for (k, vk) in v.iter().enumerate() {
        y.qdd[2 * n + k] += delta * vk;
    }
    let m = crba(&model, &mut data, &x.q[2 * n..3 * n]).unwrap().clone();
    let expected = delta * delta * (&m * &v).norm_squared();
    let l = loss_of(&model, &loss, &y);
    assert!(
        (l - expected).abs() < 1e-9 * expected,
        "q̈ + δv: L = {l}, expected {expected}"
    );
}

#[test]
fn bad_inputs_are_errors() {
    let model = Model::default_fullbody();
    let loss = default_loss(&model);
    let x = Inputs::random(&model, &loss, 2, 46);
    let mut out = EulerLagrangeOutput::default();
    let mut b = x.batch();
    b.tau = &x.tau[..10];
    let e = loss.evaluate(&model, &b, false, &mut out).unwrap_err();
    assert!(e.to_string().contains("tau"), "{e}");
    let mut weighted = loss.clone();
    weighted.weights = vec![1.0; 3];
    let e = weighted
        .evaluate(&model, &x.batch(), false, &mut out)
        .unwrap_err();
    assert!(e.to_string().contains("3 weights"), "{e}");
    weighted.weights = vec![-1.0; model.nq()];
    let e = weighted
        .evaluate(&model, &x.batch(), false, &mut out)
        .unwrap_err();
    assert!(e.to_string().contains("≥ 0"), "{e}");
    let mut q = x.q.clone();
    q[model.nq() + 2] = f64::NAN;
    let mut b = x.batch();
    b.q = &q;
    let e = loss.evaluate(&model, &b, false, &mut out).unwrap_err();
    assert!(e.to_string().contains("frame 1"), "{e}");
}

/// A tensor file the loss cannot read is an error naming the file and the array, through the
/// reader every command shares (`TensorFrames`) and through `musculo loss` (non-zero exit):
/// arrays of 0 frames (not an L_euler of 0 over no frames), `qd` with other frames than `q`
/// (the counts as numbers, no Rust `Some(..)`), and a NaN named by array and frame.
#[test]
fn tensor_files_without_frames_or_with_bad_arrays_are_named_errors() {
    use musculo::loss::tensor_file::TensorFrames;
    let model = Model::default_fullbody();
    let n = model.nq();
    let dir = ScratchDir::new("loss-bad-tensor-file");
    // q, qd, qdd, tau of `frames[k]` rows each, zero but for `edit`
    let write = |name: &str, frames: [usize; 4], edit: &dyn Fn(&str, &mut [f64])| {
        let arrays: Vec<(String, ndarray::ArrayD<f64>)> = ["q", "qd", "qdd", "tau"]
            .iter()
            .zip(frames)
            .map(|(a, t)| {
                let mut values = vec![0.0; t * n];
                edit(a, &mut values);
                let array = ndarray::ArrayD::from_shape_vec(vec![t, n], values).unwrap();
                (a.to_string(), array)
            })
            .collect();
        let views: Vec<_> = arrays.iter().map(|(k, a)| (k.as_str(), a.view())).collect();
        let path = dir.join(name);
        musculo::motion::npy::write_npz(&path, &views, false).unwrap();
        (path, arrays)
    };
    let cases: [(&str, [usize; 4], &dyn Fn(&str, &mut [f64]), &str); 4] = [
        ("empty.npz", [0; 4], &|_, _| {}, "has 0 frames"),
        (
            "mismatch.npz",
            [110, 120, 110, 110],
            &|_, _| {},
            "`qd` has 120 frames, `q` has 110",
        ),
        (
            "nan.npz",
            [3; 4],
            &|a, v| {
                if a == "tau" {
                    v[n + 7] = f64::NAN;
                }
            },
            &format!("`tau` is NaN at frame 1 (value 7 of the frame's {n})"),
        ),
        (
            "huge.npz",
            [3; 4],
            &|a, v| {
                if a == "q" {
                    v[2 * n + 4] = 7.9e32;
                }
            },
            &format!("`q` is 7.9e32 at frame 2 (value 4 of the frame's {n}), beyond ±1e15"),
        ),
    ];
    for (name, frames, edit, said) in cases {
        let (path, arrays) = write(name, frames, edit);
        let e = TensorFrames::from_arrays(&arrays, &model, name)
            .expect_err(name)
            .to_string();
        assert!(e.contains(name) && e.contains(said), "{e}");
        assert!(!e.contains("Some("), "{e}");
        let (ok, stdout, err) = musculo_cli("loss {}", &[&path]);
        assert!(!ok, "{name}: musculo loss succeeded: {stdout}");
        assert!(err.contains(name) && err.contains(said), "{err}");
        // evaluate and report read tensor files through the same reader: the clip fails
        let out = dir.join(&format!("{name}.json"));
        let (ok, stdout, err) = musculo_cli("evaluate --input {} --out {}", &[&path, &out]);
        assert!(!ok, "{name}: musculo evaluate succeeded: {stdout}");
        assert!(err.contains(name) && err.contains(said), "{err}");
        let pages = dir.join(&format!("{name}-report"));
        let (ok, stdout, err) = musculo_cli("report {} --out {}", &[&path, &pages]);
        assert!(!ok, "{name}: musculo report succeeded: {stdout}");
        assert!(err.contains(name) && err.contains(said), "{err}");
    }
}

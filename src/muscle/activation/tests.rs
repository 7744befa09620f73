//! Tests of the activation dynamics against closed forms and OpenSim's formulas.
use super::*;
use crate::model::RawElement;

const THELEN: ActivationDynamics = ActivationDynamics::Thelen2003 {
    activation_time_constant: 0.01,
    deactivation_time_constant: 0.04,
    minimum_activation: 0.01,
};

fn de_groote(smoothing: f64) -> ActivationDynamics {
    ActivationDynamics::DeGroote2016 {
        activation_time_constant: 0.015,
        deactivation_time_constant: 0.06,
        smoothing,
    }
}

const DEPRECATED: ActivationDynamics = ActivationDynamics::THELEN2003_DEPRECATED_DEFAULT;

fn grid(t_end: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|i| t_end * i as f64 / n as f64).collect()
}

/// The a in [lo, hi] with t_of(a) = t, t_of increasing from lo to hi, by bisection.
fn solve_increasing(t_of: impl Fn(f64) -> f64, t: f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if t_of(mid) < t { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// Exact step responses of ȧ = (u − a)/(τ_act z(a)) (rise) and
/// ȧ = (u − a) z(a)/τ_deact (fall), by separation of variables:
/// rise: t = τ_act [1.5 (a0 − a) + z(u) ln((u − a0)/(u − a))],
/// fall: t = τ_deact / z(u) [ln((a0 − u)/(a − u)) + ln(z(a)/z(a0))].
fn exact_step(tau_act: f64, tau_deact: f64, u: f64, a0: f64, t: f64) -> f64 {
    if u > a0 {
        let t_of = |a: f64| tau_act * (1.5 * (a0 - a) + z(u) * ((u - a0) / (u - a)).ln());
        solve_increasing(t_of, t, a0, u)
    } else {
        let t_of = |a: f64| tau_deact / z(u) * (((a0 - u) / (a - u)).ln() + (z(a) / z(a0)).ln());
        // t_of decreases in a: solve for −a.
        -solve_increasing(|m| t_of(-m), t, -a0, -u)
    }
}

#[test]
fn steady_state_is_activation_equal_to_excitation() {
    for dynamics in [THELEN, DEPRECATED, de_groote(0.1), de_groote(10.0)] {
        let (lo, hi) = dynamics.range();
        for u in [lo, 0.02, 0.3, 0.77, hi] {
            assert_eq!(dynamics.derivative(u, u), 0.0);
            let t = grid(0.5, 10);
            let a = dynamics
                .integrate(&t, &vec![u; t.len()], Interpolation::Linear, u, &t)
                .unwrap();
            assert!(a.iter().all(|&a| (a - u).abs() < 1e-15), "{dynamics:?} {u}");
        }
    }
}

#[test]
fn derivative_matches_opensim_formulas_by_hand() {
    // Thelen, rising: (0.5 − 0.2)/(0.01 (0.5 + 0.3)) = 37.5
    assert!((THELEN.derivative(0.5, 0.2) - 37.5).abs() < 1e-12);
    // Thelen, falling: (0.1 − 0.6) (0.5 + 0.9)/0.04 = −17.5
    assert!((THELEN.derivative(0.1, 0.6) + 17.5).abs() < 1e-12);
    // Thelen clamps a below a_min: as if a = 0.01.
    assert_eq!(THELEN.derivative(0.5, -0.3), THELEN.derivative(0.5, 0.01));
    // De Groote, b = 10, u − a = 0.3: f = ½ tanh 3.
    let f = 0.5 * 3.0_f64.tanh();
    let expected = ((f + 0.5) / (0.015 * 0.8) + (0.5 - f) * 0.8 / 0.06) * 0.3;
    assert!((de_groote(10.0).derivative(0.5, 0.2) - expected).abs() < 1e-12);
}

#[test]
fn thelen_step_up_and_down_match_the_exact_solution() {
    let t = grid(0.3, 300);
    for (u, a0) in [
        (0.8, 0.05),
        (1.0, 0.01),
        (0.05, 0.9),
        (0.01, 1.0),
        (0.5, 0.45),
    ] {
        let a = THELEN
            .integrate(&[0.0, 0.3], &[u, u], Interpolation::Linear, a0, &t)
            .unwrap();
        let worst = t
            .iter()
            .zip(&a)
            .map(|(&t, &a)| (a - exact_step(0.01, 0.04, u, a0, t)).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "u {u} a0 {a0}: error {worst:e}");
    }
}

#[test]
fn opensim2_thelen_step_responses_are_exponentials() {
    // Constant τ: a(t) = u + (a0 − u) exp(−t/τ), τ = τ_act rising, τ_deact falling.
    let t = grid(0.3, 300);
    for (u, a0, tau) in [
        (0.8, 0.05, 0.01),
        (1.0, 0.0, 0.01),
        (0.05, 0.9, 0.04),
        (0.0, 1.0, 0.04),
    ] {
        let a = DEPRECATED
            .integrate(&[0.0, 0.3], &[u, u], Interpolation::HoldNext, a0, &t)
            .unwrap();
        for (&t, &a) in t.iter().zip(&a) {
            let exact = u + (a0 - u) * (-t / tau).exp();
            assert!(
                (a - exact).abs() < 1e-8,
                "u {u} a0 {a0} t {t}: {a} vs {exact}"
            );
        }
    }
}

#[test]
fn de_groote_with_a_sharp_switch_follows_the_same_exact_solution() {
    // With b large, tanh is ±1 except within a few 1/b of u = a: De Groote's rise and fall
    // are then Thelen's (without a_min). Compare while |u − a| > 20/b.
    let b = 1e5;
    let t = grid(0.2, 200);
    for (u, a0) in [(0.9, 0.0), (0.0, 1.0), (0.3, 0.7)] {
        let a = de_groote(b)
            .integrate(&[0.0, 0.2], &[u, u], Interpolation::HoldPrevious, a0, &t)
            .unwrap();
        for (&t, &a) in t.iter().zip(&a) {
            if (u - a).abs() > 20.0 / b {
                let exact = exact_step(0.015, 0.06, u, a0, t);
                assert!(
                    (a - exact).abs() < 1e-6,
                    "u {u} a0 {a0} t {t}: {a} vs {exact}"
                );
            }
        }
    }
}

#[test]
fn de_groote_with_default_smoothing_blends_both_rates() {
    // b = 0.1: tanh ≈ 0 so both rates count about half, slower than Thelen's rise.
    let blended = de_groote(0.1).derivative(1.0, 0.0);
    let rise_only = 1.0 / (0.015 * 0.5);
    assert!(blended < 0.6 * rise_only && blended > 0.5 * rise_only);
}

#[test]
fn interpolation_modes_read_the_samples_as_documented() {
    // One interval, u from 0.2 to 0.8, a0 = 0.2.
    let (time, u) = ([0.0, 0.1], [0.2, 0.8]);
    let end = |mode| THELEN.integrate(&time, &u, mode, 0.2, &[0.1]).unwrap()[0];
    // HoldPrevious keeps u = 0.2 = a: nothing moves.
    assert!((end(Interpolation::HoldPrevious) - 0.2).abs() < 1e-15);
    // HoldNext applies u = 0.8 over the whole interval: the exact step response.
    let exact = exact_step(0.01, 0.04, 0.8, 0.2, 0.1);
    assert!((end(Interpolation::HoldNext) - exact).abs() < 1e-8);
    // Linear lies in between.
    let linear = end(Interpolation::Linear);
    assert!(linear > 0.2 + 1e-3 && linear < exact - 1e-3);
}

#[test]
fn excitation_from_forward_activation_recovers_the_excitation() {
    let t = grid(1.0, 1000);
    let u: Vec<f64> = t
        .iter()
        .map(|&t| {
            let w = 2.0 * std::f64::consts::PI;
            0.45 + 0.3 * (w * 2.0 * t).sin() + 0.1 * (w * 5.0 * t + 1.0).sin()
        })
        .collect();
    for dynamics in [THELEN, DEPRECATED, de_groote(0.1), de_groote(10.0)] {
        let a = dynamics
            .integrate(&t, &u, Interpolation::Linear, 0.3, &t)
            .unwrap();
        let estimate = dynamics.excitation_from_activation(&t, &a).unwrap();
        assert!(
            estimate.clamped.is_empty(),
            "{dynamics:?}: {:?}",
            estimate.clamped
        );
        // Away from the ends, where the natural spline's end conditions do not reach.
        let worst = (20..t.len() - 20)
            .map(|i| (estimate.excitation[i] - u[i]).abs())
            .fold(0.0, f64::max);
        let rms = ((20..t.len() - 20)
            .map(|i| (estimate.excitation[i] - u[i]).powi(2))
            .sum::<f64>()
            / (t.len() - 40) as f64)
            .sqrt();
        // Thelen's ä jumps where u crosses a (the τ switches), so any smooth derivative
        // is off by O(h) at a sample or two there (1e-3 here); elsewhere it is ~1e-5.
        assert!(
            worst < 2e-3 && rms < 1e-4,
            "{dynamics:?}: worst {worst:e}, rms {rms:e}"
        );
    }
}

#[test]
fn excitation_for_rate_inverts_the_derivative() {
    for dynamics in [
        THELEN,
        DEPRECATED,
        de_groote(0.1),
        de_groote(10.0),
        de_groote(1e4),
    ] {
        for a in [0.01, 0.2, 0.5, 0.99] {
            for u in [0.01, 0.1, 0.5, 0.9, 1.0, 1.7, -0.4] {
                let rate = dynamics.derivative(u, a);
                let back = dynamics.excitation_for_rate(a, rate);
                assert!((back - u).abs() < 1e-9, "{dynamics:?} a {a} u {u}: {back}");
            }
        }
    }
}

#[test]
fn excitation_beyond_the_range_is_clamped_and_reported() {
    // Activation jumps from 0.1 to 0.9 in 5 ms and back: faster than u ∈ [a_min, 1] allows.
    let t = grid(0.2, 200);
    let a: Vec<f64> = t
        .iter()
        .map(|&t| {
            0.1 + 0.8
                * (1.0 / (1.0 + (-(t - 0.05) / 0.001).exp())
                    - 1.0 / (1.0 + (-(t - 0.15) / 0.001).exp()))
        })
        .collect();
    for dynamics in [THELEN, DEPRECATED, de_groote(10.0)] {
        let (lo, hi) = dynamics.range();
        let estimate = dynamics.excitation_from_activation(&t, &a).unwrap();
        assert!(
            estimate
                .clamped
                .iter()
                .any(|c| c.applied == hi && c.amount() > 0.5)
        );
        assert!(
            estimate
                .clamped
                .iter()
                .any(|c| c.applied == lo && c.amount() < -0.5)
        );
        // Exactly the samples whose required excitation is out of range are listed.
        let expected: Vec<usize> = (0..t.len())
            .filter(|&i| {
                let u = dynamics.excitation_for_rate(a[i], estimate.activation_rate[i]);
                !(lo..=hi).contains(&u)
            })
            .collect();
        let listed: Vec<usize> = estimate.clamped.iter().map(|c| c.index).collect();
        assert_eq!(listed, expected);
        for c in &estimate.clamped {
            assert_eq!(estimate.excitation[c.index], c.applied);
            assert_eq!(c.time, t[c.index]);
        }
        assert!(estimate.excitation.iter().all(|u| (lo..=hi).contains(u)));
    }
}

#[test]
fn bad_inputs_are_errors_naming_the_argument() {
    let argument = |r: Result<Vec<f64>>| match r {
        Err(Error::InvalidArgument { argument, .. }) => argument,
        other => panic!("{other:?}"),
    };
    let lin = Interpolation::Linear;
    let t = [0.0, 0.1, 0.2];
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5, 0.5], lin, 0.5, &[])),
        "excitation"
    );
    assert_eq!(
        argument(THELEN.integrate(&[0.0, 0.1, 0.1], &[0.5; 3], lin, 0.5, &[])),
        "time"
    );
    assert_eq!(
        argument(THELEN.integrate(&[0.0, f64::NAN, 1.0], &[0.5; 3], lin, 0.5, &[])),
        "time"
    );
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5, f64::NAN, 0.5], lin, 0.5, &[])),
        "excitation"
    );
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5, 0.0, 0.5], lin, 0.5, &[])),
        "excitation"
    );
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5, 1.2, 0.5], lin, 0.5, &[])),
        "excitation"
    );
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5; 3], lin, 0.0, &[])),
        "initial_activation"
    );
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5; 3], lin, 0.5, &[0.3])),
        "output_times"
    );
    assert_eq!(
        argument(THELEN.integrate(&t, &[0.5; 3], lin, 0.5, &[0.2, 0.1])),
        "output_times"
    );
    assert_eq!(
        argument(THELEN.integrate(&[0.0], &[0.5], lin, 0.5, &[])),
        "time"
    );
    assert_eq!(
        argument(THELEN.integrate(&[0.0, 1e9], &[0.5; 2], lin, 0.5, &[])),
        "time"
    );
    let bad = ActivationDynamics::Thelen2003 {
        activation_time_constant: -0.01,
        deactivation_time_constant: 0.04,
        minimum_activation: 0.0,
    };
    assert_eq!(
        argument(bad.integrate(&t, &[0.5; 3], lin, 0.5, &[])),
        "activation_time_constant"
    );
    let bad = ActivationDynamics::Thelen2003 {
        activation_time_constant: 0.01,
        deactivation_time_constant: 0.04,
        minimum_activation: 1.0,
    };
    assert_eq!(
        argument(bad.integrate(&t, &[1.0; 3], lin, 1.0, &[])),
        "minimum_activation"
    );
    assert_eq!(
        argument(de_groote(0.0).integrate(&t, &[0.5; 3], lin, 0.5, &[])),
        "smoothing"
    );
    assert_eq!(
        argument(de_groote(1.0).integrate(&t, &[0.5; 3], lin, -0.1, &[])),
        "initial_activation"
    );

    let inverse = |a: &[f64]| match THELEN.excitation_from_activation(&t, a) {
        Err(Error::InvalidArgument { argument, .. }) => argument,
        other => panic!("{other:?}"),
    };
    assert_eq!(inverse(&[0.5, 0.0, 0.5]), "activation");
    assert_eq!(inverse(&[0.5, f64::INFINITY, 0.5]), "activation");
    assert_eq!(inverse(&[0.5, 0.5]), "activation");
}

fn muscle(kind: &str, properties: &[(&str, &str)]) -> ForceElement {
    ForceElement {
        applies_force: true,
        actuator: None,
        name: "m".into(),
        kind: kind.into(),
        path: None,
        raw: std::sync::Arc::new(RawElement {
            tag: kind.into(),
            name: Some("m".into()),
            children: properties
                .iter()
                .map(|(tag, text)| RawElement {
                    tag: tag.to_string(),
                    text: text.to_string(),
                    line: 9,
                    ..Default::default()
                })
                .collect(),
            ..Default::default()
        }),
        line: 7,
        file: "test.osim".into(),
    }
}

#[test]
fn from_muscle_reads_properties_and_class_defaults() {
    let m = muscle(
        "Thelen2003Muscle",
        &[("activation_time_constant", " 0.02 ")],
    );
    assert_eq!(
        ActivationDynamics::from_muscle(&m, "x.osim").unwrap(),
        ActivationDynamics::Thelen2003 {
            activation_time_constant: 0.02,
            deactivation_time_constant: 0.05,
            minimum_activation: 0.01
        }
    );
    let m = muscle(
        "DeGrooteFregly2016Muscle",
        &[("activation_dynamics_smoothing", "10")],
    );
    assert_eq!(
        ActivationDynamics::from_muscle(&m, "x.osim").unwrap(),
        de_groote(10.0)
    );
    let m = muscle(
        "Thelen2003Muscle_Deprecated",
        &[("deactivation_time_constant", "0.05")],
    );
    assert_eq!(
        ActivationDynamics::from_muscle(&m, "x.osim").unwrap(),
        ActivationDynamics::Thelen2003Deprecated {
            activation_time_constant: 0.01,
            deactivation_time_constant: 0.05
        }
    );
    let m = muscle("Millard2012EquilibriumMuscle", &[]);
    assert_eq!(
        ActivationDynamics::from_muscle(&m, "x.osim").unwrap(),
        ActivationDynamics::MILLARD2012_DEFAULT
    );
    let error = |m: &ForceElement| match ActivationDynamics::from_muscle(m, "x.osim") {
        Err(Error::Model {
            file,
            line,
            element,
            ..
        }) => {
            assert_eq!(
                (file.as_str(), element.as_str()),
                ("x.osim", &*format!("{} \"m\"", m.kind))
            );
            line
        }
        other => panic!("{other:?}"),
    };
    assert_eq!(
        error(&muscle(
            "Thelen2003Muscle",
            &[("deactivation_time_constant", "fast")]
        )),
        9
    );
    assert_eq!(
        error(&muscle(
            "Thelen2003Muscle",
            &[("minimum_activation", "0.001")]
        )),
        7
    );
    assert_eq!(
        error(&muscle(
            "Thelen2003Muscle",
            &[("activation_time_constant", "0")]
        )),
        7
    );
    assert_eq!(
        error(&muscle(
            "Thelen2003Muscle",
            &[("ignore_activation_dynamics", "true")]
        )),
        9
    );
    assert_eq!(error(&muscle("McKibbenActuator", &[])), 7);
}

#[test]
fn natural_cubic_slopes_match_the_general_natural_spline() {
    use crate::model::natural_spline::NaturalSpline;
    let t: Vec<f64> = (0..40)
        .map(|i| i as f64 * 0.05 + 0.01 * ((i * 7 % 5) as f64))
        .collect();
    let y: Vec<f64> = t
        .iter()
        .map(|&x| (3.0 * x).sin() + 0.2 * (11.0 * x).cos())
        .collect();
    let slopes = super::natural_cubic_slopes(&t, &y);
    let spline = NaturalSpline::interpolating(2, t.clone(), y.clone()).unwrap();
    for (i, &ti) in t.iter().enumerate() {
        let expected = spline.derivative(ti, 1);
        assert!(
            (slopes[i] - expected).abs() < 1e-9 * (1.0 + expected.abs()),
            "{i}: {} vs {expected}",
            slopes[i]
        );
    }
    // two samples: the straight line; three: against the spline too
    assert!((super::natural_cubic_slopes(&[0.0, 2.0], &[1.0, 5.0])[1] - 2.0).abs() < 1e-15);
    let s3 = super::natural_cubic_slopes(&t[..3], &y[..3]);
    let sp3 = NaturalSpline::interpolating(2, t[..3].to_vec(), y[..3].to_vec()).unwrap();
    for i in 0..3 {
        assert!((s3[i] - sp3.derivative(t[i], 1)).abs() < 1e-9);
    }
}

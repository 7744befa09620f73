//! Agreement with OpenSim 4.6 itself: total path lengths recorded from the `opensim` Python
//! package for random segments (`opensim_reference.py` regenerates `opensim_reference.txt`).

use std::f64::consts::PI;

use super::super::*;
use crate::spatial::Vec3;

const REFERENCE: &str = include_str!("opensim_reference.txt");

struct Case {
    kind: String,
    method: Option<EllipsoidMethod>,
    quadrant: Quadrant,
    p: Vec3,
    s: Vec3,
    opensim: f64,
}

fn cases() -> Vec<Case> {
    REFERENCE
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let x: Vec<f64> = f[3..].iter().map(|v| v.parse().unwrap()).collect();
            Case {
                kind: f[0].to_string(),
                method: (f[1] != "-").then(|| EllipsoidMethod::parse(f[1]).unwrap()),
                quadrant: Quadrant::parse(f[2]).unwrap(),
                p: Vec3::new(x[0], x[1], x[2]),
                s: Vec3::new(x[3], x[4], x[5]),
                opensim: x[6],
            }
        })
        .collect()
}

fn wrap(c: &Case) -> Option<Wrapped> {
    match c.kind.as_str() {
        "sphere" => wrap_sphere(0.05, c.quadrant, &c.p, &c.s).wrapped(),
        "cylinder" => wrap_cylinder(0.05, 0.3, c.quadrant, &c.p, &c.s).wrapped(),
        "short_cylinder" => wrap_cylinder(0.005, 0.03, c.quadrant, &c.p, &c.s).wrapped(),
        "ellipsoid" => wrap_ellipsoid(
            &Vec3::new(0.06, 0.025, 0.04),
            c.quadrant,
            c.method.unwrap(),
            &c.p,
            &c.s,
        )
        .wrapped(),
        _ => wrap_torus(0.02, 0.06, c.quadrant, &c.p, &c.s).wrapped(),
    }
}

#[test]
fn path_lengths_match_opensim() {
    let all = cases();
    assert_eq!(all.len(), 599);
    let mut wraps = 0;
    for c in &all {
        let w = wrap(c);
        let straight = (c.p - c.s).norm();
        let mine = w.map_or(straight, |w| w.length);
        let opensim_wraps = (c.opensim - straight).abs() > 1e-12;
        wraps += w.is_some() as usize;
        let label = format!(
            "{} {:?} {:?} {:?} {:?}: mine {mine} OpenSim {}",
            c.kind, c.method, c.quadrant, c.p, c.s, c.opensim
        );
        assert_eq!(opensim_wraps, w.is_some(), "wrap decision: {label}");
        let tolerance = match c.kind.as_str() {
            "sphere" => 1e-13,
            // OpenSim iterates the helix only to 0.1° tangency.
            "cylinder" | "short_cylinder" => 1e-5,
            // OpenSim's tangent solve stops at a residual of ~1e-4; its arc is a polyline.
            "ellipsoid" => 5e-5,
            // The line point from a least-squares solve with tolerance 1e-4.
            _ => 2e-6,
        };
        assert!((mine - c.opensim).abs() <= tolerance, "{label}");
    }
    assert!(wraps > 150, "only {wraps} of the cases wrap");
}

/// OpenSim 4.6 gives this far-side sphere wrap (> half a turn, forced by the quadrant) a
/// negative surface length, hence a negative total path length −0.23589823112357977; the
/// geometric path is returned instead (a documented deviation).
#[test]
fn far_side_sphere_wrap_is_positive_where_opensim_goes_negative() {
    let r = 0.05;
    let d = 1.01 * r;
    let p = Vec3::new(d, 0.0, 0.0);
    let s = Vec3::new(d * 1f64.cos(), d * 1f64.sin(), 0.0);
    let near = wrap_sphere(r, Quadrant::All, &p, &s).wrapped().unwrap();
    assert!(
        (near.length - 0.050093859522116084).abs() < 1e-15,
        "OpenSim agrees here"
    );
    let far = wrap_sphere(r, Quadrant::Negative(1), &p, &s)
        .wrapped()
        .unwrap();
    let (h, beta) = ((d * d - r * r).sqrt(), (r / d).acos());
    assert!((far.length - (2.0 * h + r * (2.0 * PI - 1.0 - 2.0 * beta))).abs() < 1e-15);
    assert!((far.length - 0.2642531248810954).abs() < 1e-15);
    assert!(far.surface_length > PI * r);
}

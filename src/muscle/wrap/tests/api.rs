//! Parsing, degenerate input and the surface-path helper.

use super::super::*;
use crate::spatial::Vec3;

#[test]
fn quadrant_parse_accepts_opensim_strings_and_rejects_others() {
    use Quadrant::*;
    let cases = [
        ("all", All),
        ("All", All),
        ("ALL", All),
        ("Unassigned", All),
        ("x", Positive(0)),
        ("+x", Positive(0)),
        ("X", Positive(0)),
        ("+X", Positive(0)),
        ("-x", Negative(0)),
        ("-X", Negative(0)),
        ("y", Positive(1)),
        ("+Y", Positive(1)),
        ("-y", Negative(1)),
        ("z", Positive(2)),
        ("+z", Positive(2)),
        ("-Z", Negative(2)),
        (" -y ", Negative(1)),
    ];
    for (s, q) in cases {
        assert_eq!(Quadrant::parse(s), Ok(q), "{s:?}");
    }
    for bad in ["", "aLL", "w", "+-x", "xy", "--x", "+all", "1", "x+"] {
        let err = Quadrant::parse(bad).unwrap_err();
        assert!(err.contains("quadrant"), "{bad:?}: {err}");
    }
}

#[test]
fn ellipsoid_method_parse_accepts_opensim_strings_and_rejects_others() {
    use EllipsoidMethod::*;
    for (s, m) in [
        ("hybrid", Hybrid),
        ("Hybrid", Hybrid),
        ("HYBRID", Hybrid),
        ("Unassigned", Hybrid),
        ("midpoint", Midpoint),
        ("Midpoint", Midpoint),
        ("MIDPOINT", Midpoint),
        ("axial", Axial),
        ("Axial", Axial),
        ("AXIAL", Axial),
    ] {
        assert_eq!(EllipsoidMethod::parse(s), Ok(m), "{s:?}");
    }
    for bad in ["", "hYbrid", "mid", "axis", "fan"] {
        let err = EllipsoidMethod::parse(bad).unwrap_err();
        assert!(err.contains("method"), "{bad:?}: {err}");
    }
}

fn all_surfaces() -> [WrapSurface; 6] {
    [
        WrapSurface::Sphere { radius: 0.05 },
        WrapSurface::Cylinder {
            radius: 0.05,
            length: 0.2,
        },
        WrapSurface::Ellipsoid {
            radii: Vec3::new(0.05, 0.03, 0.04),
            method: EllipsoidMethod::Hybrid,
        },
        WrapSurface::Ellipsoid {
            radii: Vec3::new(0.05, 0.03, 0.04),
            method: EllipsoidMethod::Midpoint,
        },
        WrapSurface::Ellipsoid {
            radii: Vec3::new(0.05, 0.03, 0.04),
            method: EllipsoidMethod::Axial,
        },
        WrapSurface::Torus {
            inner_radius: 0.02,
            outer_radius: 0.06,
        },
    ]
}

#[test]
fn degenerate_inputs_give_none_without_panicking() {
    let p = Vec3::new(-0.2, 0.01, 0.003);
    let s = Vec3::new(0.2, 0.012, -0.004);
    let nan = Vec3::new(f64::NAN, 0.0, 0.0);
    let inf = Vec3::new(0.0, f64::INFINITY, 0.0);
    for surf in all_surfaces() {
        // A point inside the object (the torus' centre is in its hole, not inside it).
        let centre = match surf {
            WrapSurface::Torus { outer_radius, .. } => Vec3::new(outer_radius, 0.0, 0.005),
            _ => Vec3::zeros(),
        };
        for q in [Quadrant::All, Quadrant::Positive(1), Quadrant::Negative(2)] {
            assert!(surf.wrap(q, &nan, &s).wrapped().is_none(), "{surf:?} NaN P");
            assert!(surf.wrap(q, &p, &inf).wrapped().is_none(), "{surf:?} inf S");
            assert!(surf.wrap(q, &p, &p).wrapped().is_none(), "{surf:?} P = S");
            assert!(
                surf.wrap(q, &centre, &s).wrapped().is_none(),
                "{surf:?} P inside"
            );
        }
        assert!(
            surf.wrap(Quadrant::Positive(3), &p, &s).wrapped().is_none(),
            "{surf:?} bad axis"
        );
    }
    let bad_dims = [
        WrapSurface::Sphere { radius: 0.0 },
        WrapSurface::Sphere { radius: -1.0 },
        WrapSurface::Sphere { radius: f64::NAN },
        WrapSurface::Cylinder {
            radius: 0.0,
            length: 1.0,
        },
        WrapSurface::Cylinder {
            radius: 0.05,
            length: 0.0,
        },
        WrapSurface::Ellipsoid {
            radii: Vec3::new(0.05, 0.0, 0.04),
            method: EllipsoidMethod::Hybrid,
        },
        WrapSurface::Ellipsoid {
            radii: Vec3::new(0.05, f64::NAN, 0.04),
            method: EllipsoidMethod::Axial,
        },
        WrapSurface::Torus {
            inner_radius: 0.06,
            outer_radius: 0.02,
        },
        WrapSurface::Torus {
            inner_radius: 0.0,
            outer_radius: 0.02,
        },
    ];
    for surf in bad_dims {
        assert!(
            surf.wrap(Quadrant::All, &p, &s).wrapped().is_none(),
            "{surf:?}"
        );
    }
}

#[test]
fn surface_path_runs_on_the_surface_from_t1_to_t2_with_the_surface_length() {
    let p = Vec3::new(-0.15, 0.02, 0.03);
    let s = Vec3::new(0.12, 0.015, -0.04);
    let torus_p = Vec3::new(0.045, 0.002, 0.1);
    let torus_s = Vec3::new(0.046, -0.003, -0.1);
    for surf in all_surfaces() {
        let (pp, ss) = if matches!(surf, WrapSurface::Torus { .. }) {
            (torus_p, torus_s)
        } else {
            (p, s)
        };
        let w = surf
            .wrap(Quadrant::All, &pp, &ss)
            .wrapped()
            .unwrap_or_else(|| panic!("{surf:?} wraps"));
        let mut pts = [Vec3::zeros(); 2001];
        w.surface_path(&mut pts);
        assert_eq!(pts[0], w.t1);
        assert_eq!(pts[2000], w.t2);
        assert!((w.arc.point(0.0) - w.t1).norm() < 1e-12, "{surf:?} start");
        assert!((w.arc.point(1.0) - w.t2).norm() < 1e-12, "{surf:?} end");
        let polyline: f64 = pts.windows(2).map(|q| (q[1] - q[0]).norm()).sum();
        assert!(
            (polyline - w.surface_length).abs() < 1e-6 * w.surface_length,
            "{surf:?}: {polyline} vs {}",
            w.surface_length
        );
        for q in &pts {
            let off = match surf {
                WrapSurface::Sphere { radius } => q.norm() - radius,
                WrapSurface::Cylinder { radius, .. } => q.xy().norm() - radius,
                WrapSurface::Ellipsoid { radii, .. } => {
                    (q.x / radii.x).powi(2) + (q.y / radii.y).powi(2) + (q.z / radii.z).powi(2)
                        - 1.0
                }
                // On the local cylinder, not on the torus: checked in the torus tests.
                WrapSurface::Torus { .. } => 0.0,
            };
            assert!(off.abs() < 1e-12, "{surf:?} off surface by {off}");
        }
    }
}

#[test]
fn extreme_coordinates_do_not_panic() {
    let big = 1e200;
    for surf in all_surfaces() {
        for (p, s) in [
            (Vec3::new(-big, 0.001, 0.0), Vec3::new(big, 0.0, 0.001)),
            (Vec3::new(-1e-300, 0.2, 0.0), Vec3::new(1e-300, -0.2, 0.0)),
            (Vec3::new(0.2, 0.0, 0.0), Vec3::new(-0.2, 0.0, 0.0)),
            (Vec3::new(0.0, 0.0, 0.2), Vec3::new(0.0, 0.0, -0.2)),
        ] {
            for q in [Quadrant::All, Quadrant::Negative(0), Quadrant::Positive(2)] {
                if let Some(w) = surf.wrap(q, &p, &s).wrapped() {
                    assert!(
                        w.length.is_finite() && w.dlength_dp.iter().all(|g| g.is_finite()),
                        "{surf:?} {p:?} {s:?}"
                    );
                    assert!(
                        w.length >= (p - s).norm() * (1.0 - 1e-12),
                        "{surf:?} {p:?} {s:?} {q:?}: {w:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn outcomes_report_inside_and_mandatory_as_opensim() {
    use WrapOutcome::{InsideRadius, NoWrap};
    let (p, s) = (Vec3::new(-0.2, 0.01, 0.0), Vec3::new(0.2, 0.012, 0.001));
    let inside = Vec3::new(0.01, 0.0, 0.0);
    let flag = |o: WrapOutcome| o.wrapped().expect("wraps").mandatory;
    // Sphere: a plain wrap unless a quadrant is set and a point is on its active side.
    assert_eq!(wrap_sphere(0.05, Quadrant::All, &inside, &s), InsideRadius);
    assert!(!flag(wrap_sphere(0.05, Quadrant::All, &p, &s)));
    assert!(flag(wrap_sphere(0.05, Quadrant::Positive(1), &p, &s)));
    assert!(!flag(wrap_sphere(0.05, Quadrant::Negative(1), &p, &s)));
    // Cylinder: crossing with a point active (or unconstrained) is mandatory; forced is not.
    assert_eq!(
        wrap_cylinder(0.05, 1.0, Quadrant::All, &p, &inside),
        InsideRadius
    );
    assert!(flag(wrap_cylinder(0.05, 1.0, Quadrant::All, &p, &s)));
    assert!(flag(wrap_cylinder(
        0.05,
        1.0,
        Quadrant::Positive(1),
        &p,
        &s
    )));
    assert!(!flag(wrap_cylinder(
        0.05,
        1.0,
        Quadrant::Negative(1),
        &p,
        &s
    )));
    let (far_p, far_s) = (Vec3::new(-0.2, 0.1, 0.0), Vec3::new(0.2, 0.1, 0.0));
    assert_eq!(
        wrap_cylinder(0.05, 1.0, Quadrant::All, &far_p, &far_s),
        NoWrap
    );
    assert!(!flag(wrap_cylinder(
        0.05,
        1.0,
        Quadrant::Negative(1),
        &far_p,
        &far_s
    )));
    // Ellipsoid: always mandatory.
    let radii = Vec3::new(0.05, 0.03, 0.04);
    let m = EllipsoidMethod::Hybrid;
    assert_eq!(
        wrap_ellipsoid(&radii, Quadrant::All, m, &inside, &s),
        InsideRadius
    );
    assert!(flag(wrap_ellipsoid(&radii, Quadrant::All, m, &p, &s)));
    assert!(flag(wrap_ellipsoid(
        &radii,
        Quadrant::Negative(1),
        m,
        &p,
        &s
    )));
    // Torus: never mandatory, never "inside" (a point inside the tube gives no wrap).
    let (tp, ts) = (Vec3::new(0.045, 0.002, 0.1), Vec3::new(0.046, -0.003, -0.1));
    assert!(!flag(wrap_torus(0.02, 0.06, Quadrant::All, &tp, &ts)));
    assert_eq!(
        wrap_torus(0.02, 0.06, Quadrant::All, &Vec3::new(0.06, 0.0, 0.0), &ts),
        NoWrap
    );
}

//! Shared helpers for the integration tests: reference data lookup, a deterministic random
//! number generator, random states, and small OpenSim XML builders.
#![allow(dead_code)]

use musculo::Model;
use std::path::PathBuf;

/// The path of a reference file, or `None` after printing "skipped: reference data not
/// found". With `MUSCULO_REQUIRE_REFERENCE=1` a missing file fails the test instead.
pub fn reference_file(relative: &str) -> Option<PathBuf> {
    match musculo::reference::file(relative) {
        Some(p) => Some(p),
        None if musculo::reference::required() => panic!(
            "reference data not found: {} (MUSCULO_REQUIRE_REFERENCE=1)",
            musculo::reference::directory().join(relative).display()
        ),
        None => {
            eprintln!(
                "skipped: reference data not found ({})",
                musculo::reference::directory().join(relative).display()
            );
            None
        }
    }
}

/// Every .osim file under the reference `opensim-models` directory, sorted.
pub fn reference_models() -> Vec<PathBuf> {
    let Some(root) = reference_file("opensim-models") else {
        return Vec::new();
    };
    fn walk(d: &std::path::Path, out: &mut Vec<PathBuf>) {
        let Ok(rd) = std::fs::read_dir(d) else { return };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "osim") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    walk(&root, &mut out);
    out.sort();
    out
}

/// SplitMix64: a small deterministic generator for reproducible random states.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
}

/// Independent coordinates drawn uniformly within their ranges.
pub fn random_q(model: &Model, rng: &mut Rng) -> Vec<f64> {
    model
        .reduction
        .independent
        .iter()
        .map(|&c| {
            let [lo, hi] = model.coordinates[c].range;
            rng.uniform(lo, hi)
        })
        .collect()
}

/// A vector of n values uniform in [−a, a].
pub fn random_vec(n: usize, a: f64, rng: &mut Rng) -> Vec<f64> {
    (0..n).map(|_| rng.uniform(-a, a)).collect()
}

/// |a − b| ≤ tol · max(1, |b|), with a message naming what differs.
pub fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!(
        (a - b).abs() <= tol * b.abs().max(1.0),
        "{what}: {a:.17e} vs {b:.17e} (difference {:.3e})",
        (a - b).abs()
    );
}

/// A minimal OpenSim 4 document around the given sets.
pub fn osim(bodies: &str, joints: &str, constraints: &str, gravity: [f64; 3]) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <Model name="test">
    <Ground name="ground" />
    <gravity>{} {} {}</gravity>
    <BodySet name="bodyset"><objects>
{bodies}
    </objects></BodySet>
    <JointSet name="jointset"><objects>
{joints}
    </objects></JointSet>
    <ConstraintSet name="constraintset"><objects>
{constraints}
    </objects></ConstraintSet>
  </Model>
</OpenSimDocument>
"#,
        gravity[0], gravity[1], gravity[2]
    )
}

pub fn body(name: &str, mass: f64, com: [f64; 3], inertia: [f64; 6]) -> String {
    format!(
        "<Body name=\"{name}\"><mass>{mass:e}</mass><mass_center>{:e} {:e} {:e}</mass_center>\
         <inertia>{:e} {:e} {:e} {:e} {:e} {:e}</inertia></Body>",
        com[0],
        com[1],
        com[2],
        inertia[0],
        inertia[1],
        inertia[2],
        inertia[3],
        inertia[4],
        inertia[5]
    )
}

pub fn coordinate(name: &str, range: [f64; 2]) -> String {
    format!(
        "<Coordinate name=\"{name}\"><default_value>0</default_value><range>{:e} {:e}</range></Coordinate>",
        range[0], range[1]
    )
}

/// A joint of type `kind` from `parent` (body path) at `offset` to `child` (body path)
/// with its child frame at the child body's origin.
pub fn joint(
    kind: &str,
    name: &str,
    parent: &str,
    offset: [f64; 3],
    child: &str,
    coords: &[String],
    extra: &str,
) -> String {
    format!(
        r#"<{kind} name="{name}">
  <socket_parent_frame>p</socket_parent_frame><socket_child_frame>c</socket_child_frame>
  <coordinates>{}</coordinates>
  <frames>
    <PhysicalOffsetFrame name="p"><socket_parent>{parent}</socket_parent><translation>{:e} {:e} {:e}</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
    <PhysicalOffsetFrame name="c"><socket_parent>{child}</socket_parent><translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
  </frames>
  {extra}
</{kind}>"#,
        coords.join(""),
        offset[0],
        offset[1],
        offset[2]
    )
}

/// A CustomJoint SpatialTransform from six (coordinates, axis, function XML) triples in the
/// order rotation1–3, translation1–3.
pub fn spatial_transform(axes: [(&str, [f64; 3], &str); 6]) -> String {
    let names = [
        "rotation1",
        "rotation2",
        "rotation3",
        "translation1",
        "translation2",
        "translation3",
    ];
    let mut s = String::from("<SpatialTransform>");
    for (n, (c, a, f)) in names.iter().zip(axes) {
        s += &format!(
            "<TransformAxis name=\"{n}\"><coordinates>{c}</coordinates><axis>{} {} {}</axis>{f}</TransformAxis>",
            a[0], a[1], a[2]
        );
    }
    s + "</SpatialTransform>"
}

pub const ZERO: &str = "<Constant><value>0</value></Constant>";
pub const IDENTITY: &str = "<LinearFunction><coefficients>1 0</coefficients></LinearFunction>";

/// A fresh directory under the system temp folder for one test's files (named after the
/// test and the process), removed when dropped.
pub struct ScratchDir(pub PathBuf);

impl ScratchDir {
    pub fn new(test: &str) -> ScratchDir {
        let d = std::env::temp_dir().join(format!("musculo-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("create a scratch directory");
        ScratchDir(d)
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs the `musculo` binary: (exit status success, stdout, stderr).
pub fn run_musculo<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_musculo"))
        .args(args)
        .output()
        .expect("run musculo");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `musculo` with the whitespace-separated arguments of `pattern`, each `{}` replaced by
/// the next of `paths` (which may contain spaces): (success, stdout, stderr).
pub fn musculo_cli(pattern: &str, paths: &[&std::path::Path]) -> (bool, String, String) {
    let mut paths = paths.iter();
    let args: Vec<std::ffi::OsString> = pattern
        .split_whitespace()
        .map(|a| match a {
            "{}" => paths.next().expect("a path per {}").as_os_str().to_owned(),
            _ => a.into(),
        })
        .collect();
    assert!(
        paths.next().is_none(),
        "more paths than {{}} in `{pattern}`"
    );
    run_musculo(&args)
}

/// The (file, location, message) of an `Error::Motion`; panics on any other error.
pub fn expect_motion_error(e: musculo::Error) -> (String, String, String) {
    match e {
        musculo::Error::Motion {
            file,
            location,
            message,
        } => (file, location, message),
        other => panic!("expected Error::Motion, got {other:?}"),
    }
}

/// The (argument, message) of an `Error::InvalidArgument`; panics on any other error.
pub fn expect_invalid_argument(e: musculo::Error) -> (&'static str, String) {
    match e {
        musculo::Error::InvalidArgument { argument, message } => (argument, message),
        other => panic!("expected Error::InvalidArgument, got {other:?}"),
    }
}

/// A rope over a pulley: a muscle from ground over a cylinder (radius R, axis z through the
/// pin joint's axis) to the rotating arm. While the path wraps, rotating the arm about the
/// cylinder's axis changes the wrapped arc by R per radian: |r| = R exactly. Over theta's
/// range (−0.4…0 rad) the path wraps; beyond about +0.1 rad it leaves the cylinder and |r| is
/// the distance from the axis to the straight line (> R). The origin sits on ground.
pub const PULLEY_RADIUS: f64 = 0.15;
pub const PULLEY_OSIM: &str = r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <Model name="pulley">
    <Ground name="ground">
      <WrapObjectSet name="wrapobjectset"><objects>
        <WrapCylinder name="wheel"><xyz_body_rotation>0 0 0</xyz_body_rotation><translation>0 0 0</translation><quadrant>+y</quadrant><radius>0.15</radius><length>0.2</length></WrapCylinder>
      </objects></WrapObjectSet>
    </Ground>
    <gravity>0 -9.80665 0</gravity>
    <BodySet name="bodyset"><objects>
      <Body name="arm"><mass>1</mass><mass_center>0.3 0 0</mass_center><inertia>0.01 0.01 0.01 0 0 0</inertia></Body>
    </objects></BodySet>
    <JointSet name="jointset"><objects>
      <PinJoint name="pin">
        <socket_parent_frame>ground_offset</socket_parent_frame><socket_child_frame>arm_offset</socket_child_frame>
        <coordinates><Coordinate name="theta"><default_value>-0.2</default_value><range>-0.4 0</range></Coordinate></coordinates>
        <frames>
          <PhysicalOffsetFrame name="ground_offset"><socket_parent>/ground</socket_parent><translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
          <PhysicalOffsetFrame name="arm_offset"><socket_parent>/bodyset/arm</socket_parent><translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
        </frames>
      </PinJoint>
    </objects></JointSet>
    <ForceSet name="forceset"><objects>
      <Thelen2003Muscle name="rope">
        <GeometryPath name="geometrypath">
          <PathPointSet><objects>
            <PathPoint name="rope-P1"><socket_parent_frame>/ground</socket_parent_frame><location>-0.6 0.1 0</location></PathPoint>
            <PathPoint name="rope-P2"><socket_parent_frame>/bodyset/arm</socket_parent_frame><location>0.6 0.1 0</location></PathPoint>
          </objects></PathPointSet>
          <PathWrapSet><objects><PathWrap name="w"><wrap_object>wheel</wrap_object><method>hybrid</method></PathWrap></objects></PathWrapSet>
        </GeometryPath>
        <max_isometric_force>500</max_isometric_force>
        <optimal_fiber_length>0.5</optimal_fiber_length>
        <tendon_slack_length>0.6</tendon_slack_length>
      </Thelen2003Muscle>
    </objects></ForceSet>
  </Model>
</OpenSimDocument>
"#;

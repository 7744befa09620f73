//! Small valid inputs for every reader, generated here (plus the repository's own small
//! files: `models/demo.osim`, `data/skeletons/*.json`). Each seed is checked to read without
//! error before it is mutated.

use std::fmt::Write;

pub const DEMO_OSIM: &str = include_str!("../../models/demo.osim");

/// A second model: a CustomJoint with spline and linear functions, a weld, a point
/// constraint-free chain and a two-point muscle, so the mutations reach other element kinds
/// than the demo's.
pub fn small_osim() -> String {
    r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
<Model name="small">
<Ground name="ground" />
<gravity>0 -9.80665 0</gravity>
<BodySet name="bodyset"><objects>
<Body name="a"><mass>2</mass><mass_center>0 -0.1 0</mass_center><inertia>0.02 0.01 0.02 0 0 0</inertia></Body>
<Body name="b"><mass>1</mass><mass_center>0 -0.2 0</mass_center><inertia>0.01 0.005 0.01 0 0 0</inertia></Body>
<Body name="c"><mass>0.5</mass><mass_center>0 0 0</mass_center><inertia>0.001 0.001 0.001 0 0 0</inertia></Body>
</objects></BodySet>
<JointSet name="jointset"><objects>
<CustomJoint name="ja">
<socket_parent_frame>ground_offset</socket_parent_frame><socket_child_frame>a_offset</socket_child_frame>
<coordinates><Coordinate name="qa"><default_value>0.1</default_value><range>-2 2</range></Coordinate>
<Coordinate name="ya"><default_value>0</default_value><range>-1 1</range></Coordinate></coordinates>
<frames>
<PhysicalOffsetFrame name="ground_offset"><socket_parent>/ground</socket_parent><translation>0 1 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
<PhysicalOffsetFrame name="a_offset"><socket_parent>/bodyset/a</socket_parent><translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
</frames>
<SpatialTransform>
<TransformAxis name="rotation1"><coordinates>qa</coordinates><axis>0 0 1</axis><LinearFunction><coefficients>1 0</coefficients></LinearFunction></TransformAxis>
<TransformAxis name="rotation2"><coordinates></coordinates><axis>1 0 0</axis><Constant><value>0</value></Constant></TransformAxis>
<TransformAxis name="rotation3"><coordinates></coordinates><axis>0 1 0</axis><Constant><value>0</value></Constant></TransformAxis>
<TransformAxis name="translation1"><coordinates>qa</coordinates><axis>1 0 0</axis><SimmSpline><x>-2 -1 0 1 2</x><y>-0.01 0 0.01 0 -0.01</y></SimmSpline></TransformAxis>
<TransformAxis name="translation2"><coordinates>ya</coordinates><axis>0 1 0</axis><LinearFunction><coefficients>1 0</coefficients></LinearFunction></TransformAxis>
<TransformAxis name="translation3"><coordinates></coordinates><axis>0 0 1</axis><Constant><value>0</value></Constant></TransformAxis>
</SpatialTransform>
</CustomJoint>
<PinJoint name="jb">
<socket_parent_frame>a_offset</socket_parent_frame><socket_child_frame>b_offset</socket_child_frame>
<coordinates><Coordinate name="qb"><default_value>0</default_value><range>-1.5 1.5</range><clamped>true</clamped></Coordinate></coordinates>
<frames>
<PhysicalOffsetFrame name="a_offset"><socket_parent>/bodyset/a</socket_parent><translation>0 -0.3 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
<PhysicalOffsetFrame name="b_offset"><socket_parent>/bodyset/b</socket_parent><translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
</frames>
</PinJoint>
<WeldJoint name="jc">
<socket_parent_frame>b_offset</socket_parent_frame><socket_child_frame>c_offset</socket_child_frame>
<frames>
<PhysicalOffsetFrame name="b_offset"><socket_parent>/bodyset/b</socket_parent><translation>0 -0.4 0</translation><orientation>0 0.1 0</orientation></PhysicalOffsetFrame>
<PhysicalOffsetFrame name="c_offset"><socket_parent>/bodyset/c</socket_parent><translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
</frames>
</WeldJoint>
</objects></JointSet>
<ForceSet name="forceset"><objects>
<Thelen2003Muscle name="m1">
<GeometryPath name="path"><PathPointSet><objects>
<PathPoint name="p1"><socket_parent_frame>/bodyset/a</socket_parent_frame><location>0.02 -0.05 0</location></PathPoint>
<PathPoint name="p2"><socket_parent_frame>/bodyset/b</socket_parent_frame><location>0.02 -0.1 0</location></PathPoint>
</objects></PathPointSet></GeometryPath>
<max_isometric_force>500</max_isometric_force><optimal_fiber_length>0.1</optimal_fiber_length>
<tendon_slack_length>0.2</tendon_slack_length><pennation_angle_at_optimal>0.1</pennation_angle_at_optimal>
</Thelen2003Muscle>
<CoordinateActuator name="act"><coordinate>qb</coordinate><optimal_force>10</optimal_force></CoordinateActuator>
</objects></ForceSet>
<MarkerSet name="markerset"><objects>
<Marker name="M1"><socket_parent_frame>/bodyset/b</socket_parent_frame><location>0 -0.1 0.05</location></Marker>
</objects></MarkerSet>
</Model>
</OpenSimDocument>
"#
    .to_string()
}

/// Storage files in each header dialect: version 1 (`.mot`), OpenSim 4 (`.sto`) and SIMM.
pub fn storage_files() -> Vec<(&'static str, String)> {
    let rows = |n: usize, cols: usize| {
        let mut s = String::new();
        for r in 0..n {
            let _ = write!(s, "{:.3}", r as f64 * 0.01);
            for c in 0..cols {
                let _ = write!(s, "\t{:.4}", (r as f64 * 0.3 + c as f64).sin() * 20.0);
            }
            s.push('\n');
        }
        s
    };
    vec![
        (
            "walk.mot",
            format!(
                "Coordinates\nversion=1\nnRows=12\nnColumns=5\ninDegrees=yes\n\n\
                 Units are S.I. units (second, meters, Newtons, ...)\nendheader\n\
                 time\thip_flexion\tknee_angle\tankle_angle\tpelvis_tx\n{}",
                rows(12, 4)
            ),
        ),
        (
            "forces.sto",
            format!(
                "inverse_dynamics\nversion=1\nnRows=10\nnColumns=4\ninDegrees=no\n\
                 DataType=double\nOpenSimVersion=4.5\nendheader\n\
                 time\thip_flexion_moment\tknee_angle_moment\tankle_angle_moment\n{}",
                rows(10, 3)
            ),
        ),
        (
            "simm.mot",
            format!(
                "name simm.mot\ndatacolumns 3\ndatarows 8\nrange 0 0.07\nendheader\n\
                 time hip knee\n{}",
                rows(8, 2).replace('\t', " ")
            ),
        ),
    ]
}

/// The data file of the ExternalLoads seed: two plates' force, point and torque columns.
pub fn grf_mot() -> String {
    let mut s = String::from(
        "grf\nversion=1\nnRows=8\nnColumns=19\ninDegrees=no\nendheader\ntime\
         \tr_vx\tr_vy\tr_vz\tr_px\tr_py\tr_pz\tl_vx\tl_vy\tl_vz\tl_px\tl_py\tl_pz\
         \trt_x\trt_y\trt_z\tlt_x\tlt_y\tlt_z\n",
    );
    for r in 0..8 {
        let t = r as f64 * 0.01;
        let _ = writeln!(
            s,
            "{t:.2}\t1\t{:.1}\t0\t0.1\t0\t0.05\t-1\t{:.1}\t0\t0.2\t0\t-0.05\t0\t0.5\t0\t0\t-0.5\t0",
            700.0 + 10.0 * r as f64,
            300.0 - 10.0 * r as f64
        );
    }
    s
}

/// An ExternalLoads file on the demo model's foot (read with [`grf_mot`]).
pub fn external_loads_xml() -> String {
    r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <ExternalLoads name="grf">
    <objects>
      <ExternalForce name="right">
        <applied_to_body>foot</applied_to_body>
        <force_expressed_in_body>ground</force_expressed_in_body>
        <point_expressed_in_body>ground</point_expressed_in_body>
        <force_identifier>r_v</force_identifier>
        <point_identifier>r_p</point_identifier>
        <torque_identifier>rt_</torque_identifier>
      </ExternalForce>
      <ExternalForce name="left">
        <applied_to_body>shank</applied_to_body>
        <force_expressed_in_body>ground</force_expressed_in_body>
        <point_expressed_in_body>ground</point_expressed_in_body>
        <force_identifier>l_v</force_identifier>
        <point_identifier>l_p</point_identifier>
        <torque_identifier>lt_</torque_identifier>
        <data_source_name>Unassigned</data_source_name>
      </ExternalForce>
    </objects>
    <groups />
    <datafile>grf.mot</datafile>
  </ExternalLoads>
</OpenSimDocument>
"#
    .to_string()
}

/// InverseDynamicsTool and AnalyzeTool (static optimization) setups.
pub fn tool_setups() -> Vec<(&'static str, String)> {
    vec![
        (
            "id_setup.xml",
            r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <InverseDynamicsTool name="walk">
    <results_directory>Results</results_directory>
    <input_directory />
    <model_file>../subject01.osim</model_file>
    <time_range> 0 2.5</time_range>
    <forces_to_exclude> Muscles</forces_to_exclude>
    <external_loads_file>../ExperimentalData/grf.xml</external_loads_file>
    <coordinates_file>../IK/walk_IK.mot</coordinates_file>
    <lowpass_cutoff_frequency_for_coordinates>6</lowpass_cutoff_frequency_for_coordinates>
    <output_gen_force_file>walk_ID.sto</output_gen_force_file>
    <joints_to_report_body_forces />
    <output_body_forces_file>Unassigned</output_body_forces_file>
  </InverseDynamicsTool>
</OpenSimDocument>
"#
            .to_string(),
        ),
        (
            "so_setup.xml",
            r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <AnalyzeTool name="walk_so">
    <model_file>subject01.osim</model_file>
    <replace_force_set>false</replace_force_set>
    <force_set_files>reserves.xml</force_set_files>
    <results_directory>Results</results_directory>
    <output_precision>8</output_precision>
    <initial_time>0.5</initial_time>
    <final_time>2</final_time>
    <solve_for_equilibrium_for_auxiliary_states>false</solve_for_equilibrium_for_auxiliary_states>
    <AnalysisSet name="Analyses">
      <objects>
        <StaticOptimization name="StaticOptimization">
          <on>true</on>
          <start_time>0.5</start_time>
          <end_time>2</end_time>
          <step_interval>1</step_interval>
          <in_degrees>true</in_degrees>
          <use_model_force_set>true</use_model_force_set>
          <activation_exponent>2</activation_exponent>
          <use_muscle_physiology>true</use_muscle_physiology>
          <optimizer_convergence_criterion>0.0001</optimizer_convergence_criterion>
          <optimizer_max_iterations>100</optimizer_max_iterations>
        </StaticOptimization>
      </objects>
      <groups />
    </AnalysisSet>
    <external_loads_file>grf.xml</external_loads_file>
    <coordinates_file>walk_IK.mot</coordinates_file>
    <lowpass_cutoff_frequency_for_coordinates>6</lowpass_cutoff_frequency_for_coordinates>
  </AnalyzeTool>
</OpenSimDocument>
"#
            .to_string(),
        ),
    ]
}

/// An InverseKinematicsTool setup with marker and coordinate tasks.
pub fn ik_setup() -> String {
    r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <InverseKinematicsTool name="walk_ik">
    <results_directory>./</results_directory>
    <model_file>subject01.osim</model_file>
    <constraint_weight>Inf</constraint_weight>
    <accuracy>1e-05</accuracy>
    <IKTaskSet name="tasks">
      <objects>
        <IKMarkerTask name="R.ASIS"><apply>true</apply><weight>10</weight></IKMarkerTask>
        <IKMarkerTask name="L.ASIS"><apply>true</apply><weight>10</weight></IKMarkerTask>
        <IKMarkerTask name="V.Sacral"><apply>false</apply><weight>1</weight></IKMarkerTask>
        <IKCoordinateTask name="knee_angle_r"><apply>true</apply><weight>0.1</weight>
          <value_type>default_value</value_type><value>0</value></IKCoordinateTask>
      </objects>
      <groups />
    </IKTaskSet>
    <marker_file>walk.trc</marker_file>
    <coordinate_file>Unassigned</coordinate_file>
    <time_range> 0.4 1.6</time_range>
    <report_errors>true</report_errors>
    <output_motion_file>walk_ik.mot</output_motion_file>
    <report_marker_locations>false</report_marker_locations>
  </InverseKinematicsTool>
</OpenSimDocument>
"#
    .to_string()
}

/// A ScaleTool setup with manual scales, measurements and a marker placer.
pub fn scale_setup() -> String {
    r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <ScaleTool name="subject01">
    <mass>72.6</mass>
    <height>1803.4</height>
    <age>-1</age>
    <notes>Unassigned</notes>
    <GenericModelMaker>
      <model_file>gait2354.osim</model_file>
      <marker_set_file>markers.xml</marker_set_file>
    </GenericModelMaker>
    <ModelScaler>
      <apply>true</apply>
      <scaling_order> measurements manualScale</scaling_order>
      <MeasurementSet>
        <objects>
          <Measurement name="torso">
            <apply>true</apply>
            <MarkerPairSet><objects>
              <MarkerPair><markers> Top.Head V.Sacral</markers></MarkerPair>
            </objects></MarkerPairSet>
            <BodyScaleSet><objects>
              <BodyScale name="torso"><axes> X Y Z</axes></BodyScale>
            </objects></BodyScaleSet>
          </Measurement>
        </objects>
      </MeasurementSet>
      <ScaleSet>
        <objects>
          <Scale><scales> 1.1 1.2 1.1</scales><segment>pelvis</segment><apply>true</apply></Scale>
        </objects>
      </ScaleSet>
      <marker_file>static.trc</marker_file>
      <time_range> 0.5 1.5</time_range>
      <preserve_mass_distribution>true</preserve_mass_distribution>
      <output_model_file>scaled_only.osim</output_model_file>
    </ModelScaler>
    <MarkerPlacer>
      <apply>true</apply>
      <IKTaskSet><objects>
        <IKMarkerTask name="Top.Head"><apply>true</apply><weight>1</weight></IKMarkerTask>
      </objects></IKTaskSet>
      <marker_file>static.trc</marker_file>
      <time_range> 0.5 1.5</time_range>
      <output_model_file>placed.osim</output_model_file>
      <max_marker_movement>-1</max_marker_movement>
    </MarkerPlacer>
  </ScaleTool>
</OpenSimDocument>
"#
    .to_string()
}

/// A MarkerSet file in OpenSim 4 form (socket_parent_frame) and OpenSim 3 form (body).
pub fn marker_set() -> String {
    r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <MarkerSet name="markers">
    <objects>
      <Marker name="R.ASIS">
        <socket_parent_frame>/bodyset/pelvis</socket_parent_frame>
        <location>0.01 0.02 0.12</location>
        <fixed>false</fixed>
      </Marker>
      <Marker name="R.Knee">
        <body>thigh</body>
        <location>0 -0.4 0.05</location>
        <fixed>true</fixed>
      </Marker>
    </objects>
    <groups />
  </MarkerSet>
</OpenSimDocument>
"#
    .to_string()
}

/// A force-set file of reserve and residual actuators on the demo model's coordinates.
pub fn force_set() -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40000\">\n\
         <ForceSet name=\"reserves\">\n<objects>\n",
    );
    for (c, f) in [
        ("pelvis_tilt", 100.0),
        ("pelvis_tx", 200.0),
        ("pelvis_ty", 200.0),
        ("hip_flexion", 10.0),
        ("knee_angle", 10.0),
        ("ankle_angle", 10.0),
    ] {
        let _ = writeln!(
            s,
            "<CoordinateActuator name=\"reserve_{c}\">\n<coordinate>{c}</coordinate>\n\
             <optimal_force>{f}</optimal_force>\n<min_control>-inf</min_control>\n\
             <max_control>inf</max_control>\n</CoordinateActuator>"
        );
    }
    s.push_str("</objects>\n<groups />\n</ForceSet>\n</OpenSimDocument>\n");
    s
}

/// A marker file: three markers over ten frames, one of them missing in two frames.
pub fn trc() -> String {
    let mut s = String::from(
        "PathFileType\t4\t(X/Y/Z)\twalk.trc\n\
         DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
         100\t100\t10\t3\tmm\t100\t1\t10\n\
         Frame#\tTime\tR.ASIS\t\t\tL.ASIS\t\t\tV.Sacral\t\t\n\
         \t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\n\n",
    );
    for f in 0..10 {
        let x = f as f64 * 12.5;
        let _ = write!(
            s,
            "{}\t{:.2}\t{x:.1}\t950.2\t120.4\t{x:.1}\t948.9\t-121.7",
            f + 1,
            f as f64 * 0.01
        );
        if f == 3 || f == 4 {
            s.push_str("\t\t\t\n");
        } else {
            let _ = writeln!(s, "\t{:.1}\t960.0\t0.5", x - 150.0);
        }
    }
    s
}

/// A BVH file: a root with six channels, two legs and a spine, three frames, in
/// centimetres (a 1.7 m figure).
pub fn bvh() -> String {
    let mut s = String::from(
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n\
         \x20 JOINT LeftUpLeg\n  {\n    OFFSET 10 -5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n\
         \x20   JOINT LeftLeg\n    {\n      OFFSET 0 -42 0\n      CHANNELS 3 Zrotation Xrotation Yrotation\n\
         \x20     End Site\n      {\n        OFFSET 0 -40 0\n      }\n    }\n  }\n\
         \x20 JOINT RightUpLeg\n  {\n    OFFSET -10 -5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n\
         \x20   JOINT RightLeg\n    {\n      OFFSET 0 -42 0\n      CHANNELS 3 Zrotation Xrotation Yrotation\n\
         \x20     End Site\n      {\n        OFFSET 0 -40 0\n      }\n    }\n  }\n\
         \x20 JOINT Spine\n  {\n    OFFSET 0 10 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n\
         \x20   JOINT Head\n    {\n      OFFSET 0 60 0\n      CHANNELS 3 Zrotation Xrotation Yrotation\n\
         \x20     End Site\n      {\n        OFFSET 0 20 0\n      }\n    }\n  }\n}\n\
         MOTION\nFrames: 3\nFrame Time: 0.008333\n",
    );
    for f in 0..3 {
        let a = f as f64 * 5.0;
        let _ = writeln!(
            s,
            "{a} 90 0 0 {a} 0 10 -{a} 0 20 0 0 -10 {a} 0 20 0 0 0 5 0 0 -5 0"
        );
    }
    s
}

/// The bytes of a version-1.0 `.npy` file holding `values` (little-endian f32) of `shape`.
pub fn npy_f32(shape: &[usize], values: &[f32]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let tuple = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {tuple}, }}");
    // Magic (6) + version (2) + length (2) + header + newline, padded to 64 bytes.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    for v in values {
        out.extend(v.to_le_bytes());
    }
    out
}

/// A HumanML3D `new_joints` clip (T×22×3, metres) and a KIT-ML one (T×21×3, millimetres):
/// joints spread over a 1.6 m column, moving a little from frame to frame.
pub fn joint_clips() -> Vec<(&'static str, Vec<u8>)> {
    let clip = |frames: usize, joints: usize, scale: f32| -> Vec<f32> {
        let mut v = Vec::with_capacity(frames * joints * 3);
        for f in 0..frames {
            for j in 0..joints {
                let y = 1.6 * j as f32 / (joints - 1) as f32;
                v.extend([
                    (0.1 * (j % 3) as f32 + 0.01 * f as f32) * scale,
                    y * scale,
                    (0.05 * (j % 2) as f32) * scale,
                ]);
            }
        }
        v
    };
    vec![
        (
            "clip_humanml3d.npy",
            npy_f32(&[4, 22, 3], &clip(4, 22, 1.0)),
        ),
        ("clip_kit.npy", npy_f32(&[3, 21, 3], &clip(3, 21, 1000.0))),
    ]
}

/// The bytes of a small C3D file (Intel, float storage): `frames` frames of three markers
/// in millimetres, with the POINT parameters a reader needs; written from the C3D manual.
pub fn c3d(frames: usize) -> Vec<u8> {
    let labels = ["RASI", "LASI", "SACR"];
    let rate = 100.0f32;
    // Parameter section: one group (POINT) and its parameters.
    let mut rec: Vec<u8> = Vec::new();
    let group = b"POINT";
    rec.push(group.len() as u8);
    rec.push((-1i8) as u8);
    rec.extend(group);
    rec.extend(3u16.to_le_bytes());
    rec.push(0);
    let mut param = |name: &[u8], kind: i8, dims: &[u8], data: &[u8]| {
        rec.push(name.len() as u8);
        rec.push(1);
        rec.extend(name);
        rec.extend(((2 + 1 + 1 + dims.len() + data.len() + 1) as u16).to_le_bytes());
        rec.push(kind as u8);
        rec.push(dims.len() as u8);
        rec.extend(dims);
        rec.extend(data);
        rec.push(0);
    };
    param(b"USED", 2, &[], &(labels.len() as u16).to_le_bytes());
    param(b"SCALE", 4, &[], &(-0.1f32).to_le_bytes());
    param(b"RATE", 4, &[], &rate.to_le_bytes());
    param(b"FRAMES", 2, &[], &(frames as u16).to_le_bytes());
    param(b"UNITS", -1, &[2], b"mm");
    let mut names = Vec::new();
    for l in labels {
        names.extend(l.as_bytes());
    }
    param(b"LABELS", -1, &[4, labels.len() as u8], &names);
    rec.extend([0, 0]);
    let n_blocks = (4 + rec.len()).div_ceil(512);
    let data_start = 2 + n_blocks;
    let mut out = vec![0u8; 512];
    out[0] = 2;
    out[1] = 0x50;
    let mut word = |w: usize, v: u16| out[2 * w - 2..2 * w].copy_from_slice(&v.to_le_bytes());
    word(2, labels.len() as u16);
    word(3, 0);
    word(4, 1);
    word(5, frames as u16);
    word(9, data_start as u16);
    word(10, 0);
    out[12..16].copy_from_slice(&(-0.1f32).to_le_bytes());
    out[20..24].copy_from_slice(&rate.to_le_bytes());
    out.extend([1, 0x50, n_blocks as u8, 84]);
    out.extend(rec);
    out.resize((data_start - 1) * 512, 0);
    for f in 0..frames {
        for m in 0..labels.len() {
            let p = [
                100.0 * m as f32 + f as f32,
                200.0,
                900.0 + 10.0 * m as f32,
                0.0,
            ];
            for x in p {
                out.extend(x.to_le_bytes());
            }
        }
    }
    out
}

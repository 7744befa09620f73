//! Bad model files: each is an `Err` of the right variant that names the offending element
//! and its line, with a message saying what is wrong — never a panic, never a silent load.
//!
//! Most cases edit `models/demo.osim` in one place; the expected line is found from the text
//! itself, so the tests survive edits to the demo model.

use musculo::model::{LoadOptions, WarningKind};
use musculo::{Error, Model};

const DEMO: &str = include_str!("../models/demo.osim");
const SOURCE: &str = "bad.osim";

/// 1-based line of the only occurrence of `needle` in `xml`.
#[track_caller]
fn line_of(xml: &str, needle: &str) -> u32 {
    let hits: Vec<usize> = xml.match_indices(needle).map(|(i, _)| i).collect();
    assert_eq!(
        hits.len(),
        1,
        "`{needle}` must occur exactly once in the test XML"
    );
    line_at(xml, hits[0])
}

fn line_at(xml: &str, byte: usize) -> u32 {
    xml[..byte].matches('\n').count() as u32 + 1
}

/// Replaces the first `from` after the only occurrence of `anchor`; returns the new text and
/// the line of the replacement.
#[track_caller]
fn replace_after(xml: &str, anchor: &str, from: &str, to: &str) -> (String, u32) {
    line_of(xml, anchor);
    let start = xml.find(anchor).unwrap();
    let at = start
        + xml[start..]
            .find(from)
            .unwrap_or_else(|| panic!("`{from}` does not follow `{anchor}`"));
    let mut out = String::with_capacity(xml.len() + to.len());
    out.push_str(&xml[..at]);
    out.push_str(to);
    out.push_str(&xml[at + from.len()..]);
    (out, line_at(xml, at))
}

/// Replaces the only occurrence of `from`.
#[track_caller]
fn replace_unique(xml: &str, from: &str, to: &str) -> String {
    line_of(xml, from);
    xml.replacen(from, to, 1)
}

#[track_caller]
fn load(xml: &str) -> musculo::Result<Model> {
    Model::from_osim_str(xml, SOURCE)
}

/// Asserts an `Error::Model` whose element path contains `element`, at `line`, whose
/// message contains every one of `message`.
#[track_caller]
fn assert_model_error(result: musculo::Result<Model>, element: &str, line: u32, message: &[&str]) {
    match result {
        Err(Error::Model {
            file,
            line: l,
            element: e,
            message: m,
        }) => {
            assert_eq!(file, SOURCE);
            assert!(
                e.contains(element),
                "element `{e}` should name `{element}` (message: {m})"
            );
            assert_eq!(l, line, "line of `{e}`: {m}");
            for part in message {
                assert!(m.contains(part), "message `{m}` should mention `{part}`");
            }
        }
        Err(other) => panic!("expected Error::Model naming `{element}`, got: {other}"),
        Ok(_) => panic!("expected Error::Model naming `{element}`, but the model loaded"),
    }
}

#[track_caller]
fn assert_xml_error(result: musculo::Result<Model>, line: u32, message: &[&str]) {
    match result {
        Err(Error::Xml {
            file,
            line: l,
            column,
            message: m,
        }) => {
            assert_eq!(file, SOURCE);
            assert_eq!(l, line, "line of the XML error: {m}");
            assert!(column >= 1, "columns are 1-based");
            for part in message {
                assert!(m.contains(part), "message `{m}` should mention `{part}`");
            }
        }
        Err(other) => panic!("expected Error::Xml, got: {other}"),
        Ok(_) => panic!("expected Error::Xml, but the model loaded"),
    }
}

/// A minimal model: `bodies` inside the BodySet, `joints` inside the JointSet.
fn minimal(bodies: &str, joints: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
<Model name="minimal">
<Ground name="ground" />
<BodySet name="bodyset">
<objects>
{bodies}
</objects>
</BodySet>
<JointSet name="jointset">
<objects>
{joints}
</objects>
</JointSet>
</Model>
</OpenSimDocument>
"#
    )
}

fn body(name: &str) -> String {
    format!(
        r#"<Body name="{name}">
<mass>1</mass>
<mass_center>0 0 0</mass_center>
<inertia>0.1 0.1 0.1 0 0 0</inertia>
</Body>"#
    )
}

fn pin(name: &str, parent: &str, child: &str, coordinate: &str) -> String {
    format!(
        r#"<PinJoint name="{name}">
<socket_parent_frame>{parent}</socket_parent_frame>
<socket_child_frame>{child}</socket_child_frame>
<coordinates>
<Coordinate name="{coordinate}" />
</coordinates>
</PinJoint>"#
    )
}

// ---------------------------------------------------------------------------------------
// The unedited inputs load.

#[test]
fn demo_and_minimal_models_load_unedited() {
    let demo = load(DEMO).expect("demo loads");
    assert!(demo.warnings.is_empty(), "{:?}", demo.warnings);
    let xml = minimal(&body("a"), &pin("j", "/ground", "/bodyset/a", "q"));
    let m = load(&xml).expect("minimal model loads");
    assert_eq!(m.nq(), 1);
}

// ---------------------------------------------------------------------------------------
// Malformed XML.

#[test]
fn unclosed_tag_is_an_xml_error_at_the_mismatched_closing_tag() {
    // <mass> never closed: the parser meets </Body> on the next line.
    let (xml, line) = replace_after(DEMO, r#"<Body name="pelvis">"#, "10</mass>", "10");
    assert_xml_error(load(&xml), line + 3, &["mass", "Body"]);
}

#[test]
fn truncated_file_is_an_xml_error() {
    let cut = DEMO.find("</JointSet>").unwrap();
    let xml = &DEMO[..cut];
    assert_xml_error(load(xml), line_at(DEMO, cut), &["truncated"]);
}

#[test]
fn garbage_text_is_an_xml_error() {
    assert_xml_error(load("this is not XML at all"), 1, &[]);
    assert_xml_error(load(""), 1, &[]);
    assert_xml_error(
        load("\n\n<OpenSimDocument Version=\"40000\"><Model></Mod"),
        3,
        &[],
    );
    // Garbage inside an element: a stray `<` in text.
    let (xml, line) = replace_after(
        DEMO,
        r#"<Body name="thigh">"#,
        "<mass>8</mass>",
        "<mass>8 < 9</mass>",
    );
    assert_xml_error(load(&xml), line, &[]);
    // A bare `&` (not an entity) in text.
    let (xml, line) = replace_after(
        DEMO,
        r#"<Body name="thigh">"#,
        "<mass>8</mass>",
        "<mass>8 & 9</mass>",
    );
    assert_xml_error(load(&xml), line, &[]);
}

#[test]
fn non_opensim_root_is_a_model_error() {
    let xml = "<?xml version=\"1.0\"?>\n<Robot name=\"r2\">\n</Robot>\n";
    assert_model_error(load(xml), "Robot", 2, &["OpenSimDocument"]);
}

#[test]
fn opensim_3_file_is_refused_with_a_hint() {
    let (xml, line) = replace_after(
        DEMO,
        "<OpenSimDocument",
        r#"Version="40000""#,
        r#"Version="30000""#,
    );
    assert_model_error(
        load(&xml),
        "OpenSimDocument",
        line,
        &["30000", "OpenSim 3", "OpenSim 4"],
    );
    let (xml, line) = replace_after(
        DEMO,
        "<OpenSimDocument",
        r#"Version="40000""#,
        r#"Version="four""#,
    );
    assert_model_error(load(&xml), "OpenSimDocument", line, &["Version"]);
}

// ---------------------------------------------------------------------------------------
// Bodies.

#[test]
fn negative_mass_is_an_error_naming_the_body() {
    let (xml, _) = replace_after(
        DEMO,
        r#"<Body name="thigh">"#,
        "<mass>8</mass>",
        "<mass>-8</mass>",
    );
    let line = line_of(&xml, r#"<Body name="thigh">"#);
    assert_model_error(
        load(&xml),
        r#"Body "thigh""#,
        line,
        &["negative mass", "-8"],
    );
}

#[test]
fn inertia_violating_the_triangle_inequality_is_a_warning_and_strict_refuses_it() {
    let (xml, _) = replace_after(
        DEMO,
        r#"<Body name="shank">"#,
        "<inertia>0.05 0.005 0.05 0 0 0</inertia>",
        "<inertia>1 1 3 0 0 0</inertia>",
    );
    let line = line_of(&xml, r#"<Body name="shank">"#);
    let strict = LoadOptions { strict: true };
    assert_model_error(
        Model::from_osim_str_with(&xml, SOURCE, &strict),
        r#"Body "shank""#,
        line,
        &["triangle inequality", "`--strict`"],
    );

    let model = load(&xml).expect("loads by default, as OpenSim's release builds do");
    let warning = model
        .warnings
        .iter()
        .find(|w| w.element.contains(r#"Body "shank""#))
        .unwrap_or_else(|| panic!("no warning names the shank: {:?}", model.warnings));
    assert_eq!(warning.line, line);
    assert!(
        warning.message.contains("triangle inequality") && warning.message.contains("< 3.000000e0"),
        "{}",
        warning.message
    );
    assert_eq!(warning.kind, WarningKind::NonphysicalInertia);
    assert_eq!(model.warnings.len(), 1, "{:?}", model.warnings);
    let shank = model.body_index("shank").unwrap();
    assert_eq!(model.bodies[shank].inertia_about_com[(2, 2)], 3.0);
}

#[test]
fn inertia_that_is_not_positive_semi_definite_is_an_error() {
    // Eigenvalues −1, 1, 3.
    let (xml, _) = replace_after(
        DEMO,
        r#"<Body name="shank">"#,
        "<inertia>0.05 0.005 0.05 0 0 0</inertia>",
        "<inertia>1 1 1 2 0 0</inertia>",
    );
    let line = line_of(&xml, r#"<Body name="shank">"#);
    assert_model_error(
        load(&xml),
        r#"Body "shank""#,
        line,
        &["not positive semi-definite"],
    );
    // Only the triangle inequality is accepted without `strict`.
    assert_model_error(
        load(&xml),
        r#"Body "shank""#,
        line,
        &["not positive semi-definite"],
    );
    // A negative principal moment on the diagonal.
    let (xml, _) = replace_after(
        DEMO,
        r#"<Body name="shank">"#,
        "<inertia>0.05 0.005 0.05 0 0 0</inertia>",
        "<inertia>-0.05 0.005 0.05 0 0 0</inertia>",
    );
    assert_model_error(
        load(&xml),
        r#"Body "shank""#,
        line,
        &["not positive semi-definite"],
    );
}

#[test]
fn wrong_number_of_inertia_values_is_an_error() {
    for values in ["0.09 0.08 0.05", "0.09 0.08 0.05 0 0 0 0", ""] {
        let (xml, _) = replace_after(
            DEMO,
            r#"<Body name="pelvis">"#,
            "<inertia>0.09 0.08 0.05 0 0 0</inertia>",
            &format!("<inertia>{values}</inertia>"),
        );
        let line = line_of(&xml, r#"<Body name="pelvis">"#);
        let found = values.split_whitespace().count().to_string();
        assert_model_error(
            load(&xml),
            r#"Body "pelvis""#,
            line,
            &["<inertia>", "6 numbers", &found],
        );
    }
}

#[test]
fn two_bodies_with_the_same_name_are_an_error() {
    let xml = replace_unique(DEMO, r#"<Body name="foot">"#, r#"<Body name="shank">"#);
    let line = line_at(&xml, xml.rfind(r#"<Body name="shank">"#).unwrap());
    assert_model_error(load(&xml), r#"Body "shank""#, line, &["two bodies"]);
}

#[test]
fn body_that_no_joint_connects_is_an_error_at_its_line() {
    // A sixth body, declared on its own line after the patella.
    let (xml, _) = replace_after(
        DEMO,
        r#"<Body name="patella">"#,
        "</Body>",
        "</Body>\n<Body name=\"orphan\"><mass>1</mass><inertia>0.1 0.1 0.1 0 0 0</inertia></Body>",
    );
    let line = line_of(&xml, r#"<Body name="orphan">"#);
    assert_model_error(load(&xml), "orphan", line, &["no joint"]);
}

#[test]
fn unknown_element_in_a_body_is_a_warning_with_its_line() {
    let (xml, line) = replace_after(
        DEMO,
        r#"<Body name="pelvis">"#,
        "<mass>10</mass>",
        "<mass>10</mass><FancyThing/>",
    );
    let model = load(&xml).expect("an unknown element is not an error");
    let w = model
        .warnings
        .iter()
        .find(|w| w.element.contains("FancyThing"))
        .unwrap_or_else(|| panic!("no warning names FancyThing: {:?}", model.warnings));
    assert_eq!(w.line, line);
    assert!(w.element.contains(r#"Body "pelvis""#), "{}", w.element);
    assert!(w.message.contains("not recognised"), "{}", w.message);
    assert_eq!(model.warnings.len(), 1, "{:?}", model.warnings);
}

// ---------------------------------------------------------------------------------------
// Component names.

/// OpenSim 4 refuses `/` (the component-path separator), `\`, `*`, `+` and whitespace in a
/// component's name; so does the reader, naming the element, its line and the name, for
/// every kind of component it names. (A coordinate named `../../x` would otherwise make
/// `musculo muscles` write `…_MomentArm_../../x.sto` outside its folder.)
#[test]
fn component_names_with_characters_opensim_forbids_are_errors_naming_the_element() {
    let cases = [
        (r#"<Body name="thigh">"#, "Body", "thigh"),
        (r#"<PinJoint name="ankle">"#, "PinJoint", "ankle"),
        (
            r#"<Coordinate name="knee_angle">"#,
            "Coordinate",
            "knee_angle",
        ),
        (
            r#"<WrapCylinder name="knee_wrap">"#,
            "WrapCylinder",
            "knee_wrap",
        ),
        (
            r#"<Thelen2003Muscle name="vasti">"#,
            "Thelen2003Muscle",
            "vasti",
        ),
        (r#"<PathPoint name="vasti-P1">"#, "PathPoint", "vasti-P1"),
        (r#"<Marker name="toe">"#, "Marker", "toe"),
        (
            r#"<CoordinateCouplerConstraint name="patella_follows_knee">"#,
            "CoordinateCouplerConstraint",
            "patella_follows_knee",
        ),
        (r#"<Ground name="ground" />"#, "Ground", "ground"),
    ];
    for (anchor, tag, name) in cases {
        for bad in ["a/b", "../../pwn"] {
            let to = anchor.replace(&format!("\"{name}\""), &format!("\"{bad}\""));
            let xml = replace_unique(DEMO, anchor, &to);
            let line = line_of(&xml, &to);
            assert_model_error(
                load(&xml),
                &format!("{tag} \"{bad}\""),
                line,
                &[&format!("\"{bad}\""), "contains `/`", "OpenSim forbids"],
            );
        }
    }
    for (bad, what) in [
        (r"a\b", "`\\`"),
        ("a*b", "`*`"),
        ("a+b", "`+`"),
        ("a b", "a space"),
        ("a&#9;b", "a tab"),
        ("a&#10;b", "a line break"),
    ] {
        let to = format!("<Coordinate name=\"{bad}\">");
        let xml = replace_unique(DEMO, r#"<Coordinate name="knee_angle">"#, &to);
        let line = line_of(&xml, &to);
        assert_model_error(
            load(&xml),
            "Coordinate",
            line,
            &[&format!("contains {what}"), "OpenSim forbids"],
        );
    }
    // The model's own name is a component name too.
    let xml = replace_unique(
        DEMO,
        r#"<Model name="musculo_demo_leg">"#,
        r#"<Model name="demo/leg">"#,
    );
    let line = line_of(&xml, r#"<Model name="demo/leg">"#);
    assert_model_error(
        load(&xml),
        "<Model>",
        line,
        &["\"demo/leg\"", "contains `/`"],
    );
}

/// Characters OpenSim allows in names (`-`, `.`, `:`, `|`, digits) and surrounding
/// whitespace, which the reader trims, still load.
#[test]
fn component_names_with_allowed_characters_load() {
    let xml = replace_unique(
        DEMO,
        r#"<Coordinate name="knee_angle">"#,
        r#"<Coordinate name=" knee.angle-r:1|x ">"#,
    );
    let xml = xml.replace(">knee_angle<", ">knee.angle-r:1|x<");
    let model = load(&xml).expect("allowed characters load");
    assert!(model.coordinate_index("knee.angle-r:1|x").is_some());
}

// ---------------------------------------------------------------------------------------
// Joints and the tree.

#[test]
fn joint_whose_parent_frame_names_a_missing_body_is_an_error() {
    // The socket names a body path directly.
    let (xml, _) = replace_after(
        DEMO,
        r#"<PinJoint name="hip">"#,
        "<socket_parent_frame>pelvis_offset</socket_parent_frame>",
        "<socket_parent_frame>/bodyset/pelvix</socket_parent_frame>",
    );
    let line = line_of(&xml, r#"<PinJoint name="hip">"#);
    assert_model_error(
        load(&xml),
        r#"PinJoint "hip""#,
        line,
        &["parent frame", "/bodyset/pelvix"],
    );

    // The joint's offset frame names a missing body.
    let (xml, _) = replace_after(
        DEMO,
        r#"<PinJoint name="hip">"#,
        "<socket_parent>/bodyset/pelvis</socket_parent>",
        "<socket_parent>/bodyset/pelvix</socket_parent>",
    );
    assert_model_error(
        load(&xml),
        r#"PinJoint "hip""#,
        line,
        &["parent frame", "/bodyset/pelvix"],
    );

    // A bare name that is no frame.
    let xml = minimal(&body("a"), &pin("j", "nowhere", "/bodyset/a", "q"));
    let line = line_of(&xml, r#"<PinJoint name="j">"#);
    assert_model_error(
        load(&xml),
        r#"PinJoint "j""#,
        line,
        &["parent frame", "nowhere"],
    );
}

#[test]
fn cycle_of_joints_disconnected_from_ground_is_an_error() {
    let bodies = format!("{}\n{}", body("a"), body("b"));
    let joints = format!(
        "{}\n{}",
        pin("a_to_b", "/bodyset/a", "/bodyset/b", "qa"),
        pin("b_to_a", "/bodyset/b", "/bodyset/a", "qb")
    );
    let xml = minimal(&bodies, &joints);
    let line = line_of(&xml, r#"<PinJoint name="a_to_b">"#);
    assert_model_error(
        load(&xml),
        r#"PinJoint "a_to_b""#,
        line,
        &["cycle", "a_to_b", "b_to_a"],
    );
}

#[test]
fn joint_hanging_from_an_unconnected_body_is_an_error() {
    let bodies = format!("{}\n{}", body("a"), body("b"));
    let xml = minimal(&bodies, &pin("a_to_b", "/bodyset/a", "/bodyset/b", "q"));
    let line = line_of(&xml, r#"<PinJoint name="a_to_b">"#);
    assert_model_error(
        load(&xml),
        r#"PinJoint "a_to_b""#,
        line,
        &["not connected to ground", "/bodyset/a"],
    );
}

#[test]
fn unsupported_joint_type_is_an_error() {
    let (xml, _) = replace_after(
        DEMO,
        r#"<PinJoint name="ankle">"#,
        "</PinJoint>",
        "</EllipsoidJoint>",
    );
    let xml = replace_unique(
        &xml,
        r#"<PinJoint name="ankle">"#,
        r#"<EllipsoidJoint name="ankle">"#,
    );
    let line = line_of(&xml, r#"<EllipsoidJoint name="ankle">"#);
    assert_model_error(
        load(&xml),
        r#"EllipsoidJoint "ankle""#,
        line,
        &["unsupported joint type", "EllipsoidJoint"],
    );
}

#[test]
fn pin_joint_with_the_wrong_number_of_coordinates_is_an_error() {
    let extra = r#"<Coordinate name="hip_extra"><default_value>0</default_value></Coordinate>"#;
    let (two, _) = replace_after(
        DEMO,
        r#"<PinJoint name="hip">"#,
        "</coordinates>",
        &format!("{extra}</coordinates>"),
    );
    let line = line_of(&two, r#"<PinJoint name="hip">"#);
    assert_model_error(
        load(&two),
        r#"PinJoint "hip""#,
        line,
        &["PinJoint needs 1 coordinate", "found 2"],
    );

    let none = minimal(
        &body("a"),
        &pin("j", "/ground", "/bodyset/a", "q").replace(r#"<Coordinate name="q" />"#, ""),
    );
    let line = line_of(&none, r#"<PinJoint name="j">"#);
    assert_model_error(
        load(&none),
        r#"PinJoint "j""#,
        line,
        &["PinJoint needs 1 coordinate", "found 0"],
    );
}

#[test]
fn transform_axis_naming_a_coordinate_of_another_joint_is_an_error() {
    // hip_flexion exists, but not in the knee: unknown coordinate in a function.
    let (xml, _) = replace_after(
        DEMO,
        r#"<CustomJoint name="knee">"#,
        "<coordinates>knee_angle</coordinates>",
        "<coordinates>hip_flexion</coordinates>",
    );
    let line = line_of(&xml, "<coordinates>hip_flexion</coordinates>") - 1;
    assert_model_error(
        load(&xml),
        r#"CustomJoint "knee" > <SpatialTransform> > TransformAxis "rotation1""#,
        line,
        &["unknown coordinate", "hip_flexion"],
    );
}

#[test]
fn transform_axis_naming_a_missing_coordinate_is_an_error() {
    let (xml, _) = replace_after(
        DEMO,
        r#"<CustomJoint name="patellofemoral">"#,
        "<coordinates>patella_angle</coordinates>",
        "<coordinates>patela_angle</coordinates>",
    );
    let line = line_of(&xml, "<coordinates>patela_angle</coordinates>") - 1;
    assert_model_error(
        load(&xml),
        r#"TransformAxis "rotation1""#,
        line,
        &["unknown coordinate", "patela_angle"],
    );
}

#[test]
fn coordinate_coupler_naming_an_unknown_coordinate_is_an_error() {
    let anchor = r#"<CoordinateCouplerConstraint name="patella_follows_knee">"#;
    let (xml, _) = replace_after(
        DEMO,
        anchor,
        "<independent_coordinate_names>knee_angle</independent_coordinate_names>",
        "<independent_coordinate_names>knee_angel</independent_coordinate_names>",
    );
    let line = line_of(&xml, anchor);
    assert_model_error(
        load(&xml),
        r#"CoordinateCouplerConstraint "patella_follows_knee""#,
        line,
        &["unknown independent coordinate", "knee_angel"],
    );
    let (xml, _) = replace_after(
        DEMO,
        anchor,
        "<dependent_coordinate_name>patella_angle</dependent_coordinate_name>",
        "<dependent_coordinate_name>kneecap</dependent_coordinate_name>",
    );
    assert_model_error(
        load(&xml),
        r#"CoordinateCouplerConstraint "patella_follows_knee""#,
        line,
        &["unknown dependent coordinate", "kneecap"],
    );
}

// ---------------------------------------------------------------------------------------
// Functions and numbers.

#[test]
fn unsupported_function_type_is_an_error() {
    // The first SimmSpline of the knee drives its translation1.
    let (xml, _) = replace_after(
        DEMO,
        r#"<CustomJoint name="knee">"#,
        "<SimmSpline name=\"function\">",
        "<Sine name=\"function\">",
    );
    let (xml, _) = replace_after(&xml, "<Sine name=\"function\">", "</SimmSpline>", "</Sine>");
    let line = line_of(&xml, "<Sine name=\"function\">");
    assert_model_error(
        load(&xml),
        r#"TransformAxis "translation1" > Sine "function""#,
        line,
        &["unsupported function type", "Sine"],
    );
}

#[test]
fn non_finite_numbers_are_errors_at_their_element() {
    for junk in ["nan", "NaN", "inf", "-inf", "infinity", "1e999", "-1e400"] {
        // In a body's <mass_center>.
        let (xml, line) = replace_after(
            DEMO,
            r#"<Body name="thigh">"#,
            "<mass_center>0 -0.17 0</mass_center>",
            &format!("<mass_center>0 {junk} 0</mass_center>"),
        );
        assert_model_error(
            load(&xml),
            r#"Body "thigh" > <mass_center>"#,
            line,
            &["not a finite number", junk],
        );

        // In a coordinate's default value.
        let (xml, line) = replace_after(
            DEMO,
            r#"<Coordinate name="hip_flexion">"#,
            "<default_value>0</default_value>",
            &format!("<default_value>{junk}</default_value>"),
        );
        assert_model_error(
            load(&xml),
            r#"Coordinate "hip_flexion" > <default_value>"#,
            line,
            &["not a finite number"],
        );

        // In a spline's knots.
        let (xml, line) = replace_after(
            DEMO,
            "<x>-2.0 -1.2 -0.5 0 0.15</x>",
            "<x>-2.0",
            &format!("<x>{junk}"),
        );
        assert_model_error(
            load(&xml),
            r#"SimmSpline "function" > <x>"#,
            line,
            &["not a finite number"],
        );
    }
}

#[test]
fn text_that_is_not_a_number_is_an_error() {
    let (xml, line) = replace_after(
        DEMO,
        r#"<Body name="thigh">"#,
        "<mass>8</mass>",
        "<mass>eight</mass>",
    );
    assert_model_error(
        load(&xml),
        r#"Body "thigh" > <mass>"#,
        line,
        &["`eight` is not a number"],
    );
    let (xml, line) = replace_after(
        DEMO,
        r#"<Body name="thigh">"#,
        "<mass>8</mass>",
        "<mass>8 9</mass>",
    );
    assert_model_error(
        load(&xml),
        r#"Body "thigh" > <mass>"#,
        line,
        &["one number", "found 2"],
    );
}

#[test]
fn spline_with_non_increasing_x_is_an_error() {
    let anchor = "<x>-2.0 -1.5 -1.0";
    let (xml, _) = replace_after(DEMO, anchor, "<x>-2.0 -1.5 -1.0", "<x>-2.0 -1.5 -1.5");
    let line = line_of(&xml, "<x>-2.0 -1.5 -1.5") - 1;
    assert_model_error(
        load(&xml),
        r#"TransformAxis "translation1" > SimmSpline "function""#,
        line,
        &["strictly increasing", "x[2]"],
    );
    // Decreasing.
    let (xml, _) = replace_after(DEMO, anchor, "<x>-2.0 -1.5 -1.0", "<x>-2.0 -1.0 -1.5");
    assert_model_error(
        load(&xml),
        r#"SimmSpline "function""#,
        line,
        &["strictly increasing"],
    );
    // x and y of different lengths.
    let (xml, _) = replace_after(DEMO, anchor, "<x>-2.0 -1.5 -1.0", "<x>-2.0 -1.0");
    assert_model_error(
        load(&xml),
        r#"SimmSpline "function""#,
        line,
        &["x has 5 values but y has 6"],
    );
}

// ---------------------------------------------------------------------------------------
// Forces and paths.

#[test]
fn path_point_on_an_unknown_body_is_an_error() {
    let anchor = r#"<PathPoint name="vasti-P2">"#;
    let (xml, _) = replace_after(DEMO, anchor, "/bodyset/patella", "/bodyset/kneecap");
    let line = line_of(&xml, anchor);
    assert_model_error(
        load(&xml),
        r#"Thelen2003Muscle "vasti" > GeometryPath "geometrypath" > <PathPointSet> > PathPoint "vasti-P2""#,
        line,
        &["socket_parent_frame", "/bodyset/kneecap"],
    );
}

#[test]
fn conditional_path_point_with_an_unknown_coordinate_is_an_error() {
    let anchor = r#"<PathPoint name="vasti-P2">"#;
    let conditional = r#"<ConditionalPathPoint name="vasti-P2">"#;
    let (xml, _) = replace_after(
        DEMO,
        anchor,
        "</PathPoint>",
        "<socket_coordinate>/jointset/knee/knee_anglx</socket_coordinate><range>-2 0</range></ConditionalPathPoint>",
    );
    let xml = replace_unique(&xml, anchor, conditional);
    let line = line_of(&xml, conditional);
    assert_model_error(
        load(&xml),
        r#"ConditionalPathPoint "vasti-P2""#,
        line,
        &["unknown coordinate", "knee_anglx"],
    );
    // The same point with a known coordinate loads.
    let good = xml.replace("knee_anglx", "knee_angle");
    let model = load(&good).expect("a valid ConditionalPathPoint loads");
    assert!(
        model.forces[0]
            .path
            .as_ref()
            .unwrap()
            .points
            .iter()
            .any(|p| matches!(p.kind, musculo::model::PathPointKind::Conditional { .. }))
    );
    // A coordinate of another joint than the one named in the path.
    let wrong_joint = xml.replace("/jointset/knee/knee_anglx", "/jointset/knee/hip_flexion");
    assert_model_error(
        load(&wrong_joint),
        r#"ConditionalPathPoint "vasti-P2""#,
        line,
        &["does not belong to joint `knee`"],
    );
}

#[test]
fn muscle_with_non_positive_optimal_fiber_length_is_an_error() {
    let anchor = r#"<Thelen2003Muscle name="vasti">"#;
    for value in ["0", "-0.087", "-0"] {
        let (xml, _) = replace_after(
            DEMO,
            anchor,
            "<optimal_fiber_length>0.087</optimal_fiber_length>",
            &format!("<optimal_fiber_length>{value}</optimal_fiber_length>"),
        );
        let line = line_of(&xml, anchor);
        assert_model_error(
            load(&xml),
            r#"Thelen2003Muscle "vasti""#,
            line,
            &["<optimal_fiber_length> must be positive"],
        );
    }
}

#[test]
fn path_wrap_naming_an_unknown_wrap_object_is_an_error() {
    let anchor = r#"<PathWrap name="pathwrap">"#;
    let (xml, _) = replace_after(
        DEMO,
        anchor,
        "<wrap_object>knee_wrap</wrap_object>",
        "<wrap_object>hip_wrap</wrap_object>",
    );
    let line = line_of(&xml, anchor);
    assert_model_error(
        load(&xml),
        r#"PathWrap "pathwrap""#,
        line,
        &["unknown wrap object", "hip_wrap"],
    );
}

#[test]
fn offset_frames_that_are_each_others_parent_are_an_error() {
    let frames = r#"<frames>
<PhysicalOffsetFrame name="f1">
<socket_parent>f2</socket_parent>
</PhysicalOffsetFrame>
<PhysicalOffsetFrame name="f2">
<socket_parent>f1</socket_parent>
</PhysicalOffsetFrame>
</frames>
</PinJoint>"#;
    let joint = pin("j", "f1", "/bodyset/a", "q").replace("</PinJoint>", frames);
    let xml = minimal(&body("a"), &joint);
    let line = line_of(&xml, r#"<PinJoint name="j">"#);
    assert_model_error(
        load(&xml),
        r#"PinJoint "j""#,
        line,
        &["parent frame", "cycle"],
    );

    // A frame that is its own parent.
    let joint = pin("j", "f1", "/bodyset/a", "q").replace(
        "</PinJoint>",
        &frames.replace(
            "<socket_parent>f2</socket_parent>",
            "<socket_parent>f1</socket_parent>",
        ),
    );
    let xml = minimal(&body("a"), &joint);
    assert_model_error(
        load(&xml),
        r#"PinJoint "j""#,
        line,
        &["parent frame", "cycle"],
    );
}

#[test]
fn deeply_nested_elements_are_an_error_not_a_stack_overflow() {
    let depth = 100_000;
    // Inside a force element, which is kept verbatim.
    let nested = format!("{}{}", "<a>".repeat(depth), "</a>".repeat(depth));
    let (xml, line) = replace_after(
        DEMO,
        r#"<Thelen2003Muscle name="vasti">"#,
        "<max_isometric_force>",
        &format!("{nested}<max_isometric_force>"),
    );
    assert_model_error(load(&xml), "<a>", line, &["nested more than"]);
    // Nested multiplier functions in a TransformAxis.
    let nested = format!(
        "{}<Constant><value>1</value></Constant>{}",
        "<MultiplierFunction><function>".repeat(depth),
        "</function></MultiplierFunction>".repeat(depth)
    );
    let (xml, line) = replace_after(
        DEMO,
        r#"<CustomJoint name="knee">"#,
        "<LinearFunction name=\"function\">",
        &format!("{nested}<LinearFunction name=\"function\">"),
    );
    assert_model_error(
        load(&xml),
        "<MultiplierFunction>",
        line,
        &["nested more than"],
    );
    // Twenty levels of multipliers are fine (the first function element of the axis is used).
    // (Halving at each level: doubling would turn the knee 2²⁰ rad, which the reader now
    // refuses as no joint's motion.)
    let nested = format!(
        "{}<LinearFunction><coefficients>1 0</coefficients></LinearFunction>{}",
        "<MultiplierFunction><scale>0.5</scale><function>".repeat(20),
        "</function></MultiplierFunction>".repeat(20)
    );
    let (xml, _) = replace_after(
        DEMO,
        r#"<CustomJoint name="knee">"#,
        "<LinearFunction name=\"function\">",
        &format!("{nested}<LinearFunction name=\"function\">"),
    );
    let model = load(&xml).expect("20 nested multipliers load");
    let dof = model
        .dofs
        .iter()
        .find(|d| d.name == "knee/rotation1")
        .unwrap();
    assert_eq!(dof.function.eval1(0.5).0, 0.5f64.powi(20) * 0.5);
}

// ---------------------------------------------------------------------------------------
// Kinematic functions over their coordinates' ranges: one check when the model is read, so
// that `inspect`, `export-mjcf`, `id`, `evaluate` and `augment` refuse the same models.

#[test]
fn coordinate_range_whose_width_overflows_is_an_error() {
    // Before: read, and `export-mjcf` panicked in the SVD of an empty matrix (exit 101).
    let anchor = r#"<Coordinate name="knee_angle">"#;
    let (xml, _) = replace_after(
        DEMO,
        anchor,
        "<range>-2.0 0.15</range>",
        "<range>-1e308 1e308</range>",
    );
    assert_model_error(
        load(&xml),
        r#"Coordinate "knee_angle""#,
        line_of(&xml, anchor),
        &["<range>", "-1e308", "width overflows"],
    );
}

#[test]
fn spline_knots_closer_than_a_billionth_of_their_span_are_an_error() {
    // Before: knots one floating-point step apart passed the strictly-increasing check and
    // `id` gave 10²⁶ N·m; a subnormal gap overflowed to NaN poses in `export-mjcf`.
    let spline = "<x>-2.0 -1.0 -0.5 0 0.15</x>";
    let one_step = f64::from_bits((-0.5f64).to_bits() - 1); // -0.49999999999999994
    for (x, knot) in [
        (format!("<x>-2.0 -1.0 -0.5 {one_step:?} 0.15</x>"), "x[3]"),
        (
            "<x>-2.0 -1.0 -0.5 0 5e-324</x>".to_string(),
            "x[4] = 5e-324",
        ),
    ] {
        let (xml, _) = replace_after(DEMO, spline, spline, &x);
        let line = line_of(&xml, &x) - 1;
        assert_model_error(
            load(&xml),
            r#"TransformAxis "rotation1" > SimmSpline "function""#,
            line,
            &[knot, "knots closer than 1e-9 of the knots' span"],
        );
    }
}

#[test]
fn kinematic_functions_that_overflow_over_their_ranges_are_errors() {
    // Each was read; `id` failed with a NaN torque named at a pelvis column, `export-mjcf`
    // wrote NaN coefficients, `evaluate` printed NaN residuals under exit 0.
    let coupler = r#"<CoordinateCouplerConstraint name="patella_follows_knee">"#;
    let patella = r#"<CustomJoint name="patellofemoral">"#;
    let spline_y = "<y>-0.6 -0.35 -0.12 0.0 0.01</y>";
    let cases: Vec<(String, &str, &str, &[&str])> = vec![
        (
            replace_unique(
                DEMO,
                "<scale_factor>1</scale_factor>",
                "<scale_factor>1e308</scale_factor>",
            ),
            coupler,
            r#"CoordinateCouplerConstraint "patella_follows_knee""#,
            &["scale_factor 1e308", "-inf", "knee_angle = -2"],
        ),
        (
            replace_after(
                DEMO,
                coupler,
                "<LinearFunction>\n\t\t\t\t\t\t\t<coefficients>1 0</coefficients>\n\t\t\t\t\t\t</LinearFunction>",
                "<PolynomialFunction><coefficients>1e200 1e200 1 0</coefficients></PolynomialFunction>",
            )
            .0,
            coupler,
            r#"CoordinateCouplerConstraint "patella_follows_knee""#,
            &["PolynomialFunction", "beyond ±1e6"],
        ),
        (
            replace_unique(DEMO, spline_y, "<y>-0.6 -0.35 -0.12 1e300 0.01</y>"),
            patella,
            r#"CustomJoint "patellofemoral" > TransformAxis "rotation1" > SimmSpline"#,
            &["patella_angle = ", "beyond ±1e6"],
        ),
        (
            replace_unique(
                DEMO,
                "<x>-2.0 -1.0 -0.5 0 0.15</x>",
                "<x>0 1e-300 2e-300 3e-300 5e-300</x>",
            ),
            "<x>0 1e-300",
            r#"TransformAxis "rotation1" > SimmSpline "function""#,
            &["too large for the spacing of its knots"],
        ),
    ];
    for (xml, anchor, element, message) in cases {
        // the spline's own errors are at its element (the line before its <x>)
        let line = match anchor {
            "<x>0 1e-300" => line_of(&xml, anchor) - 1,
            _ => line_of(&xml, anchor),
        };
        assert_model_error(load(&xml), element, line, message);
    }
}

#[test]
fn every_command_refuses_a_model_whose_functions_overflow_with_the_same_located_message() {
    // One validation for every command: before, `inspect` and `export-mjcf` accepted what
    // `id` refused (or panicked on it).
    let dir = std::env::temp_dir().join(format!("musculo-overflow-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("m.osim");
    let xml = replace_after(
        DEMO,
        r#"<Coordinate name="knee_angle">"#,
        "<range>-2.0 0.15</range>",
        "<range>-1e308 1e308</range>",
    )
    .0;
    std::fs::write(&model, xml).unwrap();
    let m = model.to_str().unwrap();
    let out = dir.join("out.xml");
    let o = out.to_str().unwrap();
    for args in [
        vec!["inspect", m],
        vec!["export-mjcf", m, "-o", o],
        vec!["check", m],
    ] {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_musculo"))
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("m.osim:115: ") && stderr.contains(r#"Coordinate "knee_angle""#),
            "{args:?}: {stderr}"
        );
    }
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).ok();
}

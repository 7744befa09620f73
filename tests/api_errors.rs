//! Bad arguments to the dynamics functions are errors naming the argument, never panics.

use musculo::spatial::Vec3;
use musculo::{Data, Error, Model, dynamics};
use nalgebra::DMatrix;

fn argument(e: Error) -> String {
    match e {
        Error::InvalidArgument { argument, .. } => argument.to_string(),
        other => panic!("expected InvalidArgument, got {other}"),
    }
}

#[test]
fn wrong_sizes_non_finite_values_and_foreign_data_are_errors() {
    let model = Model::demo();
    let n = model.nq();
    let mut data = Data::new(&model);
    let q = model.default_q();
    assert_eq!(
        argument(dynamics::crba(&model, &mut data, &q[..n - 1]).unwrap_err()),
        "q"
    );
    let mut bad = q.clone();
    bad[2] = f64::NAN;
    assert_eq!(
        argument(dynamics::rnea(&model, &mut data, &bad, &q, &q).unwrap_err()),
        "q"
    );
    assert_eq!(
        argument(dynamics::rnea(&model, &mut data, &q, &q[..1], &q).unwrap_err()),
        "qd"
    );
    assert_eq!(
        argument(dynamics::rnea(&model, &mut data, &q, &q, &[]).unwrap_err()),
        "qdd"
    );
    assert_eq!(
        argument(dynamics::forward_kinematics_full(&model, &mut data, &q, &q).unwrap_err()),
        "theta"
    );

    // A workspace built for another model.
    let other = Model::from_osim_str(
        &include_str!("../models/demo.osim")
            .replace("<Body name=\"patella\">", "<Body name=\"patella\"><!-- -->"),
        "same shape",
    )
    .unwrap();
    let mut small = Data::new(&Model::from_osim_str(
        r#"<OpenSimDocument Version="40000"><Model><BodySet><objects><Body name="b"><mass>1</mass><inertia>1 1 1 0 0 0</inertia></Body></objects></BodySet>
        <JointSet><objects><PinJoint name="j"><socket_parent_frame>/ground</socket_parent_frame><socket_child_frame>/bodyset/b</socket_child_frame>
        <coordinates><Coordinate name="a"/></coordinates></PinJoint></objects></JointSet></Model></OpenSimDocument>"#,
        "tiny",
    ).unwrap());
    assert_eq!(
        argument(dynamics::crba(&model, &mut small, &q).unwrap_err()),
        "data"
    );
    let mut same = Data::new(&other);
    assert!(
        dynamics::crba(&model, &mut same, &q).is_ok(),
        "a Data of the same shape is usable"
    );
}

#[test]
fn stages_body_indices_and_output_shapes_are_checked() {
    let model = Model::demo();
    let n = model.nq();
    let mut data = Data::new(&model);
    let mut j = DMatrix::zeros(3, n);
    assert!(matches!(
        dynamics::point_jacobian(&model, &data, 1, &Vec3::zeros(), &mut j),
        Err(Error::StageNotComputed { .. })
    ));
    assert!(matches!(
        dynamics::kinetic_energy(&model, &data),
        Err(Error::StageNotComputed { .. })
    ));
    dynamics::forward_kinematics(&model, &mut data, &model.default_q()).unwrap();
    assert!(
        matches!(dynamics::momentum(&model, &data), Err(Error::StageNotComputed { needs, .. }) if needs.contains("velocity"))
    );
    assert_eq!(
        argument(dynamics::point_jacobian(&model, &data, 99, &Vec3::zeros(), &mut j).unwrap_err()),
        "body"
    );
    let mut wrong = DMatrix::zeros(6, n);
    assert_eq!(
        argument(
            dynamics::point_jacobian(&model, &data, 1, &Vec3::zeros(), &mut wrong).unwrap_err()
        ),
        "out"
    );
    let mut markers = vec![Vec3::zeros(); 1];
    assert_eq!(
        argument(data.marker_positions(&model, &mut markers).unwrap_err()),
        "out"
    );
    // After forward_kinematics_full the reduced Jacobians are unavailable.
    let theta = vec![0.1; model.n_full()];
    dynamics::forward_kinematics_full(&model, &mut data, &theta, &theta).unwrap();
    assert!(matches!(
        dynamics::point_jacobian(&model, &data, 1, &Vec3::zeros(), &mut j),
        Err(Error::StageNotComputed { .. })
    ));
}

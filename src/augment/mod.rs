//! `musculo augment`: a motion dataset in, per-clip tensors of what the motion physically
//! required out — joint torques, ground contact forces, muscle activations and forces —
//! in the per-joint layout of METHOD.md §1 and in generalized coordinates.
//!
//! - [`chain`]: the per-clip chain (IK → filtering → ID → contacts → static optimization →
//!   excitations);
//! - [`layout`]: the per-joint quantities and the flattened vector `x`;
//! - [`perturb`]: seeded variants (height, mass, carried load, speed);
//! - [`output`]: the files (`.npz`, records, manifest, statistics), written atomically;
//! - [`dataset`]: HumanML3D / KIT-ML roots given as input (motion folder, captions, splits);
//! - [`runner`]: the dataset run — shards, resume, parallel clips — and `merge`;
//! - [`verdict`]: ok / suspect / failed per clip, from its quality figures;
//! - [`demo`]: the shipped sample clips of `musculo augment --demo`.

pub mod chain;
pub mod dataset;
pub mod demo;
pub mod identity;
pub mod layout;
pub mod layout_inverse;
pub mod layout_inverse_vjp;
pub mod output;
pub mod perturb;
pub mod runner;
pub mod verdict;

use layout::JointLayout;
use output::LayoutDescription;

/// The manifest's description of the arrays a chain emits for its base model (every clip
/// of a run has the same layout: scaling changes sizes, not the topology).
pub fn describe(chain: &chain::Chain) -> crate::Result<LayoutDescription> {
    let model = &chain.model;
    let set = chain::contact_set(model)?;
    let muscles = crate::muscle::MuscleSet::new(model)?;
    let muscle_names: Vec<String> = muscles
        .muscles
        .iter()
        .map(|m| m.name().to_string())
        .collect();
    let layout = JointLayout::new(model, muscle_names.len());
    let names = model.q_names();
    let units = [
        ("joint_pos", "m (ground)"),
        ("joint_rot", "rad (rotation vector, parent joint frame)"),
        ("joint_vel", "rad/s (parent joint frame)"),
        ("joint_acc", "rad/s^2 (parent joint frame)"),
        ("muscle_act", "1"),
        ("joint_torque", "N m (parent joint frame)"),
        ("contact_force", "N (ground)"),
        ("x", "per block"),
        ("q", "rad or m (model coordinates)"),
        ("qd", "rad/s or m/s"),
        ("qdd", "rad/s^2 or m/s^2"),
        (
            "tau",
            "N m or N (generalized forces carried by actuators and residuals)",
        ),
        ("grf", "N (ground, per contact group)"),
        ("cop", "m (ground, on the floor plane)"),
        ("free_moment", "N m (about the floor normal)"),
        ("contact_point_force", "N (ground)"),
        ("contact_point_pos", "m (ground)"),
        ("contact_state", "1 = carrying load"),
        ("muscle_force", "N"),
        ("muscle_length", "m (musculotendon)"),
        ("fiber_length", "m"),
        ("fiber_velocity", "m/s"),
        ("excitation", "1"),
        (
            "residual",
            "N m or N (floating-base rows no contact explained)",
        ),
        ("time", "s"),
        (
            "ik_marker_error",
            "m (per IK marker, the clip record's ik_markers; NaN: no target)",
        ),
    ];
    Ok(LayoutDescription {
        joints: layout.names.clone(),
        muscles: muscle_names,
        coordinates: names.iter().map(|s| s.to_string()).collect(),
        floating_base: set
            .floating_base
            .iter()
            .map(|&j| names[j].to_string())
            .collect(),
        contact_points: set.points.iter().map(|p| p.name.clone()).collect(),
        contact_groups: set.groups().to_vec(),
        x: layout.ranges(),
        units: units
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect(),
    })
}

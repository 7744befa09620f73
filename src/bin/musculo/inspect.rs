//! `musculo inspect`: a model summary for people (table) or programs (`--json`).

use musculo::model::{CoordinateRole, Model, MotionType};
use serde_json::json;
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim 4.x model file (.osim).
    #[arg(required_unless_present = "demo", conflicts_with = "demo")]
    model: Option<PathBuf>,
    /// Inspect the small built-in demonstration model instead of a file.
    #[arg(long)]
    demo: bool,
    /// Print JSON instead of tables.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    // Every warning is listed below, so none is printed at loading.
    let model = match &args.model {
        Some(p) => Model::from_osim_file_with(p, &args.strict.load_options())?,
        None => Model::demo(),
    };
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&to_json(&model)).unwrap_or_default()
        );
    } else {
        print!("{}", to_text(&model));
    }
    Ok(())
}

fn role(model: &Model, r: CoordinateRole) -> String {
    match r {
        CoordinateRole::Independent(j) => format!("q[{j}]"),
        CoordinateRole::Locked => "locked".into(),
        CoordinateRole::Dependent(k) => {
            let c = &model.couplers[k];
            let ind: Vec<&str> = c
                .independents
                .iter()
                .map(|&i| model.coordinates[i].name.as_str())
                .collect();
            format!("= f({}) [{}]", ind.join(", "), c.name)
        }
    }
}

fn motion(m: MotionType) -> &'static str {
    match m {
        MotionType::Rotational => "rotational",
        MotionType::Translational => "translational",
        MotionType::Coupled => "coupled",
    }
}

fn force_kinds(model: &Model) -> BTreeMap<&str, usize> {
    let mut kinds = BTreeMap::new();
    for f in &model.forces {
        *kinds.entry(f.kind.as_str()).or_insert(0) += 1;
    }
    kinds
}

fn to_text(model: &Model) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let n_dep = model.couplers.len();
    let n_locked = model
        .coordinates
        .iter()
        .filter(|c| c.role == CoordinateRole::Locked)
        .count();
    let _ = writeln!(s, "model       {} ({})", model.name, model.source);
    let _ = writeln!(s, "bodies      {} (plus ground)", model.bodies.len() - 1);
    let _ = writeln!(s, "joints      {}", model.joints.len());
    let _ = writeln!(
        s,
        "coordinates {} : {} independent, {} dependent (coupled), {} locked",
        model.coordinates.len(),
        model.nq(),
        n_dep,
        n_locked
    );
    let _ = writeln!(s, "full coords {} movable transform axes", model.n_full());
    let kinds = force_kinds(model);
    let muscles: Vec<String> = kinds
        .iter()
        .filter(|(k, _)| k.ends_with("Muscle"))
        .map(|(k, n)| format!("{n} {k}"))
        .collect();
    let _ = writeln!(
        s,
        "muscles     {}{}",
        model.muscle_count(),
        if muscles.is_empty() {
            String::new()
        } else {
            format!(" ({})", muscles.join(", "))
        }
    );
    let others: Vec<String> = kinds
        .iter()
        .filter(|(k, _)| !k.ends_with("Muscle"))
        .map(|(k, n)| format!("{n} {k}"))
        .collect();
    if !others.is_empty() {
        let _ = writeln!(s, "other forces {}", others.join(", "));
    }
    let _ = writeln!(s, "total mass  {:.4} kg", model.total_mass());
    let _ = writeln!(
        s,
        "gravity     {:.5} {:.5} {:.5} m/s²",
        model.gravity.x, model.gravity.y, model.gravity.z
    );
    let _ = writeln!(s, "markers     {}", model.markers.len());
    let _ = writeln!(s, "contact     {}", model.contact_geometry.len());
    let _ = writeln!(s, "wrap objects {}", model.wrap_objects.len());

    let _ = writeln!(
        s,
        "\nBODIES\n  {:<20} {:>10}  {:<20} parent",
        "name", "mass (kg)", "joint"
    );
    for b in model.bodies.iter().skip(1) {
        let joint = b
            .joint
            .map(|j| model.joints[j].name.as_str())
            .unwrap_or("-");
        let parent = b
            .parent
            .map(|p| model.bodies[p].name.as_str())
            .unwrap_or("-");
        let _ = writeln!(
            s,
            "  {:<20} {:>10.4}  {:<20} {}",
            b.name, b.mass, joint, parent
        );
    }
    let _ = writeln!(
        s,
        "\nJOINTS\n  {:<22} {:<15} {:<28} coordinates",
        "name", "type", "parent -> child"
    );
    for j in &model.joints {
        let coords: Vec<&str> = j
            .coordinates
            .iter()
            .map(|&c| model.coordinates[c].name.as_str())
            .collect();
        let _ = writeln!(
            s,
            "  {:<22} {:<15} {:<28} {}",
            j.name,
            j.kind.name(),
            format!(
                "{} -> {}",
                model.bodies[j.parent_body].name, model.bodies[j.child_body].name
            ),
            coords.join(" ")
        );
    }
    let _ = writeln!(
        s,
        "\nCOORDINATES\n  {:<22} {:<14} {:>10}  {:<24} role",
        "name", "motion", "default", "range"
    );
    for c in &model.coordinates {
        let _ = writeln!(
            s,
            "  {:<22} {:<14} {:>10.4}  {:<24} {}",
            c.name,
            motion(c.motion_type),
            c.default_value,
            format!("[{:.4}, {:.4}]", c.range[0], c.range[1]),
            role(model, c.role)
        );
    }
    let _ = writeln!(
        s,
        "\nNOT USED BY MUSCULO ({} warnings; {} display-only elements skipped)",
        model.warnings.len(),
        model.visual_elements_skipped
    );
    for w in &model.warnings {
        let _ = writeln!(s, "  line {}: {}: {}", w.line, w.element, w.message);
    }
    s
}

fn to_json(model: &Model) -> serde_json::Value {
    json!({
        "name": model.name,
        "source": model.source,
        "total_mass_kg": model.total_mass(),
        "gravity": [model.gravity.x, model.gravity.y, model.gravity.z],
        "n_independent_coordinates": model.nq(),
        "n_full_coordinates": model.n_full(),
        "independent_coordinates": model.q_names(),
        "bodies": model.bodies.iter().skip(1).map(|b| json!({
            "name": b.name,
            "mass": b.mass,
            "joint": b.joint.map(|j| model.joints[j].name.clone()),
            "parent": b.parent.map(|p| model.bodies[p].name.clone()),
        })).collect::<Vec<_>>(),
        "joints": model.joints.iter().map(|j| json!({
            "name": j.name,
            "type": j.kind.name(),
            "parent": model.bodies[j.parent_body].name,
            "child": model.bodies[j.child_body].name,
            "coordinates": j.coordinates.iter().map(|&c| model.coordinates[c].name.clone()).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "coordinates": model.coordinates.iter().map(|c| json!({
            "name": c.name,
            "motion_type": motion(c.motion_type),
            "default_value": c.default_value,
            "range": c.range,
            "role": role(model, c.role),
        })).collect::<Vec<_>>(),
        "muscles": model.muscle_count(),
        "forces": force_kinds(model),
        "markers": model.markers.iter().map(|m| m.name.clone()).collect::<Vec<_>>(),
        "contact_geometry": model.contact_geometry.iter().map(|c| c.name.clone()).collect::<Vec<_>>(),
        "warnings": model.warnings.iter().map(|w| json!({
            "line": w.line, "element": w.element, "message": w.message,
        })).collect::<Vec<_>>(),
        "display_only_elements_skipped": model.visual_elements_skipped,
    })
}

//! `musculo loss`: the Euler–Lagrange residual r = M q̈ + C q̇ + G − τ − J_cᵀλ of a tensor file,
//! summarised per coordinate and per frame, and its muscle loss when it has activations.

use musculo::loss::tensor_file::{
    MuscleSummary, ResidualSummary, TensorFrames, muscle_residual_of, residual_of,
};
use musculo::model::Model;
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Tensor file (.npz with q, qd, qdd, tau and, where there are contacts,
    /// contact_point_force), e.g. a clip written by `musculo augment`; or one with only the
    /// per-joint layout (joint_pos, joint_rot, joint_vel, joint_acc, joint_torque, time), whose
    /// coordinates are then fitted from it.
    file: PathBuf,
    /// OpenSim 4.x model file the tensors belong to. Default: the body the file's model
    /// identity names (augment records it in every clip: its base model, rebuilt with the
    /// clip's scaling and variant, or <clip>.osim beside it); a model given here must be that
    /// base model or the clip's own <clip>.osim, else it is refused. A file without an
    /// identity is read on this model, else <file>.osim beside it, else the built-in model,
    /// with a warning.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Also write the per-frame residual (frame, L_t, |r_t|, |r_t|/|tau_ID,t|) as CSV.
    #[arg(long, value_name = "FILE.csv")]
    per_frame: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    if let Some(p) = &args.model {
        // refuses a nonphysical model under --strict and prints its warnings
        args.strict.load(p)?;
    }
    let body = musculo::augment::identity::Bodies::new(args.model.as_deref())?
        .of_tensor_file(&args.file)?;
    crate::warnings::print(body.warning.as_slice());
    let model: &Model = &body.model;
    let frames = TensorFrames::read(&args.file, model)?;
    let s = residual_of(model, &frames)?;
    let muscle = muscle_residual_of(model, &frames)?;
    if let Some(path) = &args.per_frame {
        let mut csv = String::from("frame,loss,residual_norm,relative_residual\n");
        for t in 0..s.frames {
            let l = s.frame_norm[t] * s.frame_norm[t];
            let _ = writeln!(
                csv,
                "{t},{l:e},{:e},{:e}",
                s.frame_norm[t], s.frame_relative[t]
            );
        }
        crate::tool::write_output(path, csv.as_bytes(), &[args.file.as_path()])?;
    }
    let names = model.q_names();
    if args.json {
        let report = serde_json::json!({
            "file": args.file.display().to_string(),
            "model": model.name,
            "frames": s.frames,
            "contacts": frames.contacts,
            "loss": s.loss,
            "relative_residual": {
                "median": median(&s.frame_relative),
                "max": max(&s.frame_relative),
            },
            "coordinates": names.iter().enumerate().map(|(j, name)| serde_json::json!({
                "name": name, "rms": s.coordinate_rms[j], "max": s.coordinate_max[j],
            })).collect::<Vec<_>>(),
            "from_layout": frames.layout_error.map(|e| serde_json::json!({
                "rotation_error": e,
            })),
            "muscle": muscle.as_ref().map(|m| serde_json::json!({
                "loss": m.loss,
                "residual_norm": {"median": median(&m.residual_norm), "max": max(&m.residual_norm)},
                "activations_out_of_bounds": m.out_of_bounds,
            })),
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&report).unwrap_or_default()
        );
    } else {
        print_table(
            &args.file.display().to_string(),
            model,
            frames.contacts,
            &s,
            frames.layout_error.is_some() || body.warning.is_none(),
        );
        if let Some(e) = frames.layout_error {
            let forces = if frames.contact_force.is_empty() {
                "The file has no `contact_force`: L_euler above includes the ground's forces."
            } else {
                "Its contact forces act at the joint centres, with the couple on each foot that \
                 best explains the motion (loss::layout)."
            };
            println!(
                "note: the file holds the per-joint layout only; its coordinates were fitted from the \
                 joint rotations (largest rotation error left {e:.2e} rad), the root's translation \
                 rates from differences of its centre. {forces}"
            );
        }
        if let Some(m) = &muscle {
            print_muscle(m);
        }
    }
    Ok(())
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s.get(s.len() / 2).copied().unwrap_or(0.0)
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

/// `known_body`: the model is the file's own (its identity said so) or the file is a layout,
/// so a large residual is not blamed on the model.
fn print_table(file: &str, model: &Model, contacts: usize, s: &ResidualSummary, known_body: bool) {
    let worst = (0..s.frames)
        .max_by(|&a, &b| s.frame_relative[a].total_cmp(&s.frame_relative[b]))
        .unwrap_or(0);
    println!(
        "{file}: {} frames, model \"{}\", {contacts} contact points",
        s.frames, model.name
    );
    println!("L_euler = Σ_t |r_t|² = {:.4e}", s.loss);
    println!(
        "|r_t| / |tau_ID,t|: median {:.3e}, max {:.3e} (frame {worst})",
        median(&s.frame_relative),
        max(&s.frame_relative)
    );
    if max(&s.frame_relative) > 1e-3 && !known_body {
        println!(
            "note: a large residual in a file that does not say which model it belongs to \
             usually means the tensors belong to another model (a clip scaled to its bone \
             lengths: pass --model <clip>.osim, which augment --opensim-files writes)"
        );
    }
    let names = model.q_names();
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.sort_by(|&a, &b| s.coordinate_rms[b].total_cmp(&s.coordinate_rms[a]));
    println!("largest residuals (N·m or N):");
    println!("  {:<24} {:>12} {:>12}", "coordinate", "rms", "max");
    for &j in order.iter().take(5) {
        println!(
            "  {:<24} {:>12.4e} {:>12.4e}",
            names[j], s.coordinate_rms[j], s.coordinate_max[j]
        );
    }
}

fn print_muscle(m: &MuscleSummary) {
    println!(
        "L_muscle = Σ_t |q̈ − M⁻¹ R F_max a|² (+ bound penalty) = {:.4e}; |q̈ − M⁻¹ R F_max a| per frame: median {:.3e}, max {:.3e}; activations outside [0, 1]: {}",
        m.loss,
        median(&m.residual_norm),
        max(&m.residual_norm),
        m.out_of_bounds
    );
}

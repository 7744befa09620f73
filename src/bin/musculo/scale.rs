//! `musculo scale --setup Scale.xml`: OpenSim's Scale tool (generic model and marker set,
//! measured and manual scale factors, mass scaling, marker placement on a static trial).
//! `musculo scale --from-clip FILE -o scaled.osim`: a model (the default one unless
//! `--model`) scaled to a joint-centre clip's bone lengths, its convention markers placed.

use musculo::io::output::{OutputSet, name_in_folder};
use musculo::io::scale_setup::ScaleSetup;
use musculo::solve::scale::tool::{self, OutputKind, ToolOptions};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// OpenSim ScaleTool setup file (.xml, OpenSim 3 or 4). Its file names are relative to
    /// its folder.
    #[arg(
        long,
        required_unless_present = "from_clip",
        conflicts_with = "from_clip"
    )]
    setup: Option<PathBuf>,
    /// Instead of a setup: scale the model (default: the built-in full-body model) to this
    /// clip's bone lengths (HumanML3D, KIT-ML, BVH: median over frames, as `ik --scale auto`)
    /// and write it to -o.
    #[arg(long, value_name = "FILE")]
    from_clip: Option<PathBuf>,
    /// With --from-clip: the input format (default: from the file).
    #[arg(long, value_parser = musculo::motion::Format::parse)]
    format: Option<musculo::motion::Format>,
    /// With --from-clip: the skeleton map, built-in name or JSON file (default: the format's).
    #[arg(long)]
    map: Option<String>,
    /// With --from-clip: length unit of BVH and KIT files (m, cm, mm, in, or metres per unit).
    #[arg(long)]
    length_unit: Option<String>,
    /// Generic model to scale, instead of the setup's GenericModelMaker model_file.
    #[arg(long)]
    model: Option<PathBuf>,
    /// The final model (after marker placement, or after scaling when placement does not
    /// run) is written here instead of to the setup's output_model_file; a path ending in `/`
    /// is a folder. Every output is written together (all or none) and none may be an input.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write every output the setup names into this folder under its file name, instead of
    /// relative to the setup's folder.
    #[arg(long)]
    output_dir: Option<PathBuf>,
    /// Run GenericModelMaker and ModelScaler only (no marker placement).
    #[arg(long)]
    skip_placement: bool,
    #[command(flatten)]
    strict: crate::warnings::Strict,
}

/// The files a Scale run reads, which its outputs may not overwrite.
fn scale_inputs(setup_path: &Path, setup: &ScaleSetup, generic: &Path) -> Vec<PathBuf> {
    let mut inputs = vec![setup_path.to_path_buf(), generic.to_path_buf()];
    if let Some(g) = &setup.generic_model_maker {
        inputs.extend(g.marker_set_file.clone());
    }
    if let Some(m) = &setup.model_scaler {
        inputs.extend(m.marker_file.clone());
    }
    if let Some(p) = &setup.marker_placer {
        inputs.extend(p.marker_file.clone());
        inputs.extend(p.coordinate_file.clone());
    }
    inputs
}

fn kind_name(kind: OutputKind) -> &'static str {
    match kind {
        OutputKind::ScaledModel => "scaled model",
        OutputKind::ScaleSet => "scale factors",
        OutputKind::PlacedModel => "model with placed markers",
        OutputKind::MarkerSet => "marker set",
        OutputKind::StaticPose => "static pose",
    }
}

/// `--from-clip`: the model scaled to a clip, written to -o.
fn run_from_clip(args: &Args, clip_path: &Path) -> Result<(), musculo::Error> {
    use musculo::motion::{self, Format, LengthUnit, ReadOptions};
    let invalid = |argument: &'static str, message: String| musculo::Error::InvalidArgument {
        argument,
        message,
    };
    let output = args.output.clone().ok_or_else(|| {
        invalid(
            "--output",
            "--from-clip writes the scaled model to -o FILE".into(),
        )
    })?;
    let length_unit = match args.length_unit.as_deref() {
        Some(u) => Some(LengthUnit::parse(u).ok_or_else(|| {
            invalid(
                "--length-unit",
                format!("`{u}`: use m, cm, mm, in or a number of metres per unit from 1e-6 to 1e3"),
            )
        })?),
        None => None,
    };
    let format = match args.format {
        Some(f) => f,
        None => Format::detect(clip_path)?,
    };
    let (clip, read_warnings) =
        motion::read_with_warnings(clip_path, Some(format), &ReadOptions { length_unit })?;
    crate::warnings::print(&read_warnings);
    let map = crate::tool::skeleton_map(args.map.as_deref(), format)?.ok_or_else(|| {
        invalid(
            "--map",
            "markers have no bone lengths to scale by: give a skeleton map, or scale with \
             --setup"
                .into(),
        )
    })?;
    let (xml, source) = crate::tool::model_text(args.model.as_deref())?;
    let model = args.strict.load_str(&xml, &source)?;
    let scaling =
        musculo::solve::scale_from_clip::scale_to_clip(&xml, &source, &model, &map, &clip)?;
    let output = name_in_folder(&output, &format!("{}.osim", crate::tool::stem(clip_path)));
    let model_input: Vec<&Path> = args.model.iter().map(PathBuf::as_path).collect();
    let inputs = [&[clip_path][..], &model_input].concat();
    crate::tool::write_output(&output, scaling.xml()?.as_bytes(), &inputs)?;
    for (segment, factor) in &scaling.factors {
        println!("{segment:<18} ×{factor:.4}");
    }
    for (marker, before, after) in &scaling.placed {
        println!(
            "marker {marker:<16} placed {:.1} mm from its scaled location",
            1e3 * (after - before).norm()
        );
    }
    eprintln!(
        "wrote {} ({} scaled to {}, {:.1} kg)",
        output.display(),
        source,
        clip_path.display(),
        scaling.model.total_mass()
    );
    Ok(())
}

pub fn run(args: &Args) -> Result<(), musculo::Error> {
    if let Some(clip) = &args.from_clip {
        return run_from_clip(args, clip);
    }
    let setup_path = args
        .setup
        .as_ref()
        .ok_or_else(|| musculo::Error::InvalidArgument {
            argument: "--setup",
            message: "give a Scale setup file or --from-clip".into(),
        })?;
    let setup = ScaleSetup::read(setup_path)?;
    let options = ToolOptions {
        model_file: args.model.clone(),
        skip_placement: args.skip_placement,
        load: args.strict.load_options(),
    };
    let result = tool::run(&setup, &options)?;
    crate::warnings::print_model(&result.generic);
    crate::warnings::print(&result.warnings);
    println!(
        "{}: generic model {} ({:.3} kg)",
        if result.name.is_empty() {
            "scale"
        } else {
            &result.name
        },
        result.generic_file.display(),
        result.generic.total_mass()
    );
    for m in &result.measurements {
        println!("measurement {:<12} factor {:.6}", m.name, m.factor);
        for p in &m.pairs {
            println!(
                "    {} – {}: model {:.2} mm, experimental {:.2} mm ({} of {} frames)",
                p.markers[0],
                p.markers[1],
                1e3 * p.model,
                1e3 * p.experimental,
                p.frames_used,
                p.frames_in_window
            );
        }
    }
    if let Some(set) = &result.scale_set {
        println!(
            "{:<16} {:>9} {:>9} {:>9} {:>10} {:>10}",
            "body", "x", "y", "z", "mass (kg)", "scaled"
        );
        for s in &set.scales {
            let before = result
                .generic
                .body_index(&s.body)
                .map(|b| result.generic.bodies[b].mass);
            let after = (result.scaled.model.body_index(&s.body))
                .map(|b| result.scaled.model.bodies[b].mass);
            println!(
                "{:<16} {:>9.6} {:>9.6} {:>9.6} {:>10.4} {:>10.4}",
                s.body,
                s.factors.x,
                s.factors.y,
                s.factors.z,
                before.unwrap_or(f64::NAN),
                after.unwrap_or(f64::NAN)
            );
        }
        println!(
            "total mass {:.4} kg → {:.4} kg",
            result.generic.total_mass(),
            result.scaled.total_mass
        );
    }
    if let Some(p) = &result.placement {
        let (worst, _) = (p.marker_errors.iter())
            .filter(|e| e.1.is_finite())
            .fold(("", 0.0), |a, e| if e.1 > a.1 { (&e.0, e.1) } else { a });
        let max_move = p.moved.iter().map(|m| m.1).fold(0.0, f64::max);
        println!(
            "marker placement at t = {} s: IK marker error RMS {:.2} mm, max {:.2} mm ({worst}); \
             {} markers moved (at most {:.2} mm){}",
            p.time,
            1e3 * p.rmse,
            1e3 * p.max_error,
            p.moved.len(),
            1e3 * max_move,
            if p.removed.is_empty() {
                String::new()
            } else {
                format!(", {} removed (not in the trial)", p.removed.len())
            }
        );
        if !p.starts.is_empty() {
            println!(
                "static pose from {} starts: {}",
                p.starts.len(),
                musculo::solve::ik::describe_starts(&p.starts)
            );
        }
    }
    let final_kind = if result.placement.is_some() {
        OutputKind::PlacedModel
    } else {
        OutputKind::ScaledModel
    };
    let final_name = (result.outputs.iter())
        .find(|o| o.kind == final_kind)
        .and_then(|o| o.path.file_name())
        .map_or_else(
            || {
                format!(
                    "{}.osim",
                    if setup.name.is_empty() {
                        "scaled"
                    } else {
                        &setup.name
                    }
                )
            },
            |n| n.to_string_lossy().into_owned(),
        );
    let final_output = args.output.as_ref().map(|o| name_in_folder(o, &final_name));
    let inputs = scale_inputs(setup_path, &setup, &result.generic_file);
    let mut outputs = OutputSet::new(inputs.iter().map(PathBuf::as_path));
    let mut kinds = Vec::new();
    for out in &result.outputs {
        let path = match (&final_output, &args.output_dir) {
            (Some(o), _) if out.kind == final_kind => o.clone(),
            (_, Some(dir)) => dir.join(out.path.file_name().unwrap_or(out.path.as_os_str())),
            _ => out.path.clone(),
        };
        outputs.add(&path, out.text.as_bytes())?;
        kinds.push(out.kind);
    }
    if let Some(o) = final_output
        .as_ref()
        .filter(|_| !kinds.contains(&final_kind))
    {
        outputs.add(o, result.final_model().0.as_bytes())?;
        kinds.push(final_kind);
    }
    // Every file is written before any gets its name: all of them or none.
    let written = crate::tool::commit(outputs)?;
    for (path, kind) in written.iter().zip(kinds) {
        println!("wrote {} ({})", path.display(), kind_name(kind));
    }
    if result.outputs.is_empty() && args.output.is_none() {
        eprintln!("note: the setup names no output file and no -o was given: nothing written");
    }
    Ok(())
}

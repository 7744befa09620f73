//! Checks of the muscles: parameters against physiological ranges, paths over a grid of the
//! range of motion, the moment-arm signs of agonists, and maximum isometric joint moments.

use super::tables::{AgonistRow, MomentRow, ParsedTables, sides};
use super::{Check, CheckOptions, Family, Status, SubjectKind, glob_match};
use crate::dynamics::{Data, forward_kinematics};
use crate::model::{Coordinate, CoordinateRole, Model, MotionType};
use crate::muscle::hill::{HillMuscle, MuscleKind};
use crate::muscle::path::{PathData, PathSet, compute_paths};
use crate::random::SplitMix64;
use nalgebra::DMatrix;

/// Lengths and moment arms of every muscle path while one independent coordinate sweeps a
/// grid of its range, the others at their default values.
struct Sweep {
    /// Grid values of the coordinate.
    q: Vec<f64>,
    /// [point * m + muscle]: ℓ (m).
    length: Vec<f64>,
    /// [point * m + muscle]: r = −∂ℓ/∂q about the swept coordinate.
    arm: Vec<f64>,
}

/// What the check families read: the muscles' names and force models, their lengths and
/// moment arms at the default pose, and the sweeps of the coordinates they cross.
struct Swept<'a> {
    /// The path names, in path order (m of them).
    names: Vec<&'a str>,
    /// The force model of each path (None when its class or parameters are not modelled).
    forces: Vec<Option<&'a HillMuscle>>,
    /// n × m moment arms at the default pose.
    default_arms: DMatrix<f64>,
    /// Lengths at the default pose (m).
    default_length: Vec<f64>,
    /// Per independent coordinate: the sweep over its model range (within the options'
    /// limits) when some muscle crosses it.
    sweeps: Vec<Option<Sweep>>,
    /// Per independent coordinate: the sweep over its physiological range of motion.
    rom_sweeps: Vec<Option<Sweep>>,
}

pub(super) fn all(
    model: &Model,
    options: &CheckOptions,
    tables: &ParsedTables,
    out: &mut Vec<Check>,
    progress: &mut dyn FnMut(usize, usize),
) {
    let hill = parameters(model, tables, out);
    let set = match PathSet::muscles(model) {
        Ok(s) => s,
        Err(e) => {
            out.push(model_check(
                Family::Paths,
                "muscle paths build",
                model,
                false,
                e.to_string(),
            ));
            return;
        }
    };
    if set.is_empty() {
        return;
    }
    let forces: Vec<Option<&HillMuscle>> = set
        .paths
        .iter()
        .map(|p| hill.iter().find(|(f, _)| *f == p.force).map(|(_, h)| h))
        .collect();
    let names: Vec<&str> = set.paths.iter().map(|p| p.name.as_str()).collect();

    let mut data = Data::new(model);
    let mut paths = PathData::new(model, &set);
    let q0 = model.default_q();
    // The default pose: which coordinates any muscle crosses, and each arm there.
    if let Err(e) = forward_kinematics(model, &mut data, &q0)
        .and_then(|_| compute_paths(model, &data, &set, &mut paths))
    {
        out.push(model_check(
            Family::Paths,
            "paths at the default pose",
            model,
            false,
            e.to_string(),
        ));
        return;
    }
    let default_arms = paths.moment_arms.clone();
    let default_length = paths.length.clone();
    let mut ctx = SweepContext {
        model,
        set: &set,
        data: &mut data,
        paths: &mut paths,
        q0: &q0,
    };
    let (sweeps, rom_sweeps) = sweep_crossed(&mut ctx, tables, options, &default_arms, progress);
    let swept = Swept {
        names,
        forces,
        default_arms,
        default_length,
        sweeps,
        rom_sweeps,
    };
    path_checks(model, options, &swept, out);
    if options.random_lines > 0 {
        line_continuity(&mut ctx, tables, options, &swept, out);
    }
    moment_arm_bounds(&mut ctx, tables, options, &swept, out);
    agonist_signs(model, tables, options, &swept, &q0, out);
    max_isometric_moments(model, tables, &swept, out);
}

/// The independent coordinate `j`.
fn coordinate(model: &Model, j: usize) -> &Coordinate {
    &model.coordinates[model.reduction.independent[j]]
}

/// Which coordinates some muscle crosses (a moment arm at the default pose), and the grids
/// over their model range (paths) and their physiological range of motion (signs, moments);
/// `progress(j + 1, n)` after each coordinate.
fn sweep_crossed(
    ctx: &mut SweepContext,
    tables: &ParsedTables,
    options: &CheckOptions,
    default_arms: &DMatrix<f64>,
    progress: &mut dyn FnMut(usize, usize),
) -> (Vec<Option<Sweep>>, Vec<Option<Sweep>>) {
    let model = ctx.model;
    let (n, m) = (model.nq(), ctx.set.len());
    let mut sweeps: Vec<Option<Sweep>> = Vec::with_capacity(n);
    let mut rom_sweeps: Vec<Option<Sweep>> = Vec::with_capacity(n);
    for j in 0..n {
        let crossed = (0..m).any(|k| default_arms[(j, k)].abs() > 1e-12);
        let c = coordinate(model, j);
        let limit = match c.motion_type {
            MotionType::Translational => options.max_translation,
            _ => options.max_rotation,
        };
        let (lo, hi) = (c.range[0].max(-limit), c.range[1].min(limit));
        if !crossed || !(lo < hi) {
            sweeps.push(None);
            rom_sweeps.push(None);
        } else {
            sweeps.push(Some(ctx.sweep(j, lo, hi, options)));
            let [rlo, rhi] = tables.range_of_motion(&c.name, [lo, hi]);
            rom_sweeps.push((rlo < hi && rlo <= rhi).then(|| ctx.sweep(j, rlo, rhi, options)));
        }
        progress(j + 1, n);
    }
    (sweeps, rom_sweeps)
}

/// One muscle's path over the sweeps: its shortest length and where, whether any length or
/// arm is not finite, its largest arm change between neighbouring grid points of a
/// rotational coordinate, and the coordinates it crosses.
struct PathExtremes<'a> {
    min_length: f64,
    where_min: String,
    nonfinite: bool,
    /// (|Δr|, coordinate, q before, q after)
    jump: Option<(f64, usize, f64, f64)>,
    crossed: Vec<&'a str>,
}

/// Muscle `k`'s [`PathExtremes`] over the default pose and the sweeps.
fn path_extremes<'a>(model: &'a Model, swept: &Swept, k: usize) -> PathExtremes<'a> {
    let m = swept.names.len();
    let mut e = PathExtremes {
        min_length: swept.default_length[k],
        where_min: "the default pose".to_string(),
        nonfinite: !swept.default_length[k].is_finite(),
        jump: None,
        crossed: Vec::new(),
    };
    for (j, s) in swept.sweeps.iter().enumerate() {
        let Some(s) = s else { continue };
        if !(0..s.q.len()).any(|i| s.arm[i * m + k].abs() > 1e-12 || !s.arm[i * m + k].is_finite())
        {
            continue;
        }
        let qname = coordinate(model, j).name.as_str();
        e.crossed.push(qname);
        for i in 0..s.q.len() {
            let (l, r) = (s.length[i * m + k], s.arm[i * m + k]);
            if !l.is_finite() || !r.is_finite() {
                e.nonfinite = true;
            } else if l < e.min_length {
                e.min_length = l;
                e.where_min = format!("{} = {:.4}", qname, s.q[i]);
            }
        }
        if coordinate(model, j).motion_type != MotionType::Translational {
            for i in 1..s.q.len() {
                let d = (s.arm[i * m + k] - s.arm[(i - 1) * m + k]).abs();
                if d.is_finite() && e.jump.is_none_or(|(b, ..)| d > b) {
                    e.jump = Some((d, j, s.q[i - 1], s.q[i]));
                }
            }
        }
    }
    e
}

/// Paths: finite positive lengths; finite, continuous moment arms (two checks per muscle).
fn path_checks(model: &Model, options: &CheckOptions, swept: &Swept, out: &mut Vec<Check>) {
    for (k, name) in swept.names.iter().enumerate() {
        let e = path_extremes(model, swept, k);
        out.push(Check {
            family: Family::Paths,
            name: "length finite > 0".into(),
            subject_kind: SubjectKind::Muscle,
            subject: (*name).into(),
            status: if !e.nonfinite && e.min_length > 0.0 {
                Status::Pass
            } else {
                Status::Fail
            },
            value: Some(e.min_length),
            unit: "m",
            limit: "> 0, finite".into(),
            message: if e.nonfinite {
                "non-finite length or moment arm on the grid".into()
            } else {
                format!("shortest at {}", e.where_min)
            },
        });
        out.push(match e.jump {
            None => Check {
                family: Family::Paths,
                name: "moment-arm continuity".into(),
                subject_kind: SubjectKind::Muscle,
                subject: (*name).into(),
                status: Status::Skip,
                value: None,
                unit: "m",
                limit: format!("≤ {} between grid points", options.max_moment_arm_jump),
                message: "crosses no rotational coordinate".into(),
            },
            Some((d, j, a, b)) => Check {
                family: Family::Paths,
                name: "moment-arm continuity".into(),
                subject_kind: SubjectKind::Muscle,
                subject: (*name).into(),
                status: if d <= options.max_moment_arm_jump {
                    Status::Pass
                } else {
                    Status::Fail
                },
                value: Some(d),
                unit: "m",
                limit: format!("≤ {} between grid points", options.max_moment_arm_jump),
                message: format!(
                    "largest change about {} between {:.1}° and {:.1}° (crosses {})",
                    coordinate(model, j).name,
                    a.to_degrees(),
                    b.to_degrees(),
                    e.crossed.join(", ")
                ),
            },
        });
    }
}

/// Agonist signs: per row of `agonist_signs.csv`, per side when it has `{side}`, every
/// muscle its patterns match against the sign of its direction.
fn agonist_signs(
    model: &Model,
    tables: &ParsedTables,
    options: &CheckOptions,
    swept: &Swept,
    q0: &[f64],
    out: &mut Vec<Check>,
) {
    for row in &tables.agonists {
        // `{side}` in the muscles or the coordinate (ercspn_{side} → lumbar_extension).
        let has_side =
            row.coordinate.contains("{side}") || row.muscles.iter().any(|p| p.contains("{side}"));
        let expansions: Vec<(String, Option<&str>)> = if has_side {
            ["r", "l"]
                .into_iter()
                .map(|s| (row.coordinate.replace("{side}", s), Some(s)))
                .collect()
        } else {
            vec![(row.coordinate.clone(), None)]
        };
        // A pattern without `{side}` beside one with it is checked once per coordinate.
        let mut seen: Vec<(usize, usize)> = Vec::new();
        for (coordinate, side) in expansions {
            let Some(ci) = model.coordinate_index(&coordinate) else {
                continue;
            };
            let patterns: Vec<String> = row
                .muscles
                .iter()
                .map(|p| match side {
                    Some(s) => p.replace("{side}", s),
                    None => p.clone(),
                })
                .collect();
            let coord = &model.coordinates[ci];
            let Some(sign) = tables.direction_sign(&row.coordinate, &row.direction, coord.range)
            else {
                continue;
            };
            let matched = (0..swept.names.len())
                .filter(|&k| patterns.iter().any(|p| glob_match(p, swept.names[k])));
            for k in matched {
                if seen.contains(&(ci, k)) {
                    continue;
                }
                seen.push((ci, k));
                let agonist = Agonist {
                    row,
                    coordinate: &coordinate,
                    role: coord.role,
                    sign,
                    muscle: k,
                };
                out.push(agonist_sign_check(&agonist, options, swept, q0));
            }
        }
    }
}

/// One muscle of an agonist row, about one coordinate (its side's, when the row has sides).
struct Agonist<'a> {
    row: &'a AgonistRow,
    coordinate: &'a str,
    role: CoordinateRole,
    /// +1 when the direction is the coordinate's positive one, else −1.
    sign: f64,
    muscle: usize,
}

/// The agonist's moment arm has the direction's sign wherever it exceeds the threshold, at
/// the default pose and over the coordinate's physiological-range sweep, and exceeds it
/// somewhere.
fn agonist_sign_check(a: &Agonist, options: &CheckOptions, swept: &Swept, q0: &[f64]) -> Check {
    let (k, sign, coordinate) = (a.muscle, a.sign, a.coordinate);
    let m = swept.names.len();
    let name = format!("{} about {coordinate}", a.row.direction);
    let limit = format!(
        "{} wherever |r| > {} m",
        if sign > 0.0 { "r > 0" } else { "r < 0" },
        options.sign_threshold
    );
    let CoordinateRole::Independent(j) = a.role else {
        return Check {
            family: Family::AgonistSigns,
            name,
            subject_kind: SubjectKind::Muscle,
            subject: swept.names[k].into(),
            status: Status::Skip,
            value: None,
            unit: "m",
            limit,
            message: format!("{coordinate} is locked or dependent"),
        };
    };
    let r0 = swept.default_arms[(j, k)];
    let mut values = vec![(q0[j], r0)];
    if let Some(s) = &swept.rom_sweeps[j] {
        values.extend((0..s.q.len()).map(|i| (s.q[i], s.arm[i * m + k])));
    }
    let t = options.sign_threshold;
    let wrong: Vec<f64> = values
        .iter()
        .filter(|(_, r)| !(sign * r >= -t))
        .map(|(q, _)| *q)
        .collect();
    let right = values.iter().filter(|(_, r)| sign * r > t).count();
    let status = if wrong.is_empty() && right > 0 {
        Status::Pass
    } else {
        Status::Fail
    };
    let message = if !wrong.is_empty() {
        format!(
            "wrong sign at {} of {} poses ({} = {} deg)",
            wrong.len(),
            values.len(),
            coordinate,
            wrong
                .iter()
                .map(|q| format!("{:.0}", q.to_degrees()))
                .collect::<Vec<_>>()
                .join(", ")
        )
    } else if right == 0 {
        "moment arm below the threshold everywhere: does not act".into()
    } else {
        format!("right sign at {right} of {} poses", values.len())
    };
    Check {
        family: Family::AgonistSigns,
        name,
        subject_kind: SubjectKind::Muscle,
        subject: swept.names[k].into(),
        status,
        value: Some(r0),
        unit: "m",
        limit,
        message,
    }
}

/// Maximum isometric moments per coordinate direction of `max_isometric_moments.csv` (each
/// side of a `{side}` row), over the coordinate's physiological-range sweep.
fn max_isometric_moments(
    model: &Model,
    tables: &ParsedTables,
    swept: &Swept,
    out: &mut Vec<Check>,
) {
    for row in &tables.moments {
        for (coordinate, _) in sides(&row.coordinate) {
            let Some(ci) = model.coordinate_index(&coordinate) else {
                continue;
            };
            let coord = &model.coordinates[ci];
            let Some(sign) = tables.direction_sign(&row.coordinate, &row.direction, coord.range)
            else {
                continue;
            };
            out.push(max_isometric_moment_check(
                row,
                &coordinate,
                coord.role,
                sign,
                swept,
            ));
        }
    }
}

/// The largest moment the muscles acting in the direction (`sign`) of `coordinate` (of
/// `role`) produce at full activation over its sweep, against the row's range.
fn max_isometric_moment_check(
    row: &MomentRow,
    coordinate: &str,
    role: CoordinateRole,
    sign: f64,
    swept: &Swept,
) -> Check {
    let subject = format!("{coordinate} {}", row.direction);
    let limit = format!("[{}, {}]", row.min_nm, row.max_nm);
    let skip = |message: String| Check {
        family: Family::MaxIsometricMoments,
        name: "max isometric moment".into(),
        subject_kind: SubjectKind::Direction,
        subject: subject.clone(),
        status: Status::Skip,
        value: None,
        unit: "N m",
        limit: limit.clone(),
        message,
    };
    let CoordinateRole::Independent(j) = role else {
        return skip(format!("{coordinate} is locked or dependent"));
    };
    let Some(s) = &swept.rom_sweeps[j] else {
        return skip("no muscle crosses the coordinate".into());
    };
    let (best, unmodelled) = strongest_pose(s, sign, swept);
    if best.0 == 0.0 {
        return skip(format!(
            "no muscle acts in {} about {coordinate}",
            row.direction
        ));
    }
    let mut message = format!(
        "at {coordinate} = {:.0}°, {} muscles",
        best.1.to_degrees(),
        best.2
    );
    if !unmodelled.is_empty() {
        message += &format!("; without force model: {}", unmodelled.join(", "));
    }
    Check {
        family: Family::MaxIsometricMoments,
        name: "max isometric moment".into(),
        subject_kind: SubjectKind::Direction,
        subject,
        status: if (row.min_nm..=row.max_nm).contains(&best.0) {
            Status::Pass
        } else {
            Status::Fail
        },
        value: Some(best.0),
        unit: "N m",
        limit,
        message,
    }
}

/// Over the sweep `s`: the largest Σ_k sign r_k F_k of the muscles with sign r_k > 0 and a
/// finite positive isometric force F_k, as (moment, q, muscles counted); and the muscles
/// with sign r > 0 at the first grid point that have no force model.
fn strongest_pose<'a>(
    s: &Sweep,
    sign: f64,
    swept: &Swept<'a>,
) -> ((f64, f64, usize), Vec<&'a str>) {
    let m = swept.names.len();
    let mut best = (0.0, f64::NAN, 0usize);
    let mut unmodelled = Vec::new();
    for i in 0..s.q.len() {
        let mut total = 0.0;
        let mut count = 0;
        for k in 0..m {
            let r = s.arm[i * m + k];
            if !(sign * r > 0.0) {
                continue;
            }
            let Some(h) = swept.forces[k] else {
                if i == 0 {
                    unmodelled.push(swept.names[k]);
                }
                continue;
            };
            let f = h.isometric_force(s.length[i * m + k]);
            if f.is_finite() && f > 0.0 {
                total += sign * r * f;
                count += 1;
            }
        }
        if total > best.0 {
            best = (total, s.q[i], count);
        }
    }
    (best, unmodelled)
}

/// |r| of every muscle about every rotational coordinate it crosses against the bound of
/// `moment_arm_bounds.csv`: at the default pose, over each coordinate's physiological-range
/// sweep, and at `options.random_poses` random poses with every rotational coordinate drawn
/// uniformly from its physiological range at once. One check per muscle: the pose and
/// coordinate of its largest |r| / bound.
fn moment_arm_bounds(
    ctx: &mut SweepContext,
    tables: &ParsedTables,
    options: &CheckOptions,
    swept: &Swept,
    out: &mut Vec<Check>,
) {
    let model = ctx.model;
    let mut bounds = ArmBounds::new(model, tables, &swept.names);
    bounds.over_sweeps(model, swept);
    if options.random_poses > 0 {
        out.push(bounds.over_random_poses(ctx, tables, options, &swept.default_arms));
    }
    bounds.checks(model, &swept.names, out);
}

/// The physiological box of every crossed rotational coordinate (its model range within
/// `max_rotation`, narrowed to `range_of_motion.csv`); None for the rest, held at default.
fn physiological_box(
    model: &Model,
    tables: &ParsedTables,
    options: &CheckOptions,
    default_arms: &DMatrix<f64>,
) -> Vec<Option<[f64; 2]>> {
    let m = default_arms.ncols();
    (0..model.nq())
        .map(|j| {
            let c = coordinate(model, j);
            let crossed = (0..m).any(|k| default_arms[(j, k)].abs() > 1e-12);
            if !rotational(model, j) || !crossed {
                return None;
            }
            let lim = options.max_rotation;
            let (lo, hi) = (c.range[0].max(-lim), c.range[1].min(lim));
            let [rlo, rhi] = tables.range_of_motion(&c.name, [lo, hi]);
            (rlo <= rhi).then_some([rlo, rhi])
        })
        .collect()
}

/// The largest length change of one muscle between neighbouring poses of the random lines:
/// (|Δℓ|, line, step, the pose after the step, the change its moment arms predict).
type LineJump = (f64, usize, usize, Vec<f64>, f64);

/// Length continuity along `options.random_lines` seeded straight lines through the
/// physiological box ([`physiological_box`]): each line joins two uniform poses a, b of the
/// box and visits q_i = a + (i/s)(b − a), i = 0…s, s = ⌈‖b − a‖₂ / max_line_step⌉ (the
/// Euclidean norm over the box's coordinates), so that neighbouring poses are at most
/// `max_line_step` apart in configuration space. A muscle
/// passes when |ℓ(q_i) − ℓ(q_{i−1})| ≤ `max_line_length_jump` at every step of every line
/// (a non-finite length is an infinite jump). One check per muscle crossing a coordinate of
/// the box (its largest change, the pose after it, and the change its moment arms at the two
/// poses predict, Δℓ ≈ −Σ_j ½(r_j(q_{i−1}) + r_j(q_i))(q_i − q_{i−1})_j, which tells a steep
/// smooth path from a jump), and one that every pose could be computed.
fn line_continuity(
    ctx: &mut SweepContext,
    tables: &ParsedTables,
    options: &CheckOptions,
    swept: &Swept,
    out: &mut Vec<Check>,
) {
    let model = ctx.model;
    let (n, m) = (model.nq(), swept.names.len());
    let boxes = physiological_box(model, tables, options, &swept.default_arms);
    let free: Vec<usize> = (0..n).filter(|&j| boxes[j].is_some()).collect();
    let crosses = |k: usize, j: usize| swept.default_arms[(j, k)].abs() > 1e-12;
    let mut rng = SplitMix64(options.random_line_seed);
    let mut worst: Vec<Option<LineJump>> = vec![None; m];
    let (mut failures, mut failed) = (0usize, None::<(usize, String)>);
    let (mut q, mut a, mut b) = (ctx.q0.to_vec(), ctx.q0.to_vec(), ctx.q0.to_vec());
    for line in 0..options.random_lines {
        for &j in &free {
            let [lo, hi] = boxes[j].unwrap_or([ctx.q0[j]; 2]);
            a[j] = rng.uniform(lo, hi);
            b[j] = rng.uniform(lo, hi);
        }
        let span = free
            .iter()
            .map(|&j| (b[j] - a[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        let steps = ((span / options.max_line_step).ceil() as usize).max(1);
        // the lengths and moment arms at the line's previous pose (none after a pose that
        // failed)
        let mut previous: Option<(Vec<f64>, DMatrix<f64>)> = None;
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            for &j in &free {
                q[j] = a[j] + t * (b[j] - a[j]);
            }
            if let Err(e) = forward_kinematics(model, ctx.data, &q)
                .and_then(|_| compute_paths(model, ctx.data, ctx.set, ctx.paths))
            {
                failed.get_or_insert((line, e.to_string()));
                failures += 1;
                previous = None;
                continue;
            }
            let (length, arms) = (&ctx.paths.length, &ctx.paths.moment_arms);
            if let Some((prev, prev_arms)) = &previous {
                for k in 0..m {
                    let d = (length[k] - prev[k]).abs();
                    let d = if d.is_finite() { d } else { f64::INFINITY };
                    if worst[k].as_ref().is_none_or(|w| d > w.0) {
                        let dq =
                            (b[0..n].iter().zip(&a[0..n])).map(|(bj, aj)| (bj - aj) / steps as f64);
                        let predicted: f64 = dq
                            .enumerate()
                            .map(|(j, dqj)| -0.5 * (prev_arms[(j, k)] + arms[(j, k)]) * dqj)
                            .sum();
                        worst[k] = Some((d, line, i, q.clone(), predicted));
                    }
                }
            }
            match &mut previous {
                Some((prev, prev_arms)) => {
                    prev.copy_from_slice(length);
                    prev_arms.copy_from(arms);
                }
                None => previous = Some((length.clone(), arms.clone())),
            }
        }
    }
    let limit = format!(
        "≤ {} between poses ≤ {:.2}° apart",
        options.max_line_length_jump,
        options.max_line_step.to_degrees()
    );
    for (k, w) in worst.into_iter().enumerate() {
        if !free.iter().any(|&j| crosses(k, j)) {
            continue;
        }
        let Some((d, line, step, at, predicted)) = w else {
            continue;
        };
        let pose: Vec<String> = free
            .iter()
            .filter(|&&j| crosses(k, j))
            .map(|&j| format!("{} {:.1}°", coordinate(model, j).name, at[j].to_degrees()))
            .collect();
        out.push(Check {
            family: Family::Paths,
            name: "length continuity on random lines".into(),
            subject_kind: SubjectKind::Muscle,
            subject: swept.names[k].into(),
            status: if d <= options.max_line_length_jump {
                Status::Pass
            } else {
                Status::Fail
            },
            value: Some(d),
            unit: "m",
            limit: limit.clone(),
            message: format!(
                "largest change on line {line}, step {step}, arriving at ({}); its moment arms \
                 predict {:.2e} m",
                pose.join(", "),
                predicted.abs()
            ),
        });
    }
    let message = match &failed {
        None => format!("{} random lines", options.random_lines),
        Some((line, e)) => format!(
            "{failures} poses on {} random lines failed; first, on line {line}: {e}",
            options.random_lines
        ),
    };
    out.push(model_check(
        Family::Paths,
        "random lines computable",
        model,
        failures == 0,
        message,
    ));
}

fn rotational(model: &Model, j: usize) -> bool {
    coordinate(model, j).motion_type != MotionType::Translational
}

/// The bounds of `moment_arm_bounds.csv` on every muscle and rotational coordinate, and the
/// largest |r| / bound of each muscle over the poses considered so far.
struct ArmBounds {
    m: usize,
    /// bound[j * m + k]: the table's bound on muscle k about coordinate j.
    bound: Vec<Option<f64>>,
    /// worst[k]: (|r| / bound, |r|, coordinate, where in words)
    worst: Vec<Option<(f64, f64, usize, String)>>,
    /// crossed[k]: muscle k had a finite nonzero moment arm about a rotational coordinate.
    crossed: Vec<bool>,
}

impl ArmBounds {
    fn new(model: &Model, tables: &ParsedTables, names: &[&str]) -> ArmBounds {
        let (n, m) = (model.nq(), names.len());
        let bound: Vec<Option<f64>> = (0..n)
            .flat_map(|j| (0..m).map(move |k| (j, k)))
            .map(|(j, k)| {
                if !rotational(model, j) {
                    return None;
                }
                tables
                    .moment_arm_bound(names[k], &coordinate(model, j).name)
                    .map(|(b, _)| b)
            })
            .collect();
        ArmBounds {
            m,
            bound,
            worst: vec![None; m],
            crossed: vec![false; m],
        }
    }

    /// Muscle `k`'s arm `r` about coordinate `j` at the pose `at` describes.
    fn consider(&mut self, k: usize, j: usize, r: f64, at: &dyn Fn() -> String) {
        // Non-finite moment arms fail the paths family (sweeps) or the random-pose check.
        if !(r.abs() > 1e-12 && r.is_finite()) {
            return;
        }
        self.crossed[k] = true;
        let Some(b) = self.bound[j * self.m + k] else {
            return;
        };
        let ratio = r.abs() / b;
        if self.worst[k].as_ref().is_none_or(|w| ratio > w.0) {
            self.worst[k] = Some((ratio, r.abs(), j, at()));
        }
    }

    /// The arms at the default pose and over each rotational coordinate's
    /// physiological-range sweep.
    fn over_sweeps(&mut self, model: &Model, swept: &Swept) {
        let m = self.m;
        for j in (0..model.nq()).filter(|&j| rotational(model, j)) {
            for k in 0..m {
                self.consider(k, j, swept.default_arms[(j, k)], &|| {
                    "the default pose".into()
                });
            }
            if let Some(s) = &swept.rom_sweeps[j] {
                for i in 0..s.q.len() {
                    for k in 0..m {
                        let at = || {
                            format!(
                                "{} = {:.1}° (others at default)",
                                coordinate(model, j).name,
                                s.q[i].to_degrees()
                            )
                        };
                        self.consider(k, j, s.arm[i * m + k], &at);
                    }
                }
            }
        }
    }

    /// The arms at `options.random_poses` seeded random poses: every crossed rotational
    /// coordinate drawn uniformly from its physiological range, the rest at default. Returns
    /// the check that every pose could be computed.
    fn over_random_poses(
        &mut self,
        ctx: &mut SweepContext,
        tables: &ParsedTables,
        options: &CheckOptions,
        default_arms: &DMatrix<f64>,
    ) -> Check {
        let model = ctx.model;
        let (n, m) = (model.nq(), self.m);
        let boxes = physiological_box(model, tables, options, default_arms);
        let mut rng = SplitMix64(options.random_pose_seed);
        let (mut failures, mut failed) = (0usize, None::<(usize, String)>);
        let mut q = ctx.q0.to_vec();
        for pose in 0..options.random_poses {
            for j in 0..n {
                q[j] = match boxes[j] {
                    Some([lo, hi]) => rng.uniform(lo, hi),
                    None => ctx.q0[j],
                };
            }
            if let Err(e) = forward_kinematics(model, ctx.data, &q)
                .and_then(|_| compute_paths(model, ctx.data, ctx.set, ctx.paths))
            {
                failed.get_or_insert((pose, e.to_string()));
                failures += 1;
                continue;
            }
            for j in (0..n).filter(|&j| boxes[j].is_some()) {
                for k in 0..m {
                    let r = ctx.paths.moment_arms[(j, k)];
                    let at = || {
                        // the coordinates this muscle crosses
                        let pose_text: Vec<String> = (0..n)
                            .filter(|&i| boxes[i].is_some() && default_arms[(i, k)].abs() > 1e-12)
                            .map(|i| {
                                format!("{} {:.1}°", coordinate(model, i).name, q[i].to_degrees())
                            })
                            .collect();
                        format!("random pose {pose} ({})", pose_text.join(", "))
                    };
                    self.consider(k, j, r, &at);
                }
            }
        }
        let message = match &failed {
            None => format!("{} random poses", options.random_poses),
            Some((pose, e)) => format!(
                "{failures} of {} random poses failed; first, pose {pose}: {e}",
                options.random_poses
            ),
        };
        model_check(
            Family::MomentArmBounds,
            "random poses computable",
            model,
            failures == 0,
            message,
        )
    }

    /// One check per muscle: its largest |r| / bound, or a skip when nothing bounds it.
    fn checks(self, model: &Model, names: &[&str], out: &mut Vec<Check>) {
        let m = self.m;
        for (k, worst) in self.worst.iter().enumerate() {
            let subject = names[k].to_string();
            out.push(match worst {
                Some((ratio, r, j, at)) => {
                    let b = self.bound[j * m + k].unwrap_or(f64::NAN);
                    Check {
                        family: Family::MomentArmBounds,
                        name: "moment-arm magnitude".into(),
                        subject_kind: SubjectKind::Muscle,
                        subject,
                        status: if *ratio <= 1.0 {
                            Status::Pass
                        } else {
                            Status::Fail
                        },
                        value: Some(*r),
                        unit: "m",
                        limit: format!("≤ {b} about {}", coordinate(model, *j).name),
                        message: format!("largest |r| / bound at {at}"),
                    }
                }
                None => Check {
                    family: Family::MomentArmBounds,
                    name: "moment-arm magnitude".into(),
                    subject_kind: SubjectKind::Muscle,
                    subject,
                    status: Status::Skip,
                    value: None,
                    unit: "m",
                    limit: String::new(),
                    message: if self.crossed[k] {
                        "moment_arm_bounds.csv bounds none of the coordinates it crosses".into()
                    } else {
                        "crosses no rotational coordinate".into()
                    },
                },
            });
        }
    }
}

struct SweepContext<'a> {
    model: &'a Model,
    set: &'a PathSet,
    data: &'a mut Data,
    paths: &'a mut PathData,
    q0: &'a [f64],
}

impl SweepContext<'_> {
    /// Coordinate j over [lo, hi] (at least `grid_points`, at most `max_grid_step` apart),
    /// the others at their default values. A pose that cannot be computed gives NaN.
    fn sweep(&mut self, j: usize, lo: f64, hi: f64, options: &CheckOptions) -> Sweep {
        let m = self.set.len();
        let g = if hi > lo {
            options
                .grid_points
                .max(((hi - lo) / options.max_grid_step).ceil() as usize + 1)
        } else {
            1
        };
        let mut q = self.q0.to_vec();
        let mut s = Sweep {
            q: (0..g)
                .map(|i| lo + (hi - lo) * i as f64 / (g.max(2) - 1) as f64)
                .collect(),
            length: Vec::with_capacity(g * m),
            arm: Vec::with_capacity(g * m),
        };
        for i in 0..g {
            q[j] = s.q[i];
            match forward_kinematics(self.model, self.data, &q)
                .and_then(|_| compute_paths(self.model, self.data, self.set, self.paths))
            {
                Ok(()) => {
                    s.length.extend_from_slice(&self.paths.length);
                    s.arm.extend((0..m).map(|k| self.paths.moment_arms[(j, k)]));
                }
                Err(_) => {
                    s.length.extend(std::iter::repeat_n(f64::NAN, m));
                    s.arm.extend(std::iter::repeat_n(f64::NAN, m));
                }
            }
        }
        s
    }
}

fn model_check(family: Family, name: &str, model: &Model, pass: bool, message: String) -> Check {
    Check {
        family,
        name: name.into(),
        subject_kind: SubjectKind::Model,
        subject: model.name.clone(),
        status: if pass { Status::Pass } else { Status::Fail },
        value: None,
        unit: "",
        limit: String::new(),
        message,
    }
}

/// The five parameters of every muscle against the range table; returns the force models
/// that could be built (force index, model).
fn parameters(
    model: &Model,
    tables: &ParsedTables,
    out: &mut Vec<Check>,
) -> Vec<(usize, HillMuscle)> {
    let mut built = Vec::new();
    for (fi, f) in model
        .forces
        .iter()
        .enumerate()
        .filter(|(_, f)| f.is_muscle())
    {
        let hill = HillMuscle::from_force_element(f);
        let params = hill.as_ref().ok().map(|h| *h.params());
        for range in &tables.ranges {
            // The file's value; OpenSim's default when absent (from the force model).
            let value = f.raw.number(&range.parameter).or_else(|| {
                params.map(|p| match range.parameter.as_str() {
                    "max_isometric_force" => p.max_isometric_force,
                    "optimal_fiber_length" => p.optimal_fiber_length,
                    "tendon_slack_length" => p.tendon_slack_length,
                    "pennation_angle_at_optimal" => p.pennation_angle_at_optimal,
                    _ => p.max_contraction_velocity,
                })
            });
            let limit = format!("[{}, {}]", range.min, range.max);
            out.push(match value {
                Some(v) => Check {
                    family: Family::MuscleParameters,
                    name: range.parameter.clone(),
                    subject_kind: SubjectKind::Muscle,
                    subject: f.name.clone(),
                    status: if v >= range.min && v <= range.max {
                        Status::Pass
                    } else {
                        Status::Fail
                    },
                    value: Some(v),
                    unit: unit(&range.parameter),
                    limit,
                    message: if f.raw.child(&range.parameter).is_none() {
                        "OpenSim's default".into()
                    } else {
                        String::new()
                    },
                },
                None => Check {
                    family: Family::MuscleParameters,
                    name: range.parameter.clone(),
                    subject_kind: SubjectKind::Muscle,
                    subject: f.name.clone(),
                    status: Status::Skip,
                    value: None,
                    unit: unit(&range.parameter),
                    limit,
                    message: "absent, and the muscle class has no default musculo knows".into(),
                },
            });
        }
        match hill {
            Ok(h) => built.push((fi, h)),
            Err(e) => out.push(Check {
                family: Family::MuscleParameters,
                name: "force model".into(),
                subject_kind: SubjectKind::Muscle,
                subject: f.name.clone(),
                // A class musculo does not model is not a defect of the model.
                status: if MuscleKind::from_opensim_class(&f.kind).is_some() {
                    Status::Fail
                } else {
                    Status::Skip
                },
                value: None,
                unit: "",
                limit: String::new(),
                message: e,
            }),
        }
    }
    built
}

fn unit(parameter: &str) -> &'static str {
    match parameter {
        "max_isometric_force" => "N",
        "pennation_angle_at_optimal" => "rad",
        "max_contraction_velocity" => "l_opt/s",
        _ => "m",
    }
}

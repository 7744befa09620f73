//! Biomechanics unit checks of a model: does it describe a plausible human body?
//!
//! [`run`] checks, in families ([`Family`]):
//! - **connectivity**: every body reaches ground through exactly one joint, every attached
//!   element (marker, path point, wrap object, contact geometry) names an existing body;
//! - **mass and inertia**: masses > 0; inertias symmetric, positive definite and satisfying
//!   the triangle inequality I₁ + I₂ ≥ I₃;
//! - **coordinates**: min < max, default value inside the range, the range within plausible
//!   limits (±2π for angles, ±10 m for translations by default);
//! - **muscle parameters**: F_max, l_opt, l_s, α_opt and v_max within the physiological
//!   ranges of `data/check/muscle_parameter_ranges.csv`;
//! - **paths**: over a grid of each independent coordinate's range (the others at their
//!   default values), musculotendon lengths finite and > 0, moment arms finite and with no
//!   jump above 1 cm between neighbouring grid points;
//! - **moment-arm bounds**: |r| of every muscle about every rotational coordinate it crosses,
//!   over the physiological range of motion (single-coordinate sweeps, and optionally random
//!   poses of all coordinates at once), below the per-joint bound of
//!   `data/check/moment_arm_bounds.csv`;
//! - **agonist signs**: the moment arms of muscles whose action is not in doubt
//!   (`data/check/agonist_signs.csv`) have the sign of that action
//!   (`data/check/coordinate_directions.csv`);
//! - **maximum isometric moments**: per coordinate direction, Σ_k max(0, ±r_k F_iso,k(q))
//!   at the best grid point against published adult ranges
//!   (`data/check/max_isometric_moments.csv`).
//!
//! Every table row cites its publication in a `source` column. The report lists each check
//! with its subject, status, measured value and limit; nothing is printed.

// Comparisons are written `!(x > bound)` on purpose: NaN fails them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod muscles;
mod structure;
mod tables;

pub use tables::{
    AgonistRow, DirectionRow, DirectionSign, MomentArmBoundRow, MomentRow, ParameterRange,
    ParsedTables, RomRow, Tables, glob_match,
};

use crate::error::Error;
use crate::model::Model;

/// The family a check belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Family {
    Connectivity,
    MassInertia,
    Coordinates,
    MuscleParameters,
    Paths,
    MomentArmBounds,
    AgonistSigns,
    MaxIsometricMoments,
}

impl Family {
    pub const ALL: [Family; 8] = [
        Family::Connectivity,
        Family::MassInertia,
        Family::Coordinates,
        Family::MuscleParameters,
        Family::Paths,
        Family::MomentArmBounds,
        Family::AgonistSigns,
        Family::MaxIsometricMoments,
    ];

    pub fn name(&self) -> &'static str {
        match self {
            Family::Connectivity => "connectivity",
            Family::MassInertia => "mass-inertia",
            Family::Coordinates => "coordinates",
            Family::MuscleParameters => "muscle-parameters",
            Family::Paths => "paths",
            Family::MomentArmBounds => "moment-arm-bounds",
            Family::AgonistSigns => "agonist-signs",
            Family::MaxIsometricMoments => "max-isometric-moments",
        }
    }
}

/// What a check is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SubjectKind {
    Model,
    Body,
    Joint,
    Coordinate,
    Muscle,
    /// A coordinate direction, e.g. `knee_angle_r extension`.
    Direction,
}

impl SubjectKind {
    pub fn name(&self) -> &'static str {
        match self {
            SubjectKind::Model => "model",
            SubjectKind::Body => "body",
            SubjectKind::Joint => "joint",
            SubjectKind::Coordinate => "coordinate",
            SubjectKind::Muscle => "muscle",
            SubjectKind::Direction => "direction",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Pass,
    Fail,
    /// Not applicable or not computable (e.g. no muscle crosses the coordinate).
    Skip,
}

impl Status {
    pub fn name(&self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Fail => "FAIL",
            Status::Skip => "skip",
        }
    }
}

/// One check.
#[derive(Clone, Debug, PartialEq)]
pub struct Check {
    pub family: Family,
    /// What is checked, e.g. `mass > 0`, `optimal_fiber_length`.
    pub name: String,
    pub subject_kind: SubjectKind,
    /// The body, coordinate, muscle… by name.
    pub subject: String,
    pub status: Status,
    /// The measured value (in `unit`), when there is one.
    pub value: Option<f64>,
    pub unit: &'static str,
    /// The limit the value is held to, in words (e.g. `[0.005, 0.6]`, `> 0`).
    pub limit: String,
    /// Why it failed or was skipped, or what was measured.
    pub message: String,
}

/// The checks of one model, in family order.
#[derive(Clone, Debug, Default)]
pub struct CheckReport {
    pub model: String,
    pub checks: Vec<Check>,
}

/// Counts of one family.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FamilySummary {
    pub pass: usize,
    pub fail: usize,
    pub skip: usize,
}

impl CheckReport {
    /// True when no check failed.
    pub fn passed(&self) -> bool {
        self.checks.iter().all(|c| c.status != Status::Fail)
    }

    pub fn failures(&self) -> impl Iterator<Item = &Check> {
        self.checks.iter().filter(|c| c.status == Status::Fail)
    }

    pub fn summary(&self, family: Family) -> FamilySummary {
        let mut s = FamilySummary::default();
        for c in self.checks.iter().filter(|c| c.family == family) {
            match c.status {
                Status::Pass => s.pass += 1,
                Status::Fail => s.fail += 1,
                Status::Skip => s.skip += 1,
            }
        }
        s
    }

    /// The checks of one family on one subject (e.g. all checks of muscle `soleus_r`).
    pub fn find<'a>(&'a self, family: Family, subject: &'a str) -> impl Iterator<Item = &'a Check> {
        self.checks
            .iter()
            .filter(move |c| c.family == family && c.subject == subject)
    }
}

/// The most grid points over one coordinate's range: each point computes every muscle
/// path, so more would only make a check run for hours (or exhaust memory) to no benefit.
pub const MAX_GRID_POINTS: usize = 10_000;

/// The most random poses of the moment-arm bounds: each computes every muscle path (100,000
/// take seconds on the default model; ten million would take most of an hour).
pub const MAX_RANDOM_POSES: usize = 1_000_000;

/// The most random lines of the line-continuity check: each walks a few hundred poses
/// (1,000 lines take about a minute on the default model).
pub const MAX_RANDOM_LINES: usize = 100_000;

/// Settings of [`run`], with the defaults in one place.
#[derive(Clone, Debug)]
pub struct CheckOptions {
    /// Fewest grid points over each independent coordinate's range for the path, sign and
    /// moment checks (default 9; from 2 to [`MAX_GRID_POINTS`]).
    pub grid_points: usize,
    /// Largest spacing of the grid (default 2.5° for angles, scaled by 1 m/rad for
    /// translations): fine enough that a smoothly varying moment arm (a few mm per degree)
    /// cannot change by `max_moment_arm_jump` between neighbours, so that a flagged jump is a
    /// discontinuity, not the grid's coarseness.
    pub max_grid_step: f64,
    /// Largest change of a moment arm between neighbouring grid points (default 0.01 m).
    pub max_moment_arm_jump: f64,
    /// Moment arms smaller than this are not sign-checked (default 0.001 m).
    pub sign_threshold: f64,
    /// Plausible range limit of rotational (and coupled) coordinates (default 2π rad).
    pub max_rotation: f64,
    /// Plausible range limit of translational coordinates (default 10 m).
    pub max_translation: f64,
    /// Random poses for the moment-arm bounds (default 0; at most [`MAX_RANDOM_POSES`]):
    /// every crossed rotational
    /// coordinate drawn uniformly from its physiological range at once, where the
    /// single-coordinate sweeps leave the others at their defaults.
    pub random_poses: usize,
    /// Seed of those poses (default 1).
    pub random_pose_seed: u64,
    /// Random straight lines for the length-continuity check (default 0; at most
    /// [`MAX_RANDOM_LINES`]): each joins two poses drawn like the random poses (every crossed
    /// rotational coordinate uniform in its physiological range at once) and is walked in
    /// steps of at most `max_line_step` (the Euclidean distance between neighbouring poses
    /// over those coordinates); a muscle fails when its length changes by more than
    /// `max_line_length_jump` between neighbouring poses.
    pub random_lines: usize,
    /// Seed of those lines (default 1).
    pub random_line_seed: u64,
    /// Largest distance between neighbouring poses of a line (default 0.5°): the Euclidean
    /// norm of their difference over the line's coordinates, so a muscle crossing several
    /// of them changes its length by at most ‖r‖₂ · `max_line_step` on a smooth path.
    pub max_line_step: f64,
    /// Largest change of a musculotendon length between neighbouring poses of a line
    /// (default 0.001 m: 0.5° at a 7 cm moment arm changes a length by 0.6 mm, so a larger
    /// change at that step is a jump of the path, not the step's coarseness).
    pub max_line_length_jump: f64,
    /// The reference tables (default: the built-in `data/check/*.csv`).
    pub tables: Tables,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            grid_points: 9,
            max_grid_step: 2.5f64.to_radians(),
            max_moment_arm_jump: 0.01,
            sign_threshold: 0.001,
            max_rotation: 2.0 * std::f64::consts::PI,
            max_translation: 10.0,
            random_poses: 0,
            random_pose_seed: 1,
            random_lines: 0,
            random_line_seed: 1,
            max_line_step: 0.5f64.to_radians(),
            max_line_length_jump: 0.001,
            tables: Tables::builtin(),
        }
    }
}

/// Runs every check on `model`. Errors only for invalid options or tables; a model that
/// fails a check is a report with failures, not an error.
pub fn run(model: &Model, options: &CheckOptions) -> crate::Result<CheckReport> {
    run_with_progress(model, options, &mut |_, _| {})
}

/// [`run`], calling `progress(done, total)` after each independent coordinate's sweeps (the
/// path, sign and moment checks, which take nearly all the time; `total` = the model's
/// independent coordinates).
pub fn run_with_progress(
    model: &Model,
    options: &CheckOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> crate::Result<CheckReport> {
    if !(2..=MAX_GRID_POINTS).contains(&options.grid_points) {
        return Err(Error::invalid(
            "grid_points",
            format!(
                "{} points: must be from 2 to {MAX_GRID_POINTS}",
                options.grid_points
            ),
        ));
    }
    if options.random_poses > MAX_RANDOM_POSES {
        return Err(Error::invalid(
            "random_poses",
            format!(
                "{} poses: must be at most {MAX_RANDOM_POSES}",
                options.random_poses
            ),
        ));
    }
    if options.random_lines > MAX_RANDOM_LINES {
        return Err(Error::invalid(
            "random_lines",
            format!(
                "{} lines: must be at most {MAX_RANDOM_LINES}",
                options.random_lines
            ),
        ));
    }
    for (name, v) in [
        ("max_moment_arm_jump", options.max_moment_arm_jump),
        ("max_line_step", options.max_line_step),
        ("max_line_length_jump", options.max_line_length_jump),
        ("sign_threshold", options.sign_threshold),
        ("max_grid_step", options.max_grid_step),
        ("max_rotation", options.max_rotation),
        ("max_translation", options.max_translation),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(name, format!("must be positive, found {v}")));
        }
    }
    // The widest grid: a coordinate spanning the whole plausible range at the finest step.
    let widest = 2.0 * options.max_rotation.max(options.max_translation) / options.max_grid_step;
    if !(widest < MAX_GRID_POINTS as f64) {
        return Err(Error::invalid(
            "max_grid_step",
            format!(
                "{} over ranges up to ±{} would need {widest:.3e} grid points, more than \
                 {MAX_GRID_POINTS}",
                options.max_grid_step,
                options.max_rotation.max(options.max_translation)
            ),
        ));
    }
    // The longest line: from one corner of the box of the widest rotational ranges to the
    // opposite one.
    let longest = (model.nq() as f64).sqrt() * 2.0 * options.max_rotation / options.max_line_step;
    if !(longest < MAX_GRID_POINTS as f64) {
        return Err(Error::invalid(
            "max_line_step",
            format!(
                "{} over ranges up to ±{} would need {longest:.3e} poses per line, more than \
                 {MAX_GRID_POINTS}",
                options.max_line_step, options.max_rotation
            ),
        ));
    }
    let tables = options.tables.parse()?;
    let mut checks = Vec::new();
    structure::connectivity(model, &mut checks);
    structure::mass_inertia(model, &mut checks);
    structure::coordinates(model, options, &mut checks);
    muscles::all(model, options, &tables, &mut checks, progress);
    checks.sort_by_key(|c| c.family);
    Ok(CheckReport {
        model: model.source.clone(),
        checks,
    })
}

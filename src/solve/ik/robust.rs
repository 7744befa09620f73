//! Robust marker weights for inverse kinematics: a marker that disagrees with the others over
//! a whole clip (mislabelled, swapped with another, displaced on the skin, drifting for most
//! of the clip) is found from the clip's residuals and down-weighted, so that it no longer
//! bends the fit of the others — iteratively reweighted least squares (Holland & Welsch 1977)
//! with a hard-redescending weight (Tukey's "skipped" estimators: full weight within a cutoff
//! set by the data, almost none beyond it) on each marker's error over the clip.
//!
//! The statistic is per marker over the clip, not per frame: a swapped or displaced marker is
//! wrong in every frame, and one weight per marker keeps each frame an ordinary weighted least
//! squares, solved by the warm-started frame loop of [`super`] unchanged. Per marker task
//! i, from a fit of the clip,
//!
//!   r_i = median over the frames where marker i is present of ‖p_i(q_t) − x_i(t)‖,
//!
//! and across the markers (those of positive weight that are present somewhere)
//!
//!   c = median_i r_i,   s = 1.4826 · median_i |r_i − c|   (the MAD, a normal SD's estimate),
//!
//! marker i disagrees with the others when both
//!
//!   (r_i − c) / s > 3.5        (Iglewicz & Hoaglin's modified z-score: far from the others)
//!   r_i > 50 mm                (beyond what skin motion and joint-centre conventions explain)
//!
//! hold. The second condition keeps a clip whose markers all fit within a few centimetres
//! (soft-tissue motion of skin markers is 1–3 cm; SMPL's and a model's joint centres differ
//! by a few centimetres) a plain least-squares fit: a head joint fitted to 11 mm while the
//! others fit to 3 mm is not a wrong label. A disagreeing marker's weight is multiplied by
//! ε = 10⁻³ ([`OUTLIER_WEIGHT`]), whatever its error: the weight
//!
//!   w(r) = 1 for r ≤ max(c + 3.5 s, floor),   ε beyond,
//!
//! is that of a loss quadratic up to the cutoff and (almost) flat after it, so a marker 1 m
//! off pulls on the fit as one of weight 1 that is 1 mm off. The weight does not fall further
//! with the error (as a Geman–McClure or Cauchy weight would, ~(σ/r)⁴ or (σ/r)²): a
//! disagreeing marker's error measures the disagreement, not a noise level, and two such
//! markers on one segment would turn the segment by the ratio of their weights (with
//! Geman–McClure weights, the Gait2392 trunk's rotation moved by 3.5° between fits of its
//! walk that differed only in a thigh marker, through the acromia's weights). ε stays above
//! zero so that a coordinate only these markers determine still follows them instead of
//! resting where it starts. The other markers keep their weights, so a clip without a
//! disagreeing marker is fitted exactly as without this step, at the cost of one median per
//! marker. Otherwise the clip is solved again with the new weights (the first frame from its
//! previous solution, each later one from the new solutions before it, as in the first pass),
//! and the test repeated on the new fit (a marker that only looked wrong because a bad
//! neighbour pulled the fit towards itself is then cleared) until the set of disagreeing
//! markers stops changing.
//!
//! Only markers the others can outvote are down-weighted ([`outvoted_only`]): where the
//! disagreeing markers together carry more than half of what the fit knows of a coordinate
//! (its diagonal entry Σ wᵢ ‖∂pᵢ/∂q_j‖² of the normal matrix, median over frames), the others
//! cannot tell that coordinate without them, and every disagreeing marker that moves it keeps
//! its weight. On Gait2392's walk matched by name, the acromia fit 64 and 58 mm off while the
//! others fit to 6 mm, but they carry most of the trunk's axial rotation (the torso's other
//! markers, sternum and head top, lie near its axis): without them the trunk turned freely
//! and the ground reactions estimated from the motion moved.
//!
//! With fewer than [`MIN_MARKERS`] markers there is no majority to disagree with and nothing
//! is down-weighted. A marker that is wrong in fewer than half of its frames (a short swap)
//! keeps a clip median within the others' and is not caught by this clip-level test.

use super::{IkSolution, IkTasks};
use crate::dynamics::{Data, forward_kinematics, point_jacobian};
use crate::error::Error;
use crate::model::Model;
use crate::motion::Motion;
use nalgebra::DMatrix;

/// Iglewicz & Hoaglin's limit on the modified z-score (r − c)/s of an outlier.
pub const MODIFIED_Z_LIMIT: f64 = 3.5;

/// A marker whose clip median error is below this (m) is never called disagreeing.
pub const DISAGREEMENT_FLOOR: f64 = 0.05;

/// The fewest markers (of positive weight, present in some frame) among which one can
/// disagree with the others.
pub const MIN_MARKERS: usize = 5;

/// The factor on a disagreeing marker's weight.
pub const OUTLIER_WEIGHT: f64 = 1e-3;

/// Settings of the robust marker weights ([`RobustMarkers::default`] documents the defaults).
#[derive(Clone, Debug, PartialEq)]
pub struct RobustMarkers {
    /// Limit on the modified z-score; default [`MODIFIED_Z_LIMIT`].
    pub z_limit: f64,
    /// Clip median error (m) below which a marker never disagrees; default
    /// [`DISAGREEMENT_FLOOR`].
    pub floor: f64,
    /// The most times the clip is solved again with new weights; default 4.
    pub max_passes: usize,
    /// Factor on a disagreeing marker's weight, in (0, 1); default [`OUTLIER_WEIGHT`].
    pub outlier_weight: f64,
}

impl Default for RobustMarkers {
    fn default() -> Self {
        RobustMarkers {
            z_limit: MODIFIED_Z_LIMIT,
            floor: DISAGREEMENT_FLOOR,
            max_passes: 4,
            outlier_weight: OUTLIER_WEIGHT,
        }
    }
}

impl RobustMarkers {
    /// Checks the settings' values.
    pub fn validate(&self) -> crate::Result<()> {
        if !(self.z_limit > 0.0 && self.z_limit.is_finite()) {
            return Err(Error::invalid(
                "robust.z_limit",
                format!("{} must be > 0 and finite", self.z_limit),
            ));
        }
        if !(self.floor >= 0.0 && self.floor.is_finite()) {
            return Err(Error::invalid(
                "robust.floor",
                format!("{} m must be ≥ 0 and finite", self.floor),
            ));
        }
        if self.max_passes == 0 {
            return Err(Error::invalid("robust.max_passes", "must be at least 1"));
        }
        if !(self.outlier_weight > 0.0 && self.outlier_weight < 1.0) {
            return Err(Error::invalid(
                "robust.outlier_weight",
                format!("{} must lie in (0, 1)", self.outlier_weight),
            ));
        }
        Ok(())
    }
}

/// A marker task that disagreed with the others and was down-weighted.
#[derive(Clone, Debug, PartialEq)]
pub struct DisagreeingMarker {
    /// Index in `IkTasks::markers`.
    pub task: usize,
    /// Median over the frames where it is present of its error in the final fit (m).
    pub median_error: f64,
    /// Frames in which its target is present (of `IkSolution::n_frames`).
    pub frames_present: usize,
    /// Median of the other markers' clip median errors in the final fit (m).
    pub others_median_error: f64,
    /// The weight the final fit gave it (its task weight × the outlier weight).
    pub weight: f64,
}

/// Per marker task: the median of its errors over the frames where it is present, and the
/// number of those frames (NaN and 0 for a marker never present).
pub fn clip_errors(solution: &IkSolution, n_markers: usize) -> Vec<(f64, usize)> {
    let mut column = Vec::with_capacity(solution.n_frames());
    (0..n_markers)
        .map(|i| {
            column.clear();
            column.extend(
                (0..solution.n_frames())
                    .map(|f| solution.marker_error[f * n_markers + i])
                    .filter(|e| e.is_finite()),
            );
            (median(&mut column), column.len())
        })
        .collect()
}

/// The median of `values` (reordered; NaN when empty; the upper middle of an even count).
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The outlier test of the module's documentation on the markers' clip errors `errors`
/// (from [`clip_errors`]), among the markers `counted` (positive task weight): per marker
/// task, `Some(factor)` on its weight when it disagrees with the others, else `None`.
pub fn disagreement(
    errors: &[(f64, usize)],
    counted: &[bool],
    settings: &RobustMarkers,
) -> Vec<Option<f64>> {
    let mut out = vec![None; errors.len()];
    let mut r: Vec<f64> = (errors.iter().zip(counted))
        .filter(|((e, k), c)| **c && *k > 0 && e.is_finite())
        .map(|((e, _), _)| *e)
        .collect();
    if r.len() < MIN_MARKERS {
        return out;
    }
    let c = median(&mut r);
    for v in r.iter_mut() {
        *v = (*v - c).abs();
    }
    let s = 1.4826 * median(&mut r);
    // (r − c)/s > z ⇔ r > c + z s, which also holds for s = 0
    let cutoff = (c + settings.z_limit * s).max(settings.floor);
    for (i, ((e, k), counted)) in errors.iter().zip(counted).enumerate() {
        if *counted && *k > 0 && *e > cutoff {
            out[i] = Some(settings.outlier_weight);
        }
    }
    out
}

/// Clears the verdict (from [`disagreement`]) of the markers the others cannot outvote. Per
/// frame f and coordinate j, with d_ij = w_i ‖∂p_i/∂q_j‖² over the markers present (the
/// normal matrix's diagonal, one marker at a time),
///
///   share_j(f) = Σ_{i disagreeing} d_ij / Σ_i d_ij,
///
/// and where the median over frames of share_j exceeds ½, every disagreeing marker that moves
/// coordinate j keeps its weight.
pub fn outvoted_only(
    model: &Model,
    targets: &Motion,
    tasks: &IkTasks,
    solution: &IkSolution,
    verdict: &mut [Option<f64>],
) -> crate::Result<()> {
    if verdict.iter().all(Option::is_none) {
        return Ok(());
    }
    let n = model.nq();
    let frames = solution.n_frames();
    let mut data = Data::new(model);
    let mut jac = DMatrix::zeros(3, n);
    // per coordinate: the share per frame; per disagreeing marker: whether it moves each
    let mut shares: Vec<Vec<f64>> = vec![Vec::with_capacity(frames); n];
    let mut moves = vec![false; verdict.len() * n];
    let (mut all, mut out) = (vec![0.0; n], vec![0.0; n]);
    for f in 0..frames {
        forward_kinematics(model, &mut data, solution.frame(f))?;
        all.fill(0.0);
        out.fill(0.0);
        for (i, t) in tasks.markers.iter().enumerate() {
            if t.weight <= 0.0 || targets.frame(f)[t.target].x.is_nan() {
                continue;
            }
            let m = &model.markers[t.marker];
            point_jacobian(model, &data, m.body, &m.location_in_body, &mut jac)?;
            for j in 0..n {
                let d = t.weight * jac.column(j).norm_squared();
                all[j] += d;
                if verdict[i].is_some() {
                    out[j] += d;
                    moves[i * n + j] |= d > 0.0;
                }
            }
        }
        for j in 0..n {
            if all[j] > 0.0 {
                shares[j].push(out[j] / all[j]);
            }
        }
    }
    for (j, share) in shares.iter_mut().enumerate() {
        if median(share) > 0.5 {
            for (i, v) in verdict.iter_mut().enumerate() {
                if moves[i * n + j] {
                    *v = None;
                }
            }
        }
    }
    Ok(())
}

/// One warning per down-weighted marker of `solution`, e.g. "walk.trc: marker R.ASIS
/// disagrees with the others (median error 98 mm over 150 of 150 frames; the others' median
/// 7 mm): down-weighted in IK (weight 1 → 0.00081)".
pub fn warnings(
    model: &Model,
    tasks: &IkTasks,
    solution: &IkSolution,
    source: &str,
) -> Vec<String> {
    solution
        .disagreeing
        .iter()
        .map(|d| {
            let task = &tasks.markers[d.task];
            format!(
                "{source}: marker {} disagrees with the others (median error {:.0} mm over {} \
                 of {} frames; the others' median {:.0} mm): down-weighted in IK (weight {} → \
                 {:.2e})",
                model.markers[task.marker].name,
                d.median_error * 1e3,
                d.frames_present,
                solution.n_frames(),
                d.others_median_error * 1e3,
                task.weight,
                d.weight
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn errors_mm(mm: &[f64]) -> Vec<(f64, usize)> {
        mm.iter().map(|v| (v * 1e-3, 100)).collect()
    }

    #[test]
    fn only_a_marker_far_from_the_others_and_beyond_the_floor_disagrees() {
        let settings = RobustMarkers::default();
        let e = errors_mm(&[6.0, 7.0, 5.0, 9.0, 8.0, 6.5, 100.0, 7.5]);
        let all = vec![true; e.len()];
        let v = disagreement(&e, &all, &settings);
        let flagged: Vec<usize> = (0..e.len()).filter(|&i| v[i].is_some()).collect();
        assert_eq!(flagged, [6]);
        assert_eq!(v[6], Some(OUTLIER_WEIGHT));
        // the cutoff by hand: sorted 5, 6, 6.5, 7, 7.5, 8, 9, 100 mm → c = 7.5 (upper
        // middle); deviations sorted 0, 0.5, 0.5, 1, 1.5, 1.5, 2.5, 92.5 → 1.5, so
        // c + 3.5 · 1.4826 · 1.5 = 15.28 mm; with the floor lowered to 10 mm, 16 mm is out
        // and 15 mm in
        let lower = RobustMarkers {
            floor: 0.01,
            ..RobustMarkers::default()
        };
        for (mm, out) in [(16.0, true), (15.0, false)] {
            let mut e = e.clone();
            e[3].0 = mm * 1e-3;
            let v = disagreement(&e, &all, &lower);
            assert_eq!(v[3].is_some(), out, "{mm} mm");
        }
        // the same pattern scaled below the floor: a 10 mm marker among 0.6 mm ones
        let small = errors_mm(&[0.6, 0.7, 0.5, 0.9, 0.8, 0.65, 10.0, 0.75]);
        assert!(
            disagreement(&small, &all, &settings)
                .iter()
                .all(Option::is_none)
        );
        // a marker not counted (weight 0) neither disagrees nor enters c and s
        let mut counted = all.clone();
        counted[6] = false;
        assert!(
            disagreement(&e, &counted, &settings)
                .iter()
                .all(Option::is_none)
        );
        // too few markers to outvote one
        let few = errors_mm(&[6.0, 7.0, 5.0, 100.0]);
        assert!(
            disagreement(&few, &[true; 4], &settings)
                .iter()
                .all(Option::is_none)
        );
        // a marker never present is left alone
        let mut absent = e.clone();
        absent[6].1 = 0;
        assert!(
            disagreement(&absent, &all, &settings)
                .iter()
                .all(Option::is_none)
        );
    }

    #[test]
    fn equal_errors_give_a_zero_spread_and_still_single_out_the_far_marker() {
        let e = errors_mm(&[60.0, 60.0, 60.0, 60.0, 60.0, 200.0]);
        let v = disagreement(&e, &[true; 6], &RobustMarkers::default());
        assert!(v[..5].iter().all(Option::is_none));
        assert_eq!(v[5], Some(OUTLIER_WEIGHT));
    }

    #[test]
    fn settings_out_of_range_are_refused_by_name() {
        let bad = [
            RobustMarkers {
                z_limit: 0.0,
                ..RobustMarkers::default()
            },
            RobustMarkers {
                floor: f64::NAN,
                ..RobustMarkers::default()
            },
            RobustMarkers {
                max_passes: 0,
                ..RobustMarkers::default()
            },
            RobustMarkers {
                outlier_weight: 0.0,
                ..RobustMarkers::default()
            },
        ];
        for (s, name) in bad
            .iter()
            .zip(["z_limit", "floor", "max_passes", "outlier_weight"])
        {
            let e = s.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        RobustMarkers::default().validate().unwrap();
    }
}

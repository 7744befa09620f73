//! Calibration segments: a pose held before or after the motion (a T-pose, an A-pose, a
//! static stand for the capture system's calibration) that the motion does not continue
//! from. CMU's cmu_01_01 starts with one frame of its skeleton's rest pose (a T-pose), from
//! which the next frame's joints are 0.32 m away (RMS): 38 m/s at 120 fps, which IK, the
//! filter and inverse dynamics turn into 6.8 body weights of force no contact explains.
//!
//! Such a segment is found from the clip itself. Per transition f → f+1 the pose speed
//!
//!   s_f = √( (1/n) Σᵢ |(pᵢ,f+1 − c_f+1) − (pᵢ,f − c_f)|² ) / (t_f+1 − t_f)
//!
//! is the RMS speed of the n targets present in both frames relative to their centroid c
//! (the body's travel is motion, not a change of pose; without the centroid the walks'
//! travel halves the T-pose jump's margin). A continuous motion changes pose
//! smoothly, so its transitions share one scale: the median m of s over the clip, with the
//! robust spread σ = 1.4826 · median |s_f − m| (the median absolute deviation, scaled to a
//! normal's standard deviation). From each end the frames are held while s_f ≤ m (a pose kept,
//! not motion); the first transition b from the start (the last from the end) with s_b > m
//! closes the held segment 0..=b (b+1..T), which is calibration when its jump is
//!
//!   s_b > m + K σ   and   s_b > R · max{ s_f : f outside the segments and their jumps }
//!
//! — an outlier by the clip's own statistics, and faster than anything the motion does
//! elsewhere by a factor R — and the segment is short (at most [`MAX_SEGMENT_FRACTION`] of the
//! clip's frames). K and R were judged on every clip at hand (the HumanML3D sample, the CMU
//! and C3D trials, the OpenSim TRC trials, static ones included): there the transition that
//! ends the held frames at either end lies within 4.6 σ of the median (a static trial's marker
//! jitter), the fastest transition anywhere within 12.2 σ (the same static trial) and 1.5× the
//! next fastest; cmu_01_01's T-pose jump lies at 140 σ and 33× the walk's fastest, and stays
//! beyond both bounds at HumanML3D's 20 fps (tests/calibration_frames.rs).

use super::Motion;
use std::ops::Range;

/// K: a jump lies more than this many robust standard deviations above the clip's median
/// pose speed (module docs).
pub const OUTLIER_SIGMAS: f64 = 10.0;
/// R: a jump is more than this many times the fastest pose speed of the motion elsewhere.
pub const OUTLIER_RATIO: f64 = 2.0;
/// The largest share of the clip's frames a calibration segment may take: the rest is the
/// motion.
pub const MAX_SEGMENT_FRACTION: f64 = 0.25;

/// A calibration segment found at one end of a clip.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationSegment {
    /// Its frames (0-based, of the clip as given).
    pub frames: Range<usize>,
    /// The pose speed of the jump between it and the motion (m/s).
    pub jump_speed: f64,
    /// The clip's median pose speed (m/s).
    pub median_speed: f64,
    /// The fastest pose speed of the clip elsewhere (m/s).
    pub fastest_elsewhere: f64,
}

/// What [`detect`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationCheck {
    /// The frames to keep.
    pub keep: Range<usize>,
    pub leading: Option<CalibrationSegment>,
    pub trailing: Option<CalibrationSegment>,
}

/// The pose speed s_f of each transition f → f+1 (module docs), T−1 values; NaN where the
/// two frames share no target.
pub fn pose_speeds(motion: &Motion) -> Vec<f64> {
    let frames = motion.n_frames();
    let mut out = Vec::with_capacity(frames.saturating_sub(1));
    for f in 0..frames.saturating_sub(1) {
        let (a, b) = (motion.frame(f), motion.frame(f + 1));
        let common = || {
            a.iter()
                .zip(b)
                .filter(|(p, q)| p.x.is_finite() && q.x.is_finite())
        };
        let n = common().count();
        if n == 0 {
            out.push(f64::NAN);
            continue;
        }
        // c = centroids of the common targets in each frame
        let (ca, cb) = common().fold(
            (super::Vec3::zeros(), super::Vec3::zeros()),
            |(x, y), (p, q)| (x + p, y + q),
        );
        let (ca, cb) = (ca / n as f64, cb / n as f64);
        let sum: f64 = common()
            .map(|(p, q)| ((q - cb) - (p - ca)).norm_squared())
            .sum();
        out.push((sum / n as f64).sqrt() / (motion.time[f + 1] - motion.time[f]));
    }
    out
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Finds a calibration segment at either end of `motion` (module docs). A clip of fewer than
/// 8 frames is left whole: its statistics say nothing.
pub fn detect(motion: &Motion) -> CalibrationCheck {
    let frames = motion.n_frames();
    let whole = CalibrationCheck {
        keep: 0..frames,
        leading: None,
        trailing: None,
    };
    if frames < 8 {
        return whole;
    }
    let s = pose_speeds(motion);
    let mut finite: Vec<f64> = s.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.len() < 4 {
        return whole;
    }
    let m = median(&mut finite);
    let mut deviations: Vec<f64> = finite.iter().map(|v| (v - m).abs()).collect();
    let sigma = 1.4826 * median(&mut deviations);
    let longest = (MAX_SEGMENT_FRACTION * frames as f64).floor() as usize;
    let last = s.len() - 1;
    // Candidates: the first transition from each end that is not held (s ≤ m); the frames
    // before it (after it) are the held segment, the transition its jump.
    let moving = |f: &usize| s[*f] > m;
    let lead = (0..longest.min(s.len())).find(moving);
    let trail = (0..longest.min(s.len())).map(|k| last - k).find(moving);
    let outlier = |b: usize| s[b] > m + OUTLIER_SIGMAS * sigma;
    // the transitions of a candidate that is an outlier are not the clip's motion
    let lead_range = lead.filter(|b| outlier(*b)).map_or(0..0, |b| 0..b + 1);
    let trail_range = trail.filter(|b| outlier(*b)).map_or(0..0, |b| b..s.len());
    let fastest = (0..s.len())
        .filter(|f| !lead_range.contains(f) && !trail_range.contains(f) && s[*f].is_finite())
        .map(|f| s[f])
        .fold(0.0, f64::max);
    let segment = |b: usize, frames: Range<usize>| {
        (outlier(b) && s[b] > OUTLIER_RATIO * fastest).then(|| CalibrationSegment {
            frames,
            jump_speed: s[b],
            median_speed: m,
            fastest_elsewhere: fastest,
        })
    };
    let leading = lead.and_then(|b| segment(b, 0..b + 1));
    let trailing = trail.and_then(|b| segment(b, b + 1..frames));
    let start = leading.as_ref().map_or(0, |l| l.frames.end);
    let end = trailing.as_ref().map_or(frames, |t| t.frames.start);
    if end < start + 4 {
        return whole;
    }
    CalibrationCheck {
        keep: start..end,
        leading,
        trailing,
    }
}

/// `targets` without the calibration segments [`detect`] finds, and a warning naming the
/// frames left out — numbered as in `recorded`, the clip as read (whose frames `targets`
/// holds a run of, with the same times), with their times. The frames kept keep their times,
/// so measured loads and force plates still line up with them.
pub fn trim(targets: &Motion, recorded: &Motion) -> crate::Result<(Motion, Option<String>)> {
    let check = detect(targets);
    if check.leading.is_none() && check.trailing.is_none() {
        return Ok((targets.clone(), None));
    }
    // the frame of `recorded` at time t (the times are the same values)
    let number = |f: usize| {
        let t = targets.time[f];
        recorded
            .time
            .partition_point(|x| *x < t - 1e-3 / recorded.rate_hz)
    };
    let describe = |segment: &CalibrationSegment, how: &str| {
        let (a, b) = (segment.frames.start, segment.frames.end - 1);
        let frames = if a == b {
            format!("frame {} (t = {:.3} s)", number(a), targets.time[a])
        } else {
            format!(
                "frames {}–{} (t = {:.3}–{:.3} s)",
                number(a),
                number(b),
                targets.time[a],
                targets.time[b]
            )
        };
        format!(
            "{frames}, a held pose the motion {how} a jump of {:.2} m/s (RMS pose speed; the \
             clip's median {:.2} m/s, its fastest elsewhere {:.2} m/s)",
            segment.jump_speed, segment.median_speed, segment.fastest_elsewhere
        )
    };
    let parts: Vec<String> = [
        check.leading.as_ref().map(|s| describe(s, "leaves with")),
        check.trailing.as_ref().map(|s| describe(s, "enters with")),
    ]
    .into_iter()
    .flatten()
    .collect();
    let warning = format!(
        "{}: left out as calibration (of {} frames): {}; --keep-calibration-frames keeps them",
        targets.source,
        recorded.n_frames(),
        parts.join("; ")
    );
    let kept = targets.time_window(
        targets.time[check.keep.start],
        targets.time[check.keep.end - 1],
    )?;
    Ok((kept, Some(warning)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::Vec3;

    /// Three targets circling their centre at radius 0.2·(1 + 0.5 sin 0.7t)·(1 + k e^(−5t)) m,
    /// 2 rad/s, at 100 Hz for 4 s, after `held` frames of the first pose spread to three times
    /// its size about its centroid (arms out) and moved 1 m.
    fn clip(held: usize, k: f64) -> Motion {
        let rate = 100.0;
        let pose = |t: f64| -> Vec<Vec3> {
            (0..3)
                .map(|i| {
                    let r = 0.2 * (1.0 + 0.5 * (0.7 * t).sin()) * (1.0 + k * (-5.0 * t).exp());
                    let a = 2.0 * t + i as f64 * 2.1;
                    Vec3::new(r * a.cos(), 1.0 + r * a.sin(), 0.1 * i as f64)
                })
                .collect()
        };
        let first = pose(0.0);
        let centre = first.iter().sum::<Vec3>() / 3.0;
        let mut positions = Vec::new();
        for _ in 0..held {
            positions.extend(
                first
                    .iter()
                    .map(|p| centre + 3.0 * (p - centre) + Vec3::new(1.0, 0.0, 0.0)),
            );
        }
        for f in 0..400 {
            positions.extend(pose(f as f64 / rate));
        }
        Motion::uniform(
            "test",
            vec!["a".into(), "b".into(), "c".into()],
            rate,
            positions,
        )
        .unwrap()
    }

    #[test]
    fn a_held_pose_the_motion_jumps_from_is_found() {
        for held in [1, 10, 100] {
            let check = detect(&clip(held, 0.0));
            assert_eq!(check.keep, held..held + 400, "{held}: {check:?}");
            let jump = check.leading.unwrap();
            assert_eq!(jump.frames, 0..held);
            // the jump: each target's offset from the centroid shrinks from 3× to 1×, so it
            // moves by 2·|first pose offset| (the 1 m of travel is no change of pose)
            let first = clip(0, 0.0);
            let f0 = first.frame(0);
            let centre = f0.iter().sum::<Vec3>() / 3.0;
            let rms = (f0
                .iter()
                .map(|p| (2.0 * (p - centre)).norm_squared())
                .sum::<f64>()
                / 3.0)
                .sqrt();
            assert!(
                (jump.jump_speed - rms * 100.0).abs() < 1e-9 * rms * 100.0,
                "{jump:?}"
            );
        }
        // a held segment longer than a quarter of the clip is not calibration
        assert_eq!(detect(&clip(150, 0.0)).keep, 0..550);
    }

    #[test]
    fn a_motion_that_starts_at_its_fastest_is_kept_whole() {
        // the first transitions are the clip's fastest (radius 3× and shrinking at the start)
        // but continuous: no jump beyond R times the next
        let fast = clip(0, 2.0);
        let s = pose_speeds(&fast);
        assert!(s[0] > 2.0 * s[200], "{} {}", s[0], s[200]);
        assert_eq!(detect(&fast).keep, 0..400);
        assert_eq!(detect(&clip(0, 0.0)).keep, 0..400);
    }
}

//! Bodies as low as the feet. Where a body without contact points comes down to the floor —
//! a knee kneeling, a hand put down, the pelvis sitting — the floor carries it too, but the
//! contact forces are the contact points' only: its load goes through the feet (or the
//! residual actuators), and the joint moments and muscle forces in between are not the
//! body's.
//!
//! A body counts when its origin (the centre of the joint that moves it) lies within `height`
//! of the floor, along the floor normal n: n·o_b − h_floor ≤ height. The feet do not count:
//! the bodies with contact points, and those whose origin lies within `height` of the lowest
//! contact point in the model's default pose (a talus, whose origin is the ankle).

use super::ContactSet;
use crate::dynamics::{Data, forward_kinematics};
use crate::error::Error;
use crate::model::Model;

/// A body that came within the height of the floor ([`low_bodies`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LowBody {
    /// Index into `Model::bodies`.
    pub body: usize,
    /// Frames in which it did, the first and the last of them.
    pub frames: usize,
    pub first: usize,
    pub last: usize,
    /// Its lowest origin height above the floor over the clip (m).
    pub lowest: f64,
}

/// The bodies (in model order) whose origin comes within `height` of the floor at
/// `set.floor_height` in any frame of `q` (T × nq, frame-major).
pub fn low_bodies(
    model: &Model,
    set: &ContactSet,
    height: f64,
    q: &[f64],
) -> crate::Result<Vec<LowBody>> {
    let nq = model.nq();
    if nq == 0 || !q.len().is_multiple_of(nq) {
        return Err(Error::invalid(
            "q",
            format!("length {} is not a multiple of nq = {nq}", q.len()),
        ));
    }
    if !(height >= 0.0 && height.is_finite()) {
        return Err(Error::invalid("height", format!("{height}: must be ≥ 0")));
    }
    let nb = model.bodies.len();
    let n = set.floor_normal;
    let mut data = Data::new(model);
    // the feet: the contact bodies, and the bodies standing within `height` of the lowest
    // contact point (n·c − r) in the default pose
    forward_kinematics(model, &mut data, &model.default_q())?;
    let sole = set
        .points
        .iter()
        .map(|p| n.dot(&data.point_position(p.body, &p.location_in_body)) - p.radius)
        .fold(f64::INFINITY, f64::min);
    let mut feet: Vec<bool> = (0..nb)
        .map(|b| b == 0 || n.dot(&data.body_pose(b).1) - sole <= height)
        .collect();
    for p in &set.points {
        feet[p.body] = true;
    }
    let mut low: Vec<Option<LowBody>> = vec![None; nb];
    for (t, qt) in q.chunks(nq).enumerate() {
        forward_kinematics(model, &mut data, qt)?;
        for (b, found) in low.iter_mut().enumerate().filter(|(b, _)| !feet[*b]) {
            let (_, origin) = data.body_pose(b);
            let h = n.dot(&origin) - set.floor_height;
            if h > height {
                continue;
            }
            let entry = found.get_or_insert(LowBody {
                body: b,
                frames: 0,
                first: t,
                last: t,
                lowest: h,
            });
            entry.frames += 1;
            entry.last = t;
            entry.lowest = entry.lowest.min(h);
        }
    }
    Ok(low.into_iter().flatten().collect())
}

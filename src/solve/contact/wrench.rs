//! What a force plate under each group would report: total force, centre of pressure on the
//! floor plane and free moment.
//!
//! In floor coordinates (t₁, n, t₂) — (x, y, z) for a +y normal — with origin o = h n on the
//! floor, the group's force F = Σ f_p and moment M = Σ (p − o) × f_p give the centre of pressure
//! c = o + x t₁ + z t₂, the point of the floor about which the moment is along the normal:
//!   x = M_z / F_y,   z = −M_x / F_y,   T = M_y − z F_x + x F_z   (free moment about n).

use super::{ContactFrame, ContactSet};
use crate::error::Error;
use crate::spatial::Vec3;

/// Normal forces below this (N) leave the centre of pressure undefined.
const UNLOADED_NEWTON: f64 = 1e-6;

/// One group's ground reaction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupWrench {
    /// Total force of the ground on the group, in ground (N).
    pub force: Vec3,
    /// Centre of pressure on the floor plane (m). When the group carries no normal force
    /// (`loaded` false) it is the mean of the group's contact points projected on the floor.
    pub cop: Vec3,
    /// Moment about the floor normal at the centre of pressure (N·m; 0 when not loaded).
    pub free_moment: f64,
    /// Whether the normal force exceeds 1e-6 N.
    pub loaded: bool,
}

impl Default for GroupWrench {
    fn default() -> Self {
        GroupWrench {
            force: Vec3::zeros(),
            cop: Vec3::zeros(),
            free_moment: 0.0,
            loaded: false,
        }
    }
}

/// Per group of `set` (`out` in [`ContactSet::groups`] order): total force, centre of pressure
/// on the floor (`set.floor_height`) and free moment of `frame`'s forces.
pub fn ground_reaction(
    set: &ContactSet,
    frame: &ContactFrame,
    out: &mut [GroupWrench],
) -> crate::Result<()> {
    if out.len() != set.groups().len() {
        return Err(Error::invalid(
            "out",
            format!(
                "needs {} entries (one per group), has {}",
                set.groups().len(),
                out.len()
            ),
        ));
    }
    let np = set.points.len();
    if frame.forces.len() != np || frame.points.len() != np {
        return Err(Error::invalid(
            "frame",
            format!("has {} forces for {np} points", frame.forces.len()),
        ));
    }
    let n = set.floor_normal;
    let (t1, t2) = set.floor_tangents();
    let origin = n * set.floor_height;
    let local = |v: &Vec3| Vec3::new(v.dot(&t1), v.dot(&n), v.dot(&t2));
    for (g, w) in out.iter_mut().enumerate() {
        let (mut force, mut moment, mut centroid, mut count) =
            (Vec3::zeros(), Vec3::zeros(), Vec3::zeros(), 0.0_f64);
        for p in (0..np).filter(|&p| set.group_of(p) == g) {
            let r = frame.points[p] - origin;
            force += frame.forces[p];
            moment += r.cross(&frame.forces[p]);
            centroid += r - n * r.dot(&n);
            count += 1.0;
        }
        let (f, m) = (local(&force), local(&moment));
        *w = if f.y > UNLOADED_NEWTON {
            let (x, z) = (m.z / f.y, -m.x / f.y);
            GroupWrench {
                force,
                cop: origin + t1 * x + t2 * z,
                free_moment: m.y - z * f.x + x * f.z,
                loaded: true,
            }
        } else {
            GroupWrench {
                force,
                cop: origin + centroid / count.max(1.0),
                free_moment: 0.0,
                loaded: false,
            }
        };
    }
    Ok(())
}

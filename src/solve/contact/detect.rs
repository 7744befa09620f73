//! Contact detection over a whole clip.
//!
//! For every frame t and point p, with n the floor normal, c the sphere centre and r its
//! radius, the point's lowest point b = c − r n has
//!   height  h = n·b − h_floor,      speed  s = ‖v_b − v_floor‖
//! (v_b the velocity of the body-fixed point at b). The floor height h_floor is given or the
//! `floor_percentile` of all h; the floor velocity is given (0 for still ground, the belt for a
//! treadmill) or the median tangential velocity of the low points.
//!
//! Contact state with hysteresis: off → on when h ≤ h_on and s ≤ s_on; on → off when h > h_off
//! or s > s_off. While on, the factor is
//!   φ = S((h_off − h)/(h_off − h_full)) · S((s_off − s)/(s_off − s_on)) · ramp_in · ramp_out,
//! S the smoothstep, ramp_in = S(time since the contact began / T_tr) and ramp_out =
//! S(time until it ends / T_tr) (no ramp at the clip's ends): φ rises from 0 and falls back to 0
//! within the contact, so the distribution's weights 1/φ move load smoothly between points.

use super::{ContactOptions, ContactSet, smoothstep};
use crate::dynamics::{Data, forward_kinematics_velocity};
use crate::error::Error;
use crate::model::Model;
use crate::spatial::Vec3;

/// Contact over a clip of T frames and P points (arrays frame-major, T × P).
#[derive(Clone, Debug)]
pub struct ContactStates {
    pub frames: usize,
    pub points: usize,
    /// Contact factor in [0, 1] (1 = fully in contact).
    pub factor: Vec<f64>,
    /// The hysteresis state (in contact or not).
    pub in_contact: Vec<bool>,
    /// Height of each point's lowest point above the floor (m).
    pub height: Vec<f64>,
    /// Speed of each point's lowest point relative to the floor (m/s).
    pub speed: Vec<f64>,
    /// The floor height used (given or estimated), along the floor normal.
    pub floor: f64,
    /// The floor velocity used (given or estimated).
    pub floor_velocity: Vec3,
}

impl ContactStates {
    /// The P factors of frame `t`.
    pub fn frame(&self, t: usize) -> &[f64] {
        &self.factor[t * self.points..(t + 1) * self.points]
    }
}

/// Checks a frame-major T × nq array: length a multiple of nq, every value finite.
fn check_frames(model: &Model, argument: &'static str, x: &[f64], nq: usize) -> crate::Result<()> {
    if nq == 0 || x.is_empty() || !x.len().is_multiple_of(nq) {
        return Err(Error::invalid(
            argument,
            format!(
                "length {} is not a positive multiple of nq = {nq} (T × nq, frame-major)",
                x.len()
            ),
        ));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        let names = model.q_names();
        return Err(Error::invalid(
            argument,
            format!(
                "frame {}, coordinate \"{}\": {} is not finite",
                i / nq,
                names[i % nq],
                x[i]
            ),
        ));
    }
    Ok(())
}

/// The `percentile` (0–100) of `values` by linear interpolation (sorts `values`).
fn percentile(values: &mut [f64], percentile: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let pos = percentile / 100.0 * (values.len() - 1) as f64;
    let (i, frac) = (pos.floor() as usize, pos - pos.floor());
    if i + 1 < values.len() {
        values[i] + frac * (values[i + 1] - values[i])
    } else {
        values[i]
    }
}

/// Detects contact over a clip: `q` and `qd` are T × nq, frame-major, sampled at `rate_hz`.
/// The returned [`ContactStates::floor`] is the floor used; pass it on with
/// [`ContactSet::with_floor`] so that [`super::ground_reaction`] puts the centre of pressure
/// on it. Errors name the argument (and frame and coordinate for non-finite values).
pub fn detect(
    model: &Model,
    set: &ContactSet,
    options: &ContactOptions,
    q: &[f64],
    qd: &[f64],
    rate_hz: f64,
) -> crate::Result<ContactStates> {
    options.validate()?;
    if !(rate_hz > 0.0 && rate_hz.is_finite()) {
        return Err(Error::invalid(
            "rate_hz",
            format!("{rate_hz}: must be positive"),
        ));
    }
    let nq = model.nq();
    check_frames(model, "q", q, nq)?;
    if qd.len() != q.len() {
        return Err(Error::invalid(
            "qd",
            format!("length {} differs from q's {}", qd.len(), q.len()),
        ));
    }
    check_frames(model, "qd", qd, nq)?;
    let frames = q.len() / nq;
    let np = set.points.len();
    let n = set.floor_normal;
    let (t1, t2) = set.floor_tangents();

    // Heights (not yet relative to the floor) and velocities of the lowest points.
    let mut data = Data::new(model);
    let mut height = vec![0.0; frames * np];
    let mut velocity = vec![Vec3::zeros(); frames * np];
    for t in 0..frames {
        let rows = t * nq..(t + 1) * nq;
        forward_kinematics_velocity(model, &mut data, &q[rows.clone()], &qd[rows])?;
        for (p, point) in set.points.iter().enumerate() {
            let (rot, _) = data.body_pose(point.body);
            // b = c − r n, as a point of the body
            let bottom = point.location_in_body - rot.transpose() * n * point.radius;
            height[t * np + p] = n.dot(&data.point_position(point.body, &bottom));
            velocity[t * np + p] = data.point_velocity(point.body, &bottom);
        }
    }
    let floor = match options.floor_height {
        Some(h) => h,
        None => percentile(&mut height.clone(), options.floor_percentile),
    };
    height.iter_mut().for_each(|h| *h -= floor);
    let floor_velocity = match options.floor_velocity {
        Some(v) => v,
        None => {
            let low: Vec<usize> = (0..frames * np)
                .filter(|&i| height[i] <= options.height_on)
                .collect();
            if low.is_empty() {
                Vec3::zeros()
            } else {
                let mut a: Vec<f64> = low.iter().map(|&i| t1.dot(&velocity[i])).collect();
                let mut b: Vec<f64> = low.iter().map(|&i| t2.dot(&velocity[i])).collect();
                t1 * percentile(&mut a, 50.0) + t2 * percentile(&mut b, 50.0)
            }
        }
    };
    let speed: Vec<f64> = velocity
        .iter()
        .map(|v| (v - floor_velocity).norm())
        .collect();

    // Hysteresis, then the factor.
    let o = options;
    let mut in_contact = vec![false; frames * np];
    let mut factor = vec![0.0; frames * np];
    let dt = 1.0 / rate_hz;
    for p in 0..np {
        let mut on = false;
        for t in 0..frames {
            let i = t * np + p;
            let (h, s) = (height[i], speed[i]);
            on = if on {
                h <= o.height_off && s <= o.speed_off
            } else {
                h <= o.height_on && s <= o.speed_on
            };
            in_contact[i] = on;
            if on {
                factor[i] = smoothstep((o.height_off - h) / (o.height_off - o.height_full))
                    * smoothstep((o.speed_off - s) / (o.speed_off - o.speed_on));
            }
        }
        // ramps at the contact intervals' ends (not at the clip's ends)
        if o.transition_time > 0.0 {
            let mut t = 0;
            while t < frames {
                if !in_contact[t * np + p] {
                    t += 1;
                    continue;
                }
                let start = t;
                while t < frames && in_contact[t * np + p] {
                    t += 1;
                }
                let end = t; // exclusive
                for k in start..end {
                    let mut ramp = 1.0;
                    if start > 0 {
                        ramp *= smoothstep((k - start + 1) as f64 * dt / o.transition_time);
                    }
                    if end < frames {
                        ramp *= smoothstep((end - k) as f64 * dt / o.transition_time);
                    }
                    factor[k * np + p] *= ramp;
                }
            }
        }
    }
    Ok(ContactStates {
        frames,
        points: np,
        factor,
        in_contact,
        height,
        speed,
        floor,
        floor_velocity,
    })
}

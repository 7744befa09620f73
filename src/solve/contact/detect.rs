//! Contact detection over a whole clip: a hidden-Markov decision over the contact states of
//! the groups (feet, hands), from the kinematics of every point and from what the dynamics
//! demand, decided by one Viterbi pass over all frames.
//!
//! **Kinematic evidence.** For every frame t and point p, with n the floor normal, c the sphere
//! centre and r its radius, the point's lowest point b = c − r n has
//!   height  h = n·b − h_floor,      speed  s = ‖v_b − v_floor‖
//! (v_b the velocity of the body-fixed point at b). The floor height h_floor is given or the
//! `floor_percentile` of all h. Each point rests at its own level μ_p in stance — a fitted
//! foot is seldom exactly flat (a foot pitched by a few degrees lifts its heel centimetres) —
//! taken as the `floor_percentile` of its own heights, at most `max_point_offset` above the
//! floor. With e_p = ½[((h − μ_p)⁺/σ_h)² + (s/σ_s)²] (σ_h = `height_scale`, σ_s =
//! `speed_scale`) the point's contact likelihood is ℓ_p = exp(−e_p) and a group's (a foot
//! touches when any of its points does) ℓ_g = max_p ℓ_p; a group in contact costs −ln ℓ_g, a
//! group in the air −ln(1 − ℓ_g) (capped at [`COST_CAP`]).
//!
//! **The floor's motion.** A treadmill belt moves the stance feet backward at its speed. The
//! velocity v̂ is the median tangential velocity of the points within σ_h of their level; it is
//! the floor's velocity when it is at least `belt_speed_min` (a still floor leaves stance feet
//! still within IK's noise), else the floor is still. A given velocity or a forced treadmill
//! (`floor_velocity`, `floor_motion`) overrides the decision.
//!
//! **Dynamic evidence.** The ground must supply F = Σ_b m_b (a_b − g) (a_b the acceleration of
//! body b's centre of mass). Its normal component relative to the body weight,
//! d = n·F / (M ‖g‖), says whether any contact is needed: with no group in contact the
//! unexplained support costs ½(d⁺/σ_d)², with some group in contact a pull the floor cannot
//! give costs ½(d⁻/σ_d)² (σ_d = `demand_scale`; fading to zero over `end_time` at the clip's
//! ends, where the accelerations rest on the filter's end conditions). A running flight phase (d < 0) thus has no
//! contact however low the feet, and support (d > 0) goes to the foot the kinematics favour.
//!
//! **Balance.** The ground must also supply the moment
//!   M_o = Σ_b [(c_b − o) × m_b (a_b − g) + I_b α_b + ω_b × I_b ω_b]
//! about a point o of the floor (c_b, ω_b, α_b body b's centre of mass, angular velocity and
//! angular acceleration, I_b its inertia in ground), so its force passes through the centre
//! of pressure p = o + (M_o·t₂ / F·n) t₁ − (M_o·t₁ / F·n) t₂ (floor tangents t₁, t₂ = t₁ × n;
//! see [`super::ground_reaction`]). A state whose groups' points span a floor region (the
//! convex hull of their lowest points' projections) at a distance e from p cannot give that
//! moment: it costs ½(d⁺ e / σ_b)² (σ_b = `balance_scale`, faded at the ends as the demand
//! is). No contact gives no moment either: it is charged the cost of all groups together. A foot landing while the other pushes off is thus in double support when the
//! centre of pressure lies between the feet, even where the trailing foot already moves.
//!
//! **Decision.** The states are the 2^G subsets of the G groups in contact; the cost of a
//! state is the sum of its groups' kinematic costs and its dynamic cost; a group changing
//! state between frames costs ln(rate / `transition_rate`) (the negative log-probability of a
//! change in one frame at `transition_rate` changes per second). Viterbi gives the sequence
//! of least total cost over the clip.
//!
//! **Factors.** Within a group in contact each point's factor is ℓ_p / max_q ℓ_q over the
//! group's points (the best-placed point 1; factors below [`FACTOR_MIN`] are 0), so the foot
//! rolls from heel to toe. Where a group's contact overlaps another group's at its start or
//! end (double support), the factor ramps in (or out) with a smoothstep over the overlap,
//! at most `transition_time`: load passes from the trailing to the leading foot across the
//! double support, and a running step with no overlap carries its load from the first frame.

use super::{ContactOptions, ContactSet, FloorMotion, smoothstep};
use crate::dynamics::{Data, forward_kinematics_acceleration};
use crate::error::Error;
use crate::model::Model;
use crate::spatial::Vec3;

/// Largest cost of a group in the air (nats): a foot resting on the floor may still carry
/// nothing, and a likelihood of contact within e^−14 ≈ 1e-6 of 1 says no more than that.
pub const COST_CAP: f64 = 14.0;

/// Point factors below this are zero (the point takes no load).
pub const FACTOR_MIN: f64 = 1e-3;

/// Groups above which the joint states (2^G) are not enumerated: each group is then decided
/// on its own, with the dynamic evidence shared out as if the others were in the air.
pub const MAX_JOINT_GROUPS: usize = 6;

/// Contact over a clip of T frames and P points (arrays frame-major, T × P).
#[derive(Clone, Debug)]
pub struct ContactStates {
    pub frames: usize,
    pub points: usize,
    /// Contact factor in [0, 1] (1 = fully in contact).
    pub factor: Vec<f64>,
    /// Whether each point takes load (its group in contact and its factor above zero).
    pub in_contact: Vec<bool>,
    /// Height of each point's lowest point above the floor (m).
    pub height: Vec<f64>,
    /// Speed of each point's lowest point relative to the floor (m/s).
    pub speed: Vec<f64>,
    /// The floor height used (given or estimated), along the floor normal.
    pub floor: f64,
    /// The floor velocity used (given, estimated belt, or zero).
    pub floor_velocity: Vec3,
    /// Whether the floor moves (a treadmill): given, or detected from the stance feet.
    pub treadmill: bool,
    /// The ground's normal force the motion needs, relative to body weight, per frame
    /// (n·Σ m_b (a_b − g) / (M ‖g‖); 1 standing still, 0 in flight).
    pub demand: Vec<f64>,
    /// Each group's contact state per frame (T × G, the set's group order).
    pub group_contact: Vec<bool>,
}

impl ContactStates {
    /// The P factors of frame `t`.
    pub fn frame(&self, t: usize) -> &[f64] {
        &self.factor[t * self.points..(t + 1) * self.points]
    }

    /// Frames in which group `g` is in contact.
    pub fn group_frames(&self, g: usize) -> usize {
        let groups = self.group_contact.len() / self.frames.max(1);
        (0..self.frames)
            .filter(|&t| self.group_contact[t * groups + g])
            .count()
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

/// −ln x, capped at [`COST_CAP`].
fn cost(x: f64) -> f64 {
    if x <= (-COST_CAP).exp() {
        COST_CAP
    } else {
        -x.ln()
    }
}

/// Detects contact over a clip: `q`, `qd` and `qdd` are T × nq, frame-major, sampled at
/// `rate_hz`. The returned [`ContactStates::floor`] is the floor used; pass it on with
/// [`ContactSet::with_floor`] so that [`super::ground_reaction`] puts the centre of pressure
/// on it. Errors name the argument (and frame and coordinate for non-finite values).
pub fn detect(
    model: &Model,
    set: &ContactSet,
    options: &ContactOptions,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    rate_hz: f64,
) -> crate::Result<ContactStates> {
    let states = ClipStates { q, qd, qdd };
    check_inputs(model, options, &states, rate_hz)?;
    let frames = q.len() / model.nq();
    let np = set.points.len();
    let o = options;
    let Kinematics {
        mut height,
        position,
        velocity,
        demand,
        force,
        moment,
    } = lowest_points_and_demand(model, set, &states)?;
    let floor = match o.floor_height {
        Some(h) => h,
        None => percentile(&mut height.clone(), o.floor_percentile),
    };
    height.iter_mut().for_each(|h| *h -= floor);
    let above = above_levels(&height, frames, np, o);
    let (floor_velocity, treadmill) = floor_velocity(set, o, &above, &velocity);
    let speed: Vec<f64> = velocity
        .iter()
        .map(|v| (v - floor_velocity).norm())
        .collect();
    // e_p per frame and point
    let energy: Vec<f64> = (0..frames * np)
        .map(|i| 0.5 * ((above[i] / o.height_scale).powi(2) + (speed[i] / o.speed_scale).powi(2)))
        .collect();
    let balance = Balance::new(set, floor, &position, &force, &moment);
    let group_contact = decide_groups(set, o, &energy, &demand, &balance, rate_hz);
    // factors within each group in contact, then the double-support ramps
    let mut factor = group_factors(set, &energy, &group_contact, frames);
    let longest = ((o.transition_time * rate_hz).round() as usize).max(1);
    ramp_double_supports(&mut factor, set, &group_contact, frames, longest);
    let in_contact = factor.iter().map(|&f| f > 0.0).collect();
    Ok(ContactStates {
        frames,
        points: np,
        factor,
        in_contact,
        height,
        speed,
        floor,
        floor_velocity,
        treadmill,
        demand,
        group_contact,
    })
}

/// The clip's coordinates, velocities and accelerations (T × nq each, frame-major).
struct ClipStates<'a> {
    q: &'a [f64],
    qd: &'a [f64],
    qdd: &'a [f64],
}

/// Checks the options, the rate and the three T × nq arrays.
fn check_inputs(
    model: &Model,
    options: &ContactOptions,
    states: &ClipStates,
    rate_hz: f64,
) -> crate::Result<()> {
    options.validate()?;
    if !(rate_hz > 0.0 && rate_hz.is_finite()) {
        return Err(Error::invalid(
            "rate_hz",
            format!("{rate_hz}: must be positive"),
        ));
    }
    let nq = model.nq();
    let q = states.q;
    check_frames(model, "q", q, nq)?;
    for (name, x) in [("qd", states.qd), ("qdd", states.qdd)] {
        if x.len() != q.len() {
            return Err(Error::invalid(
                name,
                format!("length {} differs from q's {}", x.len(), q.len()),
            ));
        }
    }
    check_frames(model, "qd", states.qd, nq)?;
    check_frames(model, "qdd", states.qdd, nq)
}

/// The kinematic and dynamic evidence of [`lowest_points_and_demand`].
struct Kinematics {
    height: Vec<f64>,
    /// The lowest points, T × P.
    position: Vec<Vec3>,
    velocity: Vec<Vec3>,
    demand: Vec<f64>,
    /// Per frame the ground's force Σ m_b (a_b − g) and its moment about ground's origin
    /// (the balance section of the module documentation), both over M ‖g‖.
    force: Vec<Vec3>,
    moment: Vec<Vec3>,
}

/// Per frame and point (T × P): the height n·b of the lowest point b = c − r n (not yet
/// relative to the floor) and its velocity; per frame, the normal force the motion needs
/// relative to body weight, n·Σ m_b (a_b − g) / (M ‖g‖).
fn lowest_points_and_demand(
    model: &Model,
    set: &ContactSet,
    states: &ClipStates,
) -> crate::Result<Kinematics> {
    let nq = model.nq();
    let frames = states.q.len() / nq;
    let np = set.points.len();
    let n = set.floor_normal;
    let mut data = Data::new(model);
    let mut height = vec![0.0; frames * np];
    let mut position = vec![Vec3::zeros(); frames * np];
    let mut velocity = vec![Vec3::zeros(); frames * np];
    let mut demand = vec![0.0; frames];
    let mut forces = vec![Vec3::zeros(); frames];
    let mut moments = vec![Vec3::zeros(); frames];
    let mass: f64 = model.bodies.iter().map(|b| b.mass).sum();
    let weight = mass * model.gravity.norm();
    for t in 0..frames {
        let rows = t * nq..(t + 1) * nq;
        forward_kinematics_acceleration(
            model,
            &mut data,
            &states.q[rows.clone()],
            &states.qd[rows.clone()],
            &states.qdd[rows],
        )?;
        for (p, point) in set.points.iter().enumerate() {
            let (rot, _) = data.body_pose(point.body);
            // b = c − r n, as a point of the body
            let bottom = point.location_in_body - rot.transpose() * n * point.radius;
            position[t * np + p] = data.point_position(point.body, &bottom);
            height[t * np + p] = n.dot(&position[t * np + p]);
            velocity[t * np + p] = data.point_velocity(point.body, &bottom);
        }
        if weight > 0.0 {
            let (mut force, mut moment) = (Vec3::zeros(), Vec3::zeros());
            for (b, body) in model.bodies.iter().enumerate() {
                if body.mass > 0.0 {
                    let (alpha, a) = data.point_acceleration(b, &body.com_in_body);
                    let (omega, _) = data.body_velocity(b);
                    let (rot, _) = data.body_pose(b);
                    let inertia = rot * body.inertia_about_com * rot.transpose();
                    let f = body.mass * (a - model.gravity);
                    force += f;
                    moment += data.point_position(b, &body.com_in_body).cross(&f)
                        + inertia * alpha
                        + omega.cross(&(inertia * omega));
                }
            }
            demand[t] = n.dot(&force) / weight;
            forces[t] = force / weight;
            moments[t] = moment / weight;
        }
    }
    Ok(Kinematics {
        height,
        position,
        velocity,
        demand,
        force: forces,
        moment: moments,
    })
}

/// The balance evidence in floor coordinates (along t₁, t₂): per frame the centre of pressure
/// the motion needs (None where it needs no normal force), per frame and point the lowest
/// point's projection.
struct Balance {
    points: usize,
    foot: Vec<[f64; 2]>,
    cop: Vec<Option<[f64; 2]>>,
}

impl Balance {
    fn new(
        set: &ContactSet,
        floor: f64,
        position: &[Vec3],
        force: &[Vec3],
        moment: &[Vec3],
    ) -> Balance {
        let n = set.floor_normal;
        let (t1, t2) = set.floor_tangents();
        let origin = n * floor;
        let cop = force
            .iter()
            .zip(moment)
            .map(|(f, m)| {
                let normal = n.dot(f);
                // the moment about o, then x = M_o·t₂ / F·n, z = −M_o·t₁ / F·n
                let m = m - origin.cross(f);
                (normal > 0.0).then(|| [m.dot(&t2) / normal, -m.dot(&t1) / normal])
            })
            .collect();
        Balance {
            points: set.points.len(),
            foot: position.iter().map(|p| [p.dot(&t1), p.dot(&t2)]).collect(),
            cop,
        }
    }

    /// Per frame and joint state (T × 2^G, bit g for group g): the distance (m) from the
    /// frame's centre of pressure to the convex hull of the state's points; 0 without a
    /// centre of pressure or points.
    fn distances(&self, set: &ContactSet) -> Vec<f64> {
        let np = self.points;
        let ns = 1usize << set.groups().len();
        let (mut support, mut hull) = (Vec::with_capacity(np), Vec::with_capacity(2 * np));
        let mut out = vec![0.0; self.cop.len() * ns];
        for (t, cop) in self.cop.iter().enumerate() {
            let Some(cop) = *cop else { continue };
            for state in 1..ns {
                support.clear();
                support.extend(
                    (0..np)
                        .filter(|&p| state & (1 << set.group_of(p)) != 0)
                        .map(|p| self.foot[t * np + p]),
                );
                out[t * ns + state] = distance_to_hull(cop, &mut support, &mut hull);
            }
        }
        out
    }
}

/// Distance from `p` to the convex hull of `points` (0 inside; 0 for no points; `points` is
/// sorted and deduplicated, `hull` is scratch). The hull by Andrew's monotone chain,
/// counter-clockwise; outside, the nearest of its edges (or its one point).
fn distance_to_hull(p: [f64; 2], points: &mut Vec<[f64; 2]>, hull: &mut Vec<[f64; 2]>) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    // (b − a) × (c − a): positive for a left turn
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    hull.clear();
    for pass in 0..2 {
        let start = hull.len();
        for i in 0..points.len() {
            let q = points[if pass == 0 { i } else { points.len() - 1 - i }];
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    if hull.is_empty() {
        hull.push(points[0]);
    }
    let m = hull.len();
    let edge_distance = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let s = if len2 > 0.0 {
            (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p[0] - a[0] - s * dx).hypot(p[1] - a[1] - s * dy)
    };
    if m >= 3 && (0..m).all(|i| cross(hull[i], hull[(i + 1) % m], p) >= 0.0) {
        return 0.0;
    }
    (0..m)
        .map(|i| edge_distance(hull[i], hull[(i + 1) % m]))
        .fold(f64::INFINITY, f64::min)
}

/// (h − μ_p)⁺ per frame and point (T × P), μ_p each point's resting level: the
/// `floor_percentile` of its own heights above the floor, at most `max_point_offset`.
fn above_levels(height: &[f64], frames: usize, np: usize, o: &ContactOptions) -> Vec<f64> {
    let level: Vec<f64> = (0..np)
        .map(|p| {
            let mut own: Vec<f64> = (0..frames).map(|t| height[t * np + p]).collect();
            percentile(&mut own, o.floor_percentile).min(o.max_point_offset)
        })
        .collect();
    (0..frames * np)
        .map(|i| (height[i] - level[i % np]).max(0.0))
        .collect()
}

/// The floor's velocity and whether it moves: given, or the stance points' median tangential
/// velocity (the points within σ_h of their level), kept when at least `belt_speed_min` or
/// when a treadmill is forced.
fn floor_velocity(
    set: &ContactSet,
    o: &ContactOptions,
    above: &[f64],
    velocity: &[Vec3],
) -> (Vec3, bool) {
    let (t1, t2) = set.floor_tangents();
    let motion = match (o.floor_velocity, o.floor_motion) {
        (Some(v), _) => return (v, v.norm() > 0.0),
        (None, motion) => motion,
    };
    let low: Vec<usize> = (0..above.len())
        .filter(|&i| above[i] <= o.height_scale)
        .collect();
    let estimate = if low.is_empty() {
        Vec3::zeros()
    } else {
        let mut a: Vec<f64> = low.iter().map(|&i| t1.dot(&velocity[i])).collect();
        let mut b: Vec<f64> = low.iter().map(|&i| t2.dot(&velocity[i])).collect();
        t1 * percentile(&mut a, 50.0) + t2 * percentile(&mut b, 50.0)
    };
    match motion {
        FloorMotion::Detect if estimate.norm() >= o.belt_speed_min => (estimate, true),
        FloorMotion::Detect => (Vec3::zeros(), false),
        FloorMotion::Treadmill { speed: None } => (estimate, true),
        FloorMotion::Treadmill { speed: Some(s) } => {
            // the given speed along the estimated direction of the belt
            let direction = if estimate.norm() > 0.0 {
                estimate.normalize()
            } else {
                -t1
            };
            (direction * s, true)
        }
    }
}

/// Each group's contact state per frame (T × G): the group costs in contact (min_p e_p) and in
/// the air (−ln(1 − ℓ_g)), the dynamic cost, and Viterbi over the clip.
fn decide_groups(
    set: &ContactSet,
    o: &ContactOptions,
    energy: &[f64],
    demand: &[f64],
    balance: &Balance,
    rate_hz: f64,
) -> Vec<bool> {
    let frames = demand.len();
    let np = set.points.len();
    let ng = set.groups().len();
    // group costs in contact / in the air, T × G
    let mut cost_on = vec![COST_CAP; frames * ng];
    let mut cost_off = vec![0.0; frames * ng];
    for t in 0..frames {
        for g in 0..ng {
            let best = (0..np)
                .filter(|&p| set.group_of(p) == g)
                .map(|p| energy[t * np + p])
                .fold(f64::INFINITY, f64::min);
            cost_on[t * ng + g] = best;
            cost_off[t * ng + g] = cost(1.0 - (-best).exp());
        }
    }
    // the accelerations of the first and last frames rest on the filter's and splines' end
    // conditions: their evidence fades out towards the clip's ends over `end_time`
    let end_frames = o.end_time * rate_hz;
    let trust = |t: usize| {
        let from_end = t.min(frames - 1 - t) as f64;
        if end_frames > 0.0 {
            smoothstep(from_end / end_frames)
        } else {
            1.0
        }
    };
    let dynamic = |t: usize, any: bool| {
        let d = demand[t];
        let unexplained = if any { (-d).max(0.0) } else { d.max(0.0) };
        trust(t) * 0.5 * (unexplained / o.demand_scale).powi(2)
    };
    let switch = (rate_hz / o.transition_rate).ln().max(0.0);
    if ng <= MAX_JOINT_GROUPS {
        // the support demand and the balance the state cannot give; no contact gives no
        // moment either, and is charged what the whole support leaves (so that balance never
        // argues for flight: that is the demand's to say)
        let (all, ns) = ((1usize << ng) - 1, 1usize << ng);
        let distance = balance.distances(set);
        let joint = |t: usize, state: usize| {
            let support = if state == 0 { all } else { state };
            let unbalanced = demand[t].max(0.0) * distance[t * ns + support];
            dynamic(t, state != 0) + trust(t) * 0.5 * (unbalanced / o.balance_scale).powi(2)
        };
        viterbi_joint(frames, ng, &cost_on, &cost_off, &joint, switch)
    } else {
        viterbi_separate(frames, ng, &cost_on, &cost_off, &dynamic, switch)
    }
}

/// The point factors (T × P) within each group in contact: ℓ_p / max_q ℓ_q over the group's
/// points, zero below [`FACTOR_MIN`].
fn group_factors(
    set: &ContactSet,
    energy: &[f64],
    group_contact: &[bool],
    frames: usize,
) -> Vec<f64> {
    let np = set.points.len();
    let ng = set.groups().len();
    let mut factor = vec![0.0; frames * np];
    for t in 0..frames {
        for g in 0..ng {
            if !group_contact[t * ng + g] {
                continue;
            }
            let points = (0..np).filter(|&p| set.group_of(p) == g);
            let best = points
                .clone()
                .map(|p| energy[t * np + p])
                .fold(f64::INFINITY, f64::min);
            for p in points {
                let f = (best - energy[t * np + p]).exp();
                factor[t * np + p] = if f >= FACTOR_MIN { f } else { 0.0 };
            }
        }
    }
    factor
}

/// Ramps each contact's factors in and out with a smoothstep over its double supports (at
/// most `longest` frames), so that load passes from the trailing to the leading group.
fn ramp_double_supports(
    factor: &mut [f64],
    set: &ContactSet,
    group_contact: &[bool],
    frames: usize,
    longest: usize,
) {
    let np = set.points.len();
    let ng = set.groups().len();
    let others = |t: usize, g: usize| (0..ng).any(|k| k != g && group_contact[t * ng + k]);
    let intervals = contact_intervals(group_contact, frames, ng);
    let typical = typical_transfer(&intervals, &others, longest);
    for &(g, start, end) in &intervals {
        // the overlap at the interval's start: another group in contact before it began
        // (a transfer onto this group), or at the clip's first frame with this group
        // outlasting the others (a transfer cut by the clip's start, placed to end where
        // the others leave)
        let head = (start..end).take_while(|&k| others(k, g)).count();
        let ramp_in: Option<(f64, f64)> = if start > 0 && others(start - 1, g) {
            let cut = start + head == frames;
            let len = if cut { typical } else { head.min(longest) };
            Some((start as f64 - 1.0, len as f64))
        } else if start == 0 && head > 0 && head < end {
            Some((head as f64 - typical as f64 - 1.0, typical as f64))
        } else {
            None
        };
        // the overlap at its end, likewise (a transfer away from this group)
        let tail = (start..end).rev().take_while(|&k| others(k, g)).count();
        let ramp_out: Option<(f64, f64)> = if end < frames && others(end, g) {
            let cut = end - tail == 0;
            let len = if cut { typical } else { tail.min(longest) };
            Some((end as f64, len as f64))
        } else if end == frames && tail > 0 && end - tail > start {
            Some(((end - tail + typical) as f64, typical as f64))
        } else {
            None
        };
        for k in start..end {
            let x = k as f64;
            let mut ramp = 1.0;
            if let Some((before, len)) = ramp_in {
                ramp *= smoothstep((x - before) / (len + 1.0));
            }
            if let Some((after, len)) = ramp_out {
                ramp *= smoothstep((after - x) / (len + 1.0));
            }
            for p in (0..np).filter(|&p| set.group_of(p) == g) {
                factor[k * np + p] *= ramp;
            }
        }
    }
}

/// The clip's own transfer time (frames): the median length of the double supports the clip
/// shows whole (a group's contact begins while another's goes on, and that one ends within
/// it), at most `longest`; used where the clip's start or end cuts one.
fn typical_transfer(
    intervals: &[(usize, usize, usize)],
    others: &dyn Fn(usize, usize) -> bool,
    longest: usize,
) -> usize {
    let mut whole: Vec<usize> = Vec::new();
    for &(g, start, end) in intervals {
        if start > 0 && others(start - 1, g) {
            let overlap = (start..end).take_while(|&k| others(k, g)).count();
            if start + overlap < end {
                whole.push(overlap);
            }
        }
    }
    whole.sort_unstable();
    whole
        .get(whole.len() / 2)
        .copied()
        .unwrap_or(longest)
        .min(longest)
}

/// The contact intervals (group, first frame, end frame exclusive) of a T × G state array.
fn contact_intervals(contact: &[bool], frames: usize, ng: usize) -> Vec<(usize, usize, usize)> {
    let mut out = Vec::new();
    for g in 0..ng {
        let mut t = 0;
        while t < frames {
            if !contact[t * ng + g] {
                t += 1;
                continue;
            }
            let start = t;
            while t < frames && contact[t * ng + g] {
                t += 1;
            }
            out.push((g, start, t));
        }
    }
    out
}

/// Viterbi over the 2^G subsets of groups in contact (bit g set: group g in contact);
/// `dynamic(t, state)` is the dynamic cost of a state.
fn viterbi_joint(
    frames: usize,
    ng: usize,
    cost_on: &[f64],
    cost_off: &[f64],
    dynamic: &dyn Fn(usize, usize) -> f64,
    switch: f64,
) -> Vec<bool> {
    let ns = 1usize << ng;
    let state_cost = |t: usize, s: usize| {
        let mut c = dynamic(t, s);
        for g in 0..ng {
            c += if s & (1 << g) != 0 {
                cost_on[t * ng + g]
            } else {
                cost_off[t * ng + g]
            };
        }
        c
    };
    let mut total: Vec<f64> = (0..ns).map(|s| state_cost(0, s)).collect();
    let mut back = vec![0u32; frames * ns];
    let mut next = vec![0.0; ns];
    for t in 1..frames {
        for s in 0..ns {
            let (mut best, mut from) = (f64::INFINITY, 0);
            for (r, &c) in total.iter().enumerate() {
                let c = c + switch * (r ^ s).count_ones() as f64;
                if c < best {
                    (best, from) = (c, r);
                }
            }
            next[s] = best + state_cost(t, s);
            back[t * ns + s] = from as u32;
        }
        std::mem::swap(&mut total, &mut next);
    }
    let mut s = (0..ns)
        .min_by(|&a, &b| total[a].total_cmp(&total[b]))
        .unwrap_or(0);
    let mut out = vec![false; frames * ng];
    for t in (0..frames).rev() {
        for g in 0..ng {
            out[t * ng + g] = s & (1 << g) != 0;
        }
        s = back[t * ns + s] as usize;
    }
    out
}

/// Viterbi per group (two states each) for sets with many groups: the dynamic evidence of
/// "no contact" is charged to a group in the air as if all others were too.
fn viterbi_separate(
    frames: usize,
    ng: usize,
    cost_on: &[f64],
    cost_off: &[f64],
    dynamic: &dyn Fn(usize, bool) -> f64,
    switch: f64,
) -> Vec<bool> {
    let mut out = vec![false; frames * ng];
    for g in 0..ng {
        let c = |t: usize, on: bool| {
            if on {
                cost_on[t * ng + g] + dynamic(t, true) / ng as f64
            } else {
                cost_off[t * ng + g] + dynamic(t, false) / ng as f64
            }
        };
        let mut total = [c(0, false), c(0, true)];
        let mut back = vec![[0u8; 2]; frames];
        for t in 1..frames {
            let mut next = [0.0; 2];
            for s in 0..2 {
                let stay = total[s];
                let change = total[1 - s] + switch;
                let (best, from) = if stay <= change {
                    (stay, s)
                } else {
                    (change, 1 - s)
                };
                next[s] = best + c(t, s == 1);
                back[t][s] = from as u8;
            }
            total = next;
        }
        let mut s = usize::from(total[1] < total[0]);
        for t in (0..frames).rev() {
            out[t * ng + g] = s == 1;
            s = back[t][s] as usize;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::distance_to_hull;

    /// Distances to hulls worked out by hand: a unit square given with an interior point and
    /// a repeated corner, a segment and a single point.
    #[test]
    fn distance_to_hull_matches_the_geometry() {
        let distance = |p: [f64; 2], mut points: Vec<[f64; 2]>| {
            distance_to_hull(p, &mut points, &mut Vec::new())
        };
        let square = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.5, 0.5],
            [1.0, 1.0],
            [0.0, 1.0],
            [1.0, 1.0],
        ];
        let cases = [
            ([0.5, 0.5], 0.0),
            ([0.0, 0.3], 0.0),
            ([1.5, 0.5], 0.5),
            ([0.5, -2.0], 2.0),
            ([2.0, 2.0], 2.0f64.sqrt()),
            ([-3.0, -4.0], 5.0),
        ];
        for (p, d) in cases {
            assert!((distance(p, square.clone()) - d).abs() < 1e-12, "{p:?}");
        }
        let segment = vec![[0.0, 0.0], [2.0, 0.0], [1.0, 0.0]];
        assert!((distance([1.0, 0.5], segment.clone()) - 0.5).abs() < 1e-12);
        assert!((distance([3.0, 0.0], segment.clone()) - 1.0).abs() < 1e-12);
        assert_eq!(distance([1.0, 0.0], segment), 0.0);
        assert!((distance([3.0, 4.0], vec![[0.0, 0.0]]) - 5.0).abs() < 1e-12);
        assert_eq!(distance([3.0, 4.0], Vec::new()), 0.0);
    }
}

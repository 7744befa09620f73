//! Wrapping of a straight path segment over a wrap surface (sphere, cylinder, ellipsoid,
//! torus), as OpenSim defines it. (In progress: temporary interface, no wrapping yet.)

use crate::spatial::Vec3;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quadrant {
    All,
    Positive(usize),
    Negative(usize),
}

impl Quadrant {
    pub fn parse(s: &str) -> Result<Quadrant, String> {
        let t = s.trim().to_ascii_lowercase();
        let axis = |c: &str| match c {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        if t.is_empty() || t == "all" {
            return Ok(Quadrant::All);
        }
        let (neg, rest) = match t.strip_prefix('-') {
            Some(r) => (true, r),
            None => (false, t.strip_prefix('+').unwrap_or(&t)),
        };
        match axis(rest) {
            Some(a) if neg => Ok(Quadrant::Negative(a)),
            Some(a) => Ok(Quadrant::Positive(a)),
            None => Err(format!("unknown quadrant `{s}`")),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EllipsoidMethod {
    Hybrid,
    Midpoint,
    Axial,
}

impl EllipsoidMethod {
    pub fn parse(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "hybrid" | "" => Ok(EllipsoidMethod::Hybrid),
            "midpoint" => Ok(EllipsoidMethod::Midpoint),
            "axial" => Ok(EllipsoidMethod::Axial),
            _ => Err(format!("unknown wrap method `{s}`")),
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Wrapped {
    pub t1: Vec3,
    pub t2: Vec3,
    pub surface_length: f64,
    pub length: f64,
    pub mandatory: bool,
}

#[derive(Clone, Copy, Debug)]
pub enum WrapOutcome {
    NoWrap,
    InsideRadius,
    Wrapped(Wrapped),
}

pub fn wrap_sphere(_r: f64, _q: Quadrant, _p: &Vec3, _s: &Vec3) -> WrapOutcome {
    WrapOutcome::NoWrap
}
pub fn wrap_cylinder(_r: f64, _l: f64, _q: Quadrant, _p: &Vec3, _s: &Vec3) -> WrapOutcome {
    WrapOutcome::NoWrap
}
pub fn wrap_ellipsoid(
    _d: &Vec3,
    _q: Quadrant,
    _m: EllipsoidMethod,
    _p: &Vec3,
    _s: &Vec3,
) -> WrapOutcome {
    WrapOutcome::NoWrap
}
pub fn wrap_torus(_i: f64, _o: f64, _q: Quadrant, _p: &Vec3, _s: &Vec3) -> WrapOutcome {
    WrapOutcome::NoWrap
}

//! OpenSim component paths and physical frames: resolving a socket path such as
//! `/bodyset/pelvis`, `pelvis_offset` or `../../bodyset/femur_r` to a body and the pose of
//! the frame in that body.

use crate::spatial::Transform;
use std::collections::HashMap;

/// Joins a socket path to the path of the component that owns the socket, following
/// OpenSim's ComponentPath rules: an absolute path starts with `/`; otherwise each segment
/// descends from the owner, `..` climbs one level and `.` stays.
pub fn resolve_path(owner: &str, path: &str) -> String {
    let path = path.trim();
    let mut parts: Vec<&str> = if path.starts_with('/') {
        Vec::new()
    } else {
        owner.split('/').filter(|s| !s.is_empty()).collect()
    };
    for seg in path.split('/').filter(|s| !s.is_empty()) {
        match seg {
            "." => {}
            ".." => {
                parts.pop();
            }
            s => parts.push(s),
        }
    }
    format!("/{}", parts.join("/"))
}

/// A physical offset frame read from the file, not yet resolved to a body.
#[derive(Clone, Debug)]
pub struct OffsetFrameDef {
    /// Absolute path of the frame.
    pub path: String,
    /// Its `socket_parent`, as written.
    pub parent: String,
    /// Offset from the parent frame.
    pub offset: Transform,
}

/// The frames of a model: bodies (by absolute path) and offset frames.
#[derive(Default)]
pub struct FrameRegistry {
    bodies: HashMap<String, usize>,
    offsets: HashMap<String, OffsetFrameDef>,
    resolved: HashMap<String, (usize, Transform)>,
}

/// Why a frame path could not be resolved.
#[derive(Debug)]
pub enum FrameError {
    NotFound(String),
    Cycle(String),
    /// A bare name matched several frames.
    Ambiguous(String, Vec<String>),
}

impl std::fmt::Display for FrameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FrameError::NotFound(p) => write!(f, "no frame or body at path `{p}`"),
            FrameError::Cycle(p) => write!(f, "offset frames form a cycle through `{p}`"),
            FrameError::Ambiguous(p, c) => {
                write!(f, "`{p}` is ambiguous: it matches {}", c.join(", "))
            }
        }
    }
}

impl FrameRegistry {
    pub fn add_body(&mut self, path: String, body: usize) {
        self.bodies.insert(path, body);
    }

    /// Registers an offset frame; returns false if a frame already has this path.
    pub fn add_offset(&mut self, def: OffsetFrameDef) -> bool {
        if self.offsets.contains_key(&def.path) || self.bodies.contains_key(&def.path) {
            return false;
        }
        self.offsets.insert(def.path.clone(), def);
        true
    }

    /// Resolves the socket path `path` owned by the component at `owner` to
    /// (body, pose of the frame in that body). Falls back, for a bare name that is not found
    /// relative to the owner, to the unique frame or body with that name (how files written
    /// by older OpenSim versions name frames).
    pub fn resolve(&mut self, owner: &str, path: &str) -> Result<(usize, Transform), FrameError> {
        self.resolve_at_depth(owner, path, 0)
    }

    /// `resolve`, `depth` frames down a chain of offset frames (bounded, to report cycles).
    fn resolve_at_depth(
        &mut self,
        owner: &str,
        path: &str,
        depth: usize,
    ) -> Result<(usize, Transform), FrameError> {
        let abs = resolve_path(owner, path);
        match self.resolve_abs(&abs, depth) {
            // Only when the path itself is missing, not a frame further up its chain.
            Err(FrameError::NotFound(missing)) if missing == abs && !path.contains('/') => {
                let name = path.trim();
                let mut hits: Vec<String> = self
                    .bodies
                    .keys()
                    .chain(self.offsets.keys())
                    .filter(|p| p.rsplit('/').next() == Some(name))
                    .cloned()
                    .collect();
                hits.sort();
                hits.dedup();
                match hits.len() {
                    1 => self.resolve_abs(&hits[0], depth),
                    0 => Err(FrameError::NotFound(abs)),
                    _ => Err(FrameError::Ambiguous(name.to_string(), hits)),
                }
            }
            r => r,
        }
    }

    fn resolve_abs(&mut self, abs: &str, depth: usize) -> Result<(usize, Transform), FrameError> {
        if let Some(&b) = self.bodies.get(abs) {
            return Ok((b, Transform::identity()));
        }
        if let Some(r) = self.resolved.get(abs) {
            return Ok(*r);
        }
        if depth > 64 {
            return Err(FrameError::Cycle(abs.to_string()));
        }
        let def = self
            .offsets
            .get(abs)
            .cloned()
            .ok_or_else(|| FrameError::NotFound(abs.to_string()))?;
        let parent_abs = resolve_path(&def.path, &def.parent);
        let (body, x_parent) = match self.resolve_abs(&parent_abs, depth + 1) {
            Err(FrameError::NotFound(missing))
                if missing == parent_abs && !def.parent.contains('/') =>
            {
                // Legacy bare name.
                self.resolve_at_depth(&def.path, &def.parent, depth + 1)?
            }
            r => r?,
        };
        let r = (body, x_parent.compose(&def.offset));
        self.resolved.insert(abs.to_string(), r);
        Ok(r)
    }

    /// The path of a body (by its current index), for messages.
    pub fn body_path(&self, body: usize) -> Option<String> {
        self.bodies
            .iter()
            .find(|(_, b)| **b == body)
            .map(|(p, _)| p.clone())
    }

    /// Renumbers bodies after topological ordering: `new_index[old] = new`.
    pub fn renumber_bodies(&mut self, new_index: &[usize]) {
        for b in self.bodies.values_mut() {
            *b = new_index[*b];
        }
        for r in self.resolved.values_mut() {
            r.0 = new_index[r.0];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::Vec3;

    #[test]
    fn relative_paths_resolve_against_the_owner() {
        assert_eq!(
            resolve_path("/jointset/hip_r", "pelvis_offset"),
            "/jointset/hip_r/pelvis_offset"
        );
        assert_eq!(
            resolve_path("/jointset/hip_r/pelvis_offset", "../../../bodyset/pelvis"),
            "/bodyset/pelvis"
        );
        assert_eq!(
            resolve_path("/jointset/hip_r", "/bodyset/femur_r"),
            "/bodyset/femur_r"
        );
        assert_eq!(resolve_path("/a/b", "./c/../d"), "/a/b/d");
    }

    #[test]
    fn offset_chains_compose_and_cycles_are_reported() {
        let mut reg = FrameRegistry::default();
        reg.add_body("/bodyset/pelvis".into(), 1);
        let t = |x: f64| Transform::new(crate::spatial::Mat3::identity(), Vec3::new(x, 0.0, 0.0));
        reg.add_offset(OffsetFrameDef {
            path: "/jointset/j/a".into(),
            parent: "/bodyset/pelvis".into(),
            offset: t(1.0),
        });
        reg.add_offset(OffsetFrameDef {
            path: "/jointset/j/b".into(),
            parent: "a".into(),
            offset: t(2.0),
        });
        let (b, x) = reg.resolve("/jointset/j", "b").unwrap();
        assert_eq!(b, 1);
        assert_eq!(x.pos.x, 3.0);
        reg.add_offset(OffsetFrameDef {
            path: "/c1".into(),
            parent: "/c2".into(),
            offset: t(0.0),
        });
        reg.add_offset(OffsetFrameDef {
            path: "/c2".into(),
            parent: "/c1".into(),
            offset: t(0.0),
        });
        assert!(matches!(reg.resolve("/", "/c1"), Err(FrameError::Cycle(_))));
        assert!(matches!(
            reg.resolve("/", "/nothing"),
            Err(FrameError::NotFound(_))
        ));
    }
}

//! The OpenSim 4.x `.osim` reader: XML (roxmltree) → [`Model`].
//!
//! Everything in the file is either read, counted as display-only (meshes, appearance), or
//! reported: an unsupported element that would change the dynamics is an error; one that
//! musculo keeps but does not use is a named [`Warning`].

mod forces;
mod functions;
mod joints;
mod kinematic_range;
mod xml;

use self::functions::{function_child, parse_function};
use self::xml::{Ctx, XNode, child, elements, set_members};
use super::frames::{FrameRegistry, OffsetFrameDef, resolve_path};
use super::{Body, CoordinateRole, CouplerConstraint, Model, reduction::Reduction};
use crate::error::Error;
use crate::spatial::{Mat3, Transform, Vec3};
use roxmltree::Document;

/// Options for reading a model file.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// Refuse what OpenSim's release builds accept but no real body can have: principal
    /// moments of inertia that violate the triangle inequality (I₁ + I₂ ≥ I₃; two of
    /// OpenSim's tutorial models have such toes). Off by default: such a body is read, with
    /// a [`WarningKind::NonphysicalInertia`](super::WarningKind) warning naming it and its
    /// moments. The CLI's `--strict`.
    pub strict: bool,
}

/// Reads the OpenSim function elements (`NaturalCubicSpline`, `GCVSpline`, `Constant`, …)
/// of any OpenSim XML document with the model reader's rules, errors naming the file, the
/// line and the element path (used for ExternalLoads' `PrescribedForce`).
pub(crate) struct FunctionReader<'a, 'i> {
    ctx: Ctx<'a, 'i>,
}

impl<'a, 'i> FunctionReader<'a, 'i> {
    pub(crate) fn new(doc: &'a Document<'i>, file: &'a str) -> Self {
        FunctionReader {
            ctx: Ctx::new(doc, file),
        }
    }

    /// True for the tag of an OpenSim function class (read or named as unsupported).
    pub(crate) fn is_function(node: XNode) -> bool {
        functions::is_function_tag(node.tag_name().name())
    }

    pub(crate) fn read(&self, node: XNode) -> Result<super::Function, Error> {
        parse_function(&self.ctx, node)
    }

    /// An error at `node` with its element path.
    pub(crate) fn err(&self, node: XNode, message: impl Into<String>) -> Error {
        self.ctx.err(node, message)
    }
}

/// The oldest file version read: OpenSim 4.0 writes `Version="40000"`.
const MIN_VERSION: u32 = 40000;

/// The deepest element nesting read; OpenSim files nest about 15 levels.
const MAX_NESTING: usize = crate::limits::MAX_XML_DEPTH;

/// Force-set files added to a model as OpenSim's tools do (`<force_set_files>` with
/// `<replace_force_set>`): each is an `OpenSimDocument` holding one `<ForceSet>` (or, in files
/// written for OpenSim 2 and 3, an `<ActuatorSet>`: the same set under its old name), whose
/// members are appended to the model's forces (or replace them).
#[derive(Clone, Debug, Default)]
pub struct ForceSetFiles {
    /// (file text, file name for messages), in order.
    pub files: Vec<(String, String)>,
    /// Drop the model's own forces (muscles included) before adding these.
    pub replace: bool,
}

fn parse_document<'i>(text: &'i str, source: &str) -> Result<Document<'i>, Error> {
    crate::xml::parse(text, source)
}

/// Reads a model file's text, adding the forces of `force_sets`.
pub(crate) fn parse_with_force_sets(
    text: &str,
    source: &str,
    options: &LoadOptions,
    force_sets: &ForceSetFiles,
) -> Result<Model, Error> {
    parse_inner(text, source, options, Some(force_sets))
}

pub(crate) fn parse(text: &str, source: &str, options: &LoadOptions) -> Result<Model, Error> {
    parse_inner(text, source, options, None)
}

fn parse_inner(
    text: &str,
    source: &str,
    options: &LoadOptions,
    force_sets: Option<&ForceSetFiles>,
) -> Result<Model, Error> {
    let doc = parse_document(text, source)?;
    let mut ctx = Ctx::new(&doc, source);
    // The reader recurses into elements (functions, verbatim copies of forces): refuse
    // nesting far deeper than any model needs instead of overflowing the stack.
    if let Some(deep) = doc
        .descendants()
        .find(|n| n.is_element() && n.ancestors().nth(MAX_NESTING).is_some())
    {
        return Err(Error::Model {
            file: source.to_string(),
            line: ctx.line(deep),
            element: format!("<{}>", deep.tag_name().name()),
            message: format!(
                "elements are nested more than {MAX_NESTING} levels deep \
                 (musculo::limits::MAX_XML_DEPTH)"
            ),
        });
    }
    let root = doc.root_element();
    if root.tag_name().name() != "OpenSimDocument" {
        return Err(ctx.err(root, "the root element must be <OpenSimDocument>"));
    }
    let version: u32 = root
        .attribute("Version")
        .and_then(|v| v.trim().parse().ok())
        .ok_or_else(|| ctx.err(root, "missing or invalid `Version` attribute"))?;
    if version < MIN_VERSION {
        return Err(ctx.err(
            root,
            format!(
                "file format Version {version} is OpenSim 3.x or older; musculo reads OpenSim 4.x \
                 files (Version ≥ {MIN_VERSION}): open and save the model in OpenSim 4 first"
            ),
        ));
    }
    let mut model_node = None;
    for c in elements(root) {
        if c.tag_name().name() == "Model" && model_node.is_none() {
            model_node = Some(c);
        } else {
            ctx.unknown(c);
        }
    }
    let model_node = model_node.ok_or_else(|| ctx.err(root, "no <Model> element"))?;
    ModelReader::default().read(&mut ctx, model_node, source, options, force_sets)
}

/// `<length_units>` must be meters and `<force_units>` newtons: musculo does not convert.
fn check_units(ctx: &Ctx, node: XNode) -> Result<(), Error> {
    let u = node.text().unwrap_or("").trim();
    if node.tag_name().name() == "length_units" {
        if !matches!(u, "meters" | "meter" | "m") {
            return Err(ctx.err(
                node,
                format!("length units `{u}` are not supported; musculo reads models in meters"),
            ));
        }
    } else if !matches!(u, "N" | "newtons" | "Newtons") {
        return Err(ctx.err(
            node,
            format!("force units `{u}` are not supported; musculo reads models in N"),
        ));
    }
    Ok(())
}

/// A body as read, before topological ordering.
struct BodyDef {
    name: String,
    mass: f64,
    com: Vec3,
    inertia: Mat3,
    line: u32,
}

#[derive(Default)]
struct ModelReader<'a, 'i> {
    frames: FrameRegistry,
    bodies: Vec<BodyDef>,
    /// Wrap-object elements with their (file-order) body index.
    wrap_nodes: Vec<(XNode<'a, 'i>, usize)>,
    joint_nodes: Vec<XNode<'a, 'i>>,
    constraint_nodes: Vec<XNode<'a, 'i>>,
    force_nodes: Vec<XNode<'a, 'i>>,
    marker_nodes: Vec<XNode<'a, 'i>>,
    contact_nodes: Vec<XNode<'a, 'i>>,
}

impl<'a, 'i> ModelReader<'a, 'i> {
    /// Reads the `<Model>` element: its sets, then ground, the joint tree with the bodies in
    /// topological order, constraints and the coordinate reduction, wrap objects, markers,
    /// contact geometry and forces (with the force-set files).
    fn read(
        mut self,
        ctx: &mut Ctx<'a, 'i>,
        model: XNode<'a, 'i>,
        source: &str,
        options: &LoadOptions,
        force_sets: Option<&ForceSetFiles>,
    ) -> Result<Model, Error> {
        let name = match model.attribute("name").map(str::trim) {
            Some(n) if !n.is_empty() => ctx.check_component_name(model, n.to_string())?,
            _ => "model".to_string(),
        };
        let (gravity, ground) = self.read_model_elements(ctx, model, options)?;
        self.add_ground(ctx, ground)?;
        self.check_unique_body_names(ctx)?;

        // Joints: register their frames first (a joint may refer to another joint's frame).
        let joint_defs = joints::read_joints(ctx, &self.joint_nodes, &mut self.frames)?;
        let body_lines: Vec<u32> = self.bodies.iter().map(|b| b.line).collect();
        let tree = joints::build_tree(ctx, joint_defs, &mut self.frames, &body_lines)?;
        let bodies = self.bodies_in_tree_order(&tree);
        self.frames.renumber_bodies(&tree.body_new_index);

        let mut model = Model {
            name,
            source: source.to_string(),
            gravity,
            bodies,
            joints: tree.joints,
            coordinates: tree.coordinates,
            dofs: tree.dofs,
            couplers: Vec::new(),
            markers: Vec::new(),
            contact_geometry: Vec::new(),
            forces: Vec::new(),
            wrap_objects: Vec::new(),
            warnings: Vec::new(),
            visual_elements_skipped: 0,
            reduction: Reduction::default(),
        };

        self.read_constraints_and_reduce(ctx, &mut model)?;
        for &(w, body) in &self.wrap_nodes {
            if let Some(obj) = forces::read_wrap_object(ctx, w, tree.body_new_index[body])? {
                model.wrap_objects.push(obj);
            }
        }
        self.read_markers(ctx, &mut model)?;
        for &c in &self.contact_nodes {
            if let Some(g) = forces::read_contact_geometry(ctx, c, &mut self.frames)? {
                model.contact_geometry.push(g);
            }
        }
        let replace = force_sets.is_some_and(|f| f.replace);
        if !replace {
            self.read_forces(ctx, &mut model)?;
        }
        model.warnings = std::mem::take(&mut ctx.warnings);
        for (text, file) in force_sets.map(|f| f.files.as_slice()).unwrap_or(&[]) {
            self.read_force_set_file(text, file, &mut model)?;
        }
        model.visual_elements_skipped = ctx.visual;
        Ok(model)
    }

    /// The children of `<Model>`: bodies are read now, the other sets' members collected for
    /// later stages. Returns (gravity, the `<Ground>` element).
    fn read_model_elements(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        model: XNode<'a, 'i>,
        options: &LoadOptions,
    ) -> Result<(Vec3, Option<XNode<'a, 'i>>), Error> {
        let mut gravity = Vec3::new(0.0, -9.80665, 0.0);
        let mut ground = None;
        for c in elements(model) {
            match c.tag_name().name() {
                "Ground" => ground = Some(c),
                "gravity" => gravity = ctx.vec3_or(model, "gravity", gravity)?,
                "credits" | "publications" => {}
                "length_units" | "force_units" => check_units(ctx, c)?,
                "BodySet" => self.read_body_set(ctx, c, options)?,
                "JointSet" => self.joint_nodes.extend(set_members(c)),
                "ConstraintSet" => self.constraint_nodes.extend(set_members(c)),
                "ForceSet" => self.force_nodes.extend(set_members(c)),
                "MarkerSet" => self.marker_nodes.extend(set_members(c)),
                "ContactGeometrySet" => self.contact_nodes.extend(set_members(c)),
                "ComponentSet" | "components" => {
                    let base = if c.tag_name().name() == "ComponentSet" {
                        "/componentset"
                    } else {
                        ""
                    };
                    for m in set_members(c) {
                        self.read_component(ctx, m, base)?;
                    }
                }
                "ControllerSet" | "ProbeSet" => {
                    let n = set_members(c).len();
                    if n > 0 {
                        ctx.warn(c, format!("{n} element(s) kept out of the model: musculo computes controls and analyses itself"));
                    }
                }
                "defaults" => {}
                _ => ctx.unknown(c),
            }
        }
        Ok((gravity, ground))
    }

    /// The `<Body>` members of `<BodySet>`, at most MAX_BODIES with ground; any other body
    /// type is an error.
    fn read_body_set(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        set: XNode<'a, 'i>,
        options: &LoadOptions,
    ) -> Result<(), Error> {
        let members = set_members(set);
        // ground is a body too
        if members.len() + 1 > crate::limits::MAX_BODIES {
            return Err(ctx.err(
                set,
                format!(
                    "{} bodies: more than the {} a model may have \
                     (musculo::limits::MAX_BODIES, ground included)",
                    members.len() + 1,
                    crate::limits::MAX_BODIES
                ),
            ));
        }
        for b in members {
            if b.tag_name().name() == "Body" {
                self.read_body(ctx, b, options)?;
            } else {
                return Err(ctx.err(
                    b,
                    format!("unsupported body type `{}`", b.tag_name().name()),
                ));
            }
        }
        Ok(())
    }

    /// Ground becomes body 0 (file order too): the other bodies' indices shift by one, every
    /// body's frame is registered, and ground's wrap objects and components are read.
    fn add_ground(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        ground: Option<XNode<'a, 'i>>,
    ) -> Result<(), Error> {
        let ground_name = match ground.and_then(|g| Some((g, g.attribute("name")?.trim()))) {
            Some((g, n)) if !n.is_empty() => ctx.check_component_name(g, n.to_string())?,
            _ => "ground".to_string(),
        };
        self.bodies.insert(
            0,
            BodyDef {
                name: ground_name,
                mass: 0.0,
                com: Vec3::zeros(),
                inertia: Mat3::zeros(),
                line: ground.map(|g| ctx.line(g)).unwrap_or(0),
            },
        );
        // Bodies were read with indices starting at 0; shift them by one for ground.
        for (_, b) in self.wrap_nodes.iter_mut() {
            *b += 1;
        }
        self.frames.add_body("/ground".to_string(), 0);
        for (i, b) in self.bodies.iter().enumerate().skip(1) {
            self.frames.add_body(format!("/bodyset/{}", b.name), i);
        }
        if let Some(g) = ground {
            for c in elements(g) {
                match c.tag_name().name() {
                    "WrapObjectSet" => self
                        .wrap_nodes
                        .extend(set_members(c).into_iter().map(|w| (w, 0))),
                    "components" => {
                        for m in set_members(c) {
                            self.read_component(ctx, m, "/ground")?;
                        }
                    }
                    _ => ctx.unknown(c),
                }
            }
        }
        Ok(())
    }

    /// Two bodies (ground included) with one name are an error.
    fn check_unique_body_names(&self, ctx: &Ctx<'a, 'i>) -> Result<(), Error> {
        let mut seen = std::collections::HashSet::new();
        for b in &self.bodies {
            if !seen.insert(b.name.clone()) {
                return Err(Error::Model {
                    file: ctx.file.to_string(),
                    line: b.line,
                    element: format!("Body \"{}\"", b.name),
                    message: "two bodies have this name".into(),
                });
            }
        }
        Ok(())
    }

    /// The bodies in the tree's topological order, with their joint and parent.
    fn bodies_in_tree_order(&self, tree: &joints::Tree) -> Vec<Body> {
        tree.body_order
            .iter()
            .enumerate()
            .map(|(new, &old)| {
                let d = &self.bodies[old];
                Body {
                    name: d.name.clone(),
                    mass: d.mass,
                    com_in_body: d.com,
                    inertia_about_com: d.inertia,
                    joint: tree.body_joint[new],
                    parent: tree.body_parent[new],
                    line: d.line,
                }
            })
            .collect()
    }

    /// Reads the constraints, builds the coordinate reduction (an error names the coupler it
    /// fails on), checks the kinematic functions over their ranges and sets each coordinate's
    /// role: dependent, independent (its index in q) or locked.
    fn read_constraints_and_reduce(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        model: &mut Model,
    ) -> Result<(), Error> {
        for c in std::mem::take(&mut self.constraint_nodes) {
            self.read_constraint(ctx, c, model)?;
        }
        model.reduction = Reduction::build(model).map_err(|(coupler, message)| {
            let c = &model.couplers[coupler];
            Error::Model {
                file: ctx.file.to_string(),
                line: c.line,
                element: format!("CoordinateCouplerConstraint \"{}\"", c.name),
                message,
            }
        })?;
        kinematic_range::check_kinematic_functions(ctx, model)?;
        for c in model.coordinates.iter_mut() {
            if !matches!(c.role, CoordinateRole::Dependent(_)) {
                c.role = CoordinateRole::Locked;
            }
        }
        for (j, &c) in model.reduction.independent.iter().enumerate() {
            model.coordinates[c].role = CoordinateRole::Independent(j);
        }
        Ok(())
    }

    /// The markers; two with one name are an error.
    fn read_markers(&mut self, ctx: &mut Ctx<'a, 'i>, model: &mut Model) -> Result<(), Error> {
        let mut marker_names = std::collections::HashSet::new();
        for &m in &self.marker_nodes {
            let marker = forces::read_marker(ctx, m, &mut self.frames)?;
            if !marker_names.insert(marker.name.clone()) {
                return Err(ctx.err(
                    m,
                    format!(
                        "two markers are named \"{}\": a marker file could not say which one \
                         it tracks",
                        marker.name
                    ),
                ));
            }
            model.markers.push(marker);
        }
        Ok(())
    }

    /// The model's own forces; two with one name are an error.
    fn read_forces(&mut self, ctx: &mut Ctx<'a, 'i>, model: &mut Model) -> Result<(), Error> {
        let mut by_name = std::collections::HashMap::new();
        for &f in &self.force_nodes {
            let force = forces::read_force(ctx, f, &mut self.frames, model)?;
            if let Some(first) = by_name
                .insert(force.name.clone(), model.forces.len())
                .map(|i| &model.forces[i])
            {
                return Err(ctx.err(
                    f,
                    format!(
                        "two forces are named \"{}\" (the first, a {}, at line {}): \
                         OpenSim names forces uniquely, and tables of muscles and \
                         actuators are keyed by name",
                        force.name, first.kind, first.line
                    ),
                ));
            }
            model.forces.push(force);
        }
        Ok(())
    }

    /// Appends the members of the `<ForceSet>` (or OpenSim 2–3 `<ActuatorSet>`) of a
    /// force-set file. Errors and warnings name that file; a name already used by a force of
    /// the model is an error.
    fn read_force_set_file(
        &mut self,
        text: &str,
        file: &str,
        model: &mut Model,
    ) -> Result<(), Error> {
        let doc = parse_document(text, file)?;
        let mut ctx = Ctx::new(&doc, file);
        let root = doc.root_element();
        // Force-set files written for OpenSim 2 and 3 are read (their names may hold
        // whitespace, which OpenSim removes from documents older than Version 30500).
        ctx.legacy_whitespace_in_names = root
            .attribute("Version")
            .and_then(|v| v.trim().parse::<u32>().ok())
            .is_some_and(|v| v < 30500);
        let is_set = |n: XNode| matches!(n.tag_name().name(), "ForceSet" | "ActuatorSet");
        let set = if is_set(root) {
            Some(root)
        } else if root.tag_name().name() == "OpenSimDocument" {
            elements(root).find(|&c| is_set(c))
        } else {
            None
        };
        let set = set.ok_or_else(|| {
            ctx.err(
                root,
                "a force-set file must hold a <ForceSet> (or OpenSim 2–3's <ActuatorSet>), \
                 inside <OpenSimDocument>",
            )
        })?;
        for f in set_members(set) {
            let force = forces::read_force(&mut ctx, f, &mut self.frames, model)?;
            if model.forces.iter().any(|g| g.name == force.name) {
                return Err(ctx.err(
                    f,
                    format!("a force named \"{}\" is already in the model", force.name),
                ));
            }
            model.forces.push(force);
        }
        model.warnings.append(&mut ctx.warnings);
        Ok(())
    }

    fn read_body(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        b: XNode<'a, 'i>,
        options: &LoadOptions,
    ) -> Result<(), Error> {
        let name = ctx.name(b)?;
        let index = self.bodies.len(); // file-order index before ground is inserted
        let mass = ctx.f64_or(b, "mass", 0.0)?;
        if mass < 0.0 {
            return Err(ctx.err(b, format!("negative mass {mass} kg")));
        }
        let com = ctx.vec3_or(b, "mass_center", Vec3::zeros())?;
        let iv = ctx.vec_opt(b, "inertia")?.unwrap_or_else(|| vec![0.0; 6]);
        if iv.len() != 6 {
            return Err(ctx.err(
                b,
                format!(
                    "<inertia> must hold 6 numbers [Ixx Iyy Izz Ixy Ixz Iyz], found {}",
                    iv.len()
                ),
            ));
        }
        let inertia = Mat3::new(
            iv[0], iv[3], iv[4], iv[3], iv[1], iv[5], iv[4], iv[5], iv[2],
        );
        check_inertia(ctx, b, &inertia, options)?;
        for c in elements(b) {
            match c.tag_name().name() {
                "mass" | "mass_center" | "inertia" => {}
                "WrapObjectSet" => self
                    .wrap_nodes
                    .extend(set_members(c).into_iter().map(|w| (w, index))),
                "components" => {
                    for m in set_members(c) {
                        self.read_component(ctx, m, &format!("/bodyset/{name}"))?;
                    }
                }
                _ => ctx.unknown(c),
            }
        }
        self.bodies.push(BodyDef {
            name,
            mass,
            com,
            inertia,
            line: ctx.line(b),
        });
        Ok(())
    }

    /// A member of `components` / `ComponentSet`: offset frames are registered, anything
    /// else is reported.
    fn read_component(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        c: XNode<'a, 'i>,
        owner: &str,
    ) -> Result<(), Error> {
        if c.tag_name().name() == "PhysicalOffsetFrame" {
            let def = read_offset_frame(ctx, c, owner)?;
            if !self.frames.add_offset(def) {
                return Err(ctx.err(c, "another frame has the same path"));
            }
            Ok(())
        } else {
            ctx.warn(
                c,
                format!(
                    "component of type `{}` is not used by musculo",
                    c.tag_name().name()
                ),
            );
            Ok(())
        }
    }

    fn read_constraint(
        &mut self,
        ctx: &mut Ctx<'a, 'i>,
        c: XNode<'a, 'i>,
        model: &mut Model,
    ) -> Result<(), Error> {
        if c.tag_name().name() != "CoordinateCouplerConstraint" {
            ctx.warn(c, format!(
                "constraint type `{}` is not supported and is NOT enforced: the dynamics are computed without it",
                c.tag_name().name()
            ));
            return Ok(());
        }
        let name = ctx.name(c)?;
        if !ctx.bool_or(c, "isEnforced", true)? {
            ctx.warn(
                c,
                "isEnforced is false: the coupling is ignored, as in OpenSim",
            );
            return Ok(());
        }
        let find = |n: &str| model.coordinate_index(n);
        let dep_name = ctx.req_text(c, "dependent_coordinate_name")?;
        let dependent = find(dep_name)
            .ok_or_else(|| ctx.err(c, format!("unknown dependent coordinate `{dep_name}`")))?;
        let indep_text = ctx.req_text(c, "independent_coordinate_names")?;
        let mut independents = Vec::new();
        for n in indep_text.split_whitespace() {
            let i = find(n)
                .ok_or_else(|| ctx.err(c, format!("unknown independent coordinate `{n}`")))?;
            if i == dependent {
                return Err(ctx.err(c, format!("coordinate `{n}` cannot depend on itself")));
            }
            independents.push(i);
        }
        let holder = child(c, "coupled_coordinates_function")
            .ok_or_else(|| ctx.err(c, "missing <coupled_coordinates_function>"))?;
        let fnode =
            function_child(holder).ok_or_else(|| ctx.err(holder, "holds no function element"))?;
        let function = parse_function(ctx, fnode)?;
        if let super::Arity::Exactly(k) = function.arity()
            && k != independents.len()
        {
            return Err(ctx.err(
                fnode,
                format!(
                    "function of {k} argument(s) given {} independent coordinate(s)",
                    independents.len()
                ),
            ));
        }
        let scale = ctx.f64_or(c, "scale_factor", 1.0)?;
        let coord = &mut model.coordinates[dependent];
        if coord.locked {
            return Err(ctx.err(c, format!(
                "coordinate `{dep_name}` is both locked and the dependent coordinate of this coupler"
            )));
        }
        if let CoordinateRole::Dependent(other) = coord.role {
            return Err(ctx.err(
                c,
                format!(
                    "coordinate `{dep_name}` is already the dependent coordinate of coupler `{}`",
                    model.couplers[other].name
                ),
            ));
        }
        coord.role = CoordinateRole::Dependent(model.couplers.len());
        model.couplers.push(CouplerConstraint {
            name,
            dependent,
            independents,
            function,
            scale,
            line: ctx.line(c),
        });
        Ok(())
    }
}

/// A PhysicalOffsetFrame element owned by the component at `owner`.
fn read_offset_frame(ctx: &mut Ctx, f: XNode, owner: &str) -> Result<OffsetFrameDef, Error> {
    let name = ctx.name(f)?;
    let parent = ctx
        .text(f, "socket_parent")
        .filter(|s| !s.is_empty())
        .ok_or_else(|| ctx.err(f, "missing <socket_parent>"))?
        .to_string();
    let translation = ctx.vec3_or(f, "translation", Vec3::zeros())?;
    let orientation = ctx.vec3_or(f, "orientation", Vec3::zeros())?;
    for c in elements(f) {
        match c.tag_name().name() {
            "socket_parent" | "translation" | "orientation" => {}
            _ => ctx.unknown(c),
        }
    }
    Ok(OffsetFrameDef {
        path: resolve_path(owner, &name),
        parent,
        offset: Transform::from_translation_xyz_body(translation, orientation),
    })
}

/// Inertia checks: symmetric positive semi-definite with principal moments satisfying the
/// triangle inequality I₁ + I₂ ≥ I₃ (with a relative tolerance of 1e-9).
fn check_inertia(
    ctx: &mut Ctx,
    b: XNode,
    inertia: &Mat3,
    options: &LoadOptions,
) -> Result<(), Error> {
    let eig = nalgebra::SymmetricEigen::new(*inertia).eigenvalues;
    let mut p = [eig[0], eig[1], eig[2]];
    p.sort_by(|a, b| a.total_cmp(b));
    let scale = p[2].abs().max(1e-300);
    let tol = 1e-9 * scale;
    if p[0] < -tol {
        return Err(ctx.err(
            b,
            format!(
                "inertia is not positive semi-definite (principal moments {:.6e}, {:.6e}, {:.6e})",
                p[0], p[1], p[2]
            ),
        ));
    }
    if p[0] + p[1] < p[2] - tol {
        let msg = format!(
            "inertia violates the triangle inequality: principal moments {:.6e} + {:.6e} < {:.6e}",
            p[0], p[1], p[2]
        );
        if options.strict {
            return Err(ctx.err(
                b,
                format!(
                    "{msg}; no rigid body has such an inertia, and strict reading (`--strict`) \
                     refuses it (without `--strict` the body is read with a warning, as \
                     OpenSim's release builds read it)"
                ),
            ));
        }
        ctx.warn_kind(
            b,
            super::WarningKind::NonphysicalInertia,
            format!(
                "{msg}: no rigid body has such an inertia; read as OpenSim's release builds \
                 read it (`--strict` refuses it)"
            ),
        );
    }
    Ok(())
}

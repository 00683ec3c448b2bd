//! A small, strict URDF reader: links with their collision geometry, and joints.
//!
//! Only what kinematics, collision and dynamics need is read (no visuals).
//! Only `<link>` and `<joint>` elements that are direct children of `<robot>` count
//! (Talos' `<transmission>` blocks also contain `<joint>` tags).
//!
//! What the reader accepts is usable: every number is finite and within a documented bound
//! ([`MAX_MAGNITUDE`] for lengths, angles, masses and inertias, [`MAX_JOINT_POSITION`] for joint
//! limits), a moving joint's axis is a unit vector, a revolute or prismatic joint's limits are
//! not reversed, and link and joint names are unique ([`Urdf::validate`]). Errors name the file
//! (when read from one), the link or joint, the element and the problem.
//!
//! A joint's `<mimic>` is read ([`Mimic`]); whether genplan can follow it (a revolute or
//! prismatic joint following an earlier one of those kinds) is decided when a model is built
//! ([`KinematicModel::from_urdf`](crate::kinematics::KinematicModel::from_urdf)).

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use crate::error::{Error, Result};

/// Collision geometry as written in the URDF.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// `<box>`, centred on its origin.
    Box {
        /// Edge lengths along x, y, z.
        size: Vector3<f64>,
    },
    /// `<cylinder>` along z, centred on its origin.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Length along z.
        length: f64,
    },
    /// `<sphere>`.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// `<capsule>` along z, centred on its origin.
    Capsule {
        /// Radius of the cylinder and the end caps.
        radius: f64,
        /// Length of the cylinder part, along z.
        length: f64,
    },
    /// `<mesh>`.
    Mesh {
        /// The file name as written (`package://`, `file://` or a path; see [`Urdf::resolve_mesh`]).
        filename: String,
        /// Scale along x, y, z (default 1).
        scale: Vector3<f64>,
    },
}

/// One `<collision>` element of a link.
#[derive(Debug, Clone)]
pub struct Collision {
    /// Pose of the geometry in the link frame (`<origin>`).
    pub origin: Isometry3<f64>,
    /// The shape.
    pub geometry: Geometry,
}

/// Mass properties of a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertial {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the link frame.
    pub com: Vector3<f64>,
    /// Rotational inertia about the centre of mass, in the link frame's axes (the URDF's
    /// `<inertia>`, given in the `<inertial><origin rpy>` axes, rotated into the link's:
    /// `R I R^T`). Zero when the URDF gives no `<inertia>`.
    pub inertia: Matrix3<f64>,
}

/// One `<link>`.
#[derive(Debug, Clone)]
pub struct Link {
    /// Its name.
    pub name: String,
    /// Its `<collision>` elements, in file order.
    pub collisions: Vec<Collision>,
    /// Its `<inertial>`, if any.
    pub inertial: Option<Inertial>,
}

/// The `type` of a `<joint>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointType {
    /// No motion.
    Fixed,
    /// Rotation about the axis, within limits.
    Revolute,
    /// Rotation about the axis, unbounded.
    Continuous,
    /// Translation along the axis, within limits.
    Prismatic,
    /// Six degrees of freedom.
    Floating,
    /// Motion in the plane normal to the axis.
    Planar,
}

/// A joint's `<mimic>`: it does not move on its own but follows another joint, at
/// `multiplier * q_joint + offset` (as ROS and Pinocchio read it).
#[derive(Debug, Clone, PartialEq)]
pub struct Mimic {
    /// The joint it follows (its "master").
    pub joint: String,
    /// Scale of the master's value (default 1); finite, at most [`MAX_MAGNITUDE`] in magnitude.
    pub multiplier: f64,
    /// Added to the scaled value (default 0); finite, at most [`MAX_JOINT_POSITION`] in magnitude.
    pub offset: f64,
}

/// One `<joint>`.
#[derive(Debug, Clone)]
pub struct Joint {
    /// Its name.
    pub name: String,
    /// Its type.
    pub joint_type: JointType,
    /// Name of the parent link.
    pub parent: String,
    /// Name of the child link.
    pub child: String,
    /// Pose of the joint frame in the parent link frame (`<origin>`).
    pub origin: Isometry3<f64>,
    /// Axis in the joint frame (`<axis xyz>`, default x); a unit vector for a joint that moves
    /// along or about it (revolute, continuous, prismatic, planar), as written otherwise.
    pub axis: Vector3<f64>,
    /// Lower limit (`<limit lower>` of a revolute or prismatic joint, default 0); -inf otherwise.
    /// At most [`MAX_JOINT_POSITION`] in magnitude, and at most `upper`.
    pub lower: f64,
    /// Upper limit (`<limit upper>` of a revolute or prismatic joint, default 0); +inf otherwise.
    pub upper: f64,
    /// Largest effort (`<limit effort>`: N m for a revolute joint, N for a prismatic one);
    /// +inf when not given.
    pub effort: f64,
    /// Largest speed (`<limit velocity>`: rad/s or m/s); +inf when not given.
    pub velocity: f64,
    /// Its `<mimic>`, if any: the joint follows another instead of moving on its own.
    pub mimic: Option<Mimic>,
}

/// A parsed URDF file.
#[derive(Debug, Clone)]
pub struct Urdf {
    /// The robot's name (`<robot name>`).
    pub name: String,
    /// The links, in file order.
    pub links: Vec<Link>,
    /// The joints, in file order.
    pub joints: Vec<Joint>,
    /// Folder of the file, for resolving relative mesh paths (None when parsed from a string).
    pub dir: Option<PathBuf>,
    /// The file it was read from (None when parsed from a string); errors name it.
    pub path: Option<PathBuf>,
}

/// The largest magnitude the reader accepts for a length (m) or an angle (rad): every `xyz` and
/// `rpy` of an `<origin>` (joints, collisions, inertials), collision sizes and mesh scales; also
/// the largest mass (kg) and inertia component (kg m^2). Real robots stay below 10; with 1e6 no
/// sum or product that kinematics, collision and dynamics form can overflow.
pub const MAX_MAGNITUDE: f64 = 1e6;

/// The largest magnitude of a joint position: a `<limit lower/upper>` of a revolute or
/// prismatic joint, a locked joint's value, an SRDF group-state value. Some URDFs write
/// +-1e16 for a joint without bounds; the width of any accepted limits is finite, so they can be
/// sampled uniformly.
pub const MAX_JOINT_POSITION: f64 = 1e16;

/// The shortest `<axis>` of a moving joint (revolute, continuous, prismatic, planar) that gives
/// a direction; the reader refuses a shorter one and normalises the others.
pub const MIN_AXIS_NORM: f64 = 1e-12;

/// Rotation of a URDF `rpy` attribute: fixed-axis roll about x, then pitch about y, then yaw
/// about z, i.e. R = Rz(yaw) Ry(pitch) Rx(roll) (the same as Pinocchio's `rpyToMatrix`).
pub fn rpy_to_rotation(roll: f64, pitch: f64, yaw: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll, pitch, yaw)
}

/// An error of the URDF text (`from_file` adds the file's path).
fn parse_error(msg: String) -> Error {
    Error::Parse {
        what: "URDF".into(),
        msg,
    }
}

/// `n` numbers of an attribute, each finite and at most `bound` in magnitude; `what` names the
/// attribute and its element (e.g. `joint 'j1': <origin xyz>`).
fn parse_floats(what: &str, text: &str, n: usize, bound: f64) -> Result<Vec<f64>> {
    let values: std::result::Result<Vec<f64>, _> =
        text.split_whitespace().map(str::parse::<f64>).collect();
    match values {
        Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => {
            match v.iter().find(|x| x.abs() > bound) {
                Some(x) => Err(parse_error(format!(
                    "{what}: {x:e} is too large (at most {bound:e} in magnitude)"
                ))),
                None => Ok(v),
            }
        }
        _ => Err(parse_error(format!(
            "{what}: expected {n} finite numbers, got '{text}'"
        ))),
    }
}

/// `<tag attr>` of `node`, as named in messages: `{ctx}: <tag attr>`.
fn attr_name(ctx: &str, node: roxmltree::Node, attr: &str) -> String {
    format!("{ctx}: <{} {attr}>", node.tag_name().name())
}

fn vec3_attr(
    ctx: &str,
    node: roxmltree::Node,
    attr: &str,
    default: Vector3<f64>,
    bound: f64,
) -> Result<Vector3<f64>> {
    match node.attribute(attr) {
        None => Ok(default),
        Some(t) => {
            let v = parse_floats(&attr_name(ctx, node, attr), t, 3, bound)?;
            Ok(Vector3::new(v[0], v[1], v[2]))
        }
    }
}

fn f64_attr(ctx: &str, node: roxmltree::Node, attr: &str, bound: f64) -> Result<Option<f64>> {
    match node.attribute(attr) {
        None => Ok(None),
        Some(t) => Ok(Some(parse_floats(&attr_name(ctx, node, attr), t, 1, bound)?[0])),
    }
}

fn required_f64(ctx: &str, node: roxmltree::Node, attr: &str, bound: f64) -> Result<f64> {
    f64_attr(ctx, node, attr, bound)?.ok_or_else(|| {
        parse_error(format!("{ctx}: <{}> lacks attribute '{attr}'", node.tag_name().name()))
    })
}

fn child<'a, 'i>(node: roxmltree::Node<'a, 'i>, tag: &str) -> Option<roxmltree::Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == tag)
}

fn origin_of(ctx: &str, node: roxmltree::Node) -> Result<Isometry3<f64>> {
    match child(node, "origin") {
        None => Ok(Isometry3::identity()),
        Some(o) => {
            let xyz = vec3_attr(ctx, o, "xyz", Vector3::zeros(), MAX_MAGNITUDE)?;
            let rpy = vec3_attr(ctx, o, "rpy", Vector3::zeros(), MAX_MAGNITUDE)?;
            Ok(Isometry3::from_parts(
                Translation3::from(xyz),
                rpy_to_rotation(rpy.x, rpy.y, rpy.z),
            ))
        }
    }
}

fn parse_geometry(link: &str, node: roxmltree::Node) -> Result<Option<Geometry>> {
    let ctx = format!("link '{link}' <collision>");
    let ctx = ctx.as_str();
    let geom = match child(node, "geometry") {
        Some(g) => g,
        None => {
            return Err(parse_error(format!(
                "a <collision> of link '{link}' has no <geometry>"
            )))
        }
    };
    let shape = match geom.children().find(|c| c.is_element()) {
        Some(s) => s,
        None => return Ok(None),
    };
    let length = |attr: &str| required_f64(ctx, shape, attr, MAX_MAGNITUDE);
    let g = match shape.tag_name().name() {
        "box" => Geometry::Box {
            size: vec3_attr(ctx, shape, "size", Vector3::zeros(), MAX_MAGNITUDE)?,
        },
        "cylinder" => Geometry::Cylinder {
            radius: length("radius")?,
            length: length("length")?,
        },
        "capsule" => Geometry::Capsule {
            radius: length("radius")?,
            length: length("length")?,
        },
        "sphere" => Geometry::Sphere {
            radius: length("radius")?,
        },
        "mesh" => Geometry::Mesh {
            filename: shape
                .attribute("filename")
                .ok_or_else(|| parse_error(format!("a <mesh> of link '{link}' has no filename")))?
                .to_string(),
            scale: vec3_attr(ctx, shape, "scale", Vector3::new(1.0, 1.0, 1.0), MAX_MAGNITUDE)?,
        },
        other => {
            return Err(parse_error(format!(
                "link '{link}': unsupported collision geometry <{other}>"
            )))
        }
    };
    Ok(Some(g))
}

/// The `<inertial>` of link `name`.
fn parse_inertial(name: &str, i: roxmltree::Node) -> Result<Inertial> {
    let ctx = format!("link '{name}' <inertial>");
    let ctx = ctx.as_str();
    let mass = child(i, "mass")
        .map(|m| required_f64(ctx, m, "value", MAX_MAGNITUDE))
        .transpose()?
        .unwrap_or(0.0);
    if mass < 0.0 {
        return Err(parse_error(format!("link '{name}' has negative mass {mass}")));
    }
    let (com, rpy) = match child(i, "origin") {
        Some(o) => (
            vec3_attr(ctx, o, "xyz", Vector3::zeros(), MAX_MAGNITUDE)?,
            vec3_attr(ctx, o, "rpy", Vector3::zeros(), MAX_MAGNITUDE)?,
        ),
        None => (Vector3::zeros(), Vector3::zeros()),
    };
    let inertia = match child(i, "inertia") {
        None => Matrix3::zeros(),
        Some(t) => {
            let get = |a: &str| -> Result<f64> { Ok(f64_attr(ctx, t, a, MAX_MAGNITUDE)?.unwrap_or(0.0)) };
            let (xx, xy, xz) = (get("ixx")?, get("ixy")?, get("ixz")?);
            let (yy, yz, zz) = (get("iyy")?, get("iyz")?, get("izz")?);
            let local = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
            let r = rpy_to_rotation(rpy.x, rpy.y, rpy.z)
                .to_rotation_matrix()
                .into_inner();
            r * local * r.transpose()
        }
    };
    Ok(Inertial { mass, com, inertia })
}

fn parse_link(node: roxmltree::Node) -> Result<Link> {
    let name = node
        .attribute("name")
        .ok_or_else(|| parse_error("a <link> has no name".into()))?;
    let mut collisions = Vec::new();
    for c in node
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "collision")
    {
        if let Some(geometry) = parse_geometry(name, c)? {
            collisions.push(Collision {
                origin: origin_of(&format!("link '{name}' <collision>"), c)?,
                geometry,
            });
        }
    }
    let inertial = child(node, "inertial")
        .map(|i| parse_inertial(name, i))
        .transpose()?;
    Ok(Link {
        name: name.to_string(),
        collisions,
        inertial,
    })
}

/// The first name that occurs twice, if any.
fn first_duplicate<'a>(names: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let mut seen = std::collections::HashSet::new();
    names.into_iter().find(|n| !seen.insert(*n))
}

/// A joint type whose motion follows its axis.
fn has_axis(t: JointType) -> bool {
    matches!(
        t,
        JointType::Revolute | JointType::Continuous | JointType::Prismatic | JointType::Planar
    )
}

impl Urdf {
    /// Parse URDF text, and check it ([`Urdf::validate`]): every number finite and within the
    /// documented bounds ([`MAX_MAGNITUDE`], [`MAX_JOINT_POSITION`]), a moving joint's axis not
    /// zero (it is normalised), a revolute or prismatic joint's limits not reversed, no two links
    /// or joints of the same name. (Whether the joints form a tree is checked when a model is
    /// built: [`KinematicModel::from_urdf`](crate::kinematics::KinematicModel::from_urdf).)
    pub fn parse(text: &str) -> Result<Urdf> {
        let doc = roxmltree::Document::parse(text).map_err(|e| parse_error(e.to_string()))?;
        let robot = doc.root_element();
        if robot.tag_name().name() != "robot" {
            return Err(parse_error(format!(
                "root element is <{}>, not <robot>",
                robot.tag_name().name()
            )));
        }
        let mut links = Vec::new();
        let mut joints = Vec::new();
        for node in robot.children().filter(|n| n.is_element()) {
            match node.tag_name().name() {
                "link" => links.push(parse_link(node)?),
                "joint" => joints.push(parse_joint(node)?),
                _ => {}
            }
        }
        if links.is_empty() {
            return Err(parse_error("no <link> elements".into()));
        }
        let urdf = Urdf {
            name: robot.attribute("name").unwrap_or("").to_string(),
            links,
            joints,
            dir: None,
            path: None,
        };
        urdf.validate()?;
        Ok(urdf)
    }

    /// Read and parse a URDF file ([`Urdf::parse`]); errors name the file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Urdf> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut urdf = Urdf::parse(&text).map_err(|e| match e {
            Error::Parse { msg, .. } => Error::Parse {
                what: format!("URDF {}", path.display()),
                msg,
            },
            other => other,
        })?;
        urdf.dir = path.parent().map(Path::to_path_buf);
        urdf.path = Some(path.to_path_buf());
        Ok(urdf)
    }

    /// `URDF <path>` (or `URDF` when parsed from a string): the file, as errors name it.
    pub fn what(&self) -> String {
        match &self.path {
            Some(p) => format!("URDF {}", p.display()),
            None => "URDF".into(),
        }
    }

    /// An [`Error::Parse`] of this URDF (naming its file when known).
    pub(crate) fn error(&self, msg: String) -> Error {
        Error::Parse {
            what: self.what(),
            msg,
        }
    }

    /// Check what [`Urdf::parse`] guarantees, for a `Urdf` that was built or changed in code
    /// (the kinematic model checks it again): link and joint names unique; joint origins,
    /// centres of mass and masses finite and at most [`MAX_MAGNITUDE`] in magnitude; a moving
    /// joint's axis finite and at least [`MIN_AXIS_NORM`] long; limits not NaN, finite ones at
    /// most [`MAX_JOINT_POSITION`] in magnitude, lower <= upper; effort and velocity not NaN.
    pub fn validate(&self) -> Result<()> {
        if let Some(n) = first_duplicate(self.links.iter().map(|l| l.name.as_str())) {
            return Err(self.error(format!("link '{n}' is defined twice (link names must be unique)")));
        }
        if let Some(n) = first_duplicate(self.joints.iter().map(|j| j.name.as_str())) {
            return Err(self.error(format!("joint '{n}' is defined twice (joint names must be unique)")));
        }
        let bounded = |v: &[f64]| v.iter().all(|x| x.is_finite() && x.abs() <= MAX_MAGNITUDE);
        for l in &self.links {
            if let Some(i) = &l.inertial {
                // the inertia is rotated into the link's axes: its entries reach 3 MAX_MAGNITUDE
                let inertia_ok = i.inertia.iter().all(|x| x.is_finite() && x.abs() <= 3.0 * MAX_MAGNITUDE);
                if !(bounded(&[i.mass]) && i.mass >= 0.0 && bounded(i.com.as_slice()) && inertia_ok) {
                    return Err(self.error(format!(
                        "link '{}': <inertial> mass {}, centre of mass {:?} or inertia {:?} is negative, \
                         not finite or larger than {MAX_MAGNITUDE:e} in magnitude",
                        l.name, i.mass, i.com.as_slice(), i.inertia.as_slice()
                    )));
                }
            }
        }
        for j in &self.joints {
            let t = j.origin.translation.vector;
            let r = j.origin.rotation.coords;
            if !bounded(t.as_slice()) || !r.iter().all(|x| x.is_finite()) {
                return Err(self.error(format!(
                    "joint '{}': <origin> {:?} is not finite or larger than {MAX_MAGNITUDE:e} in magnitude",
                    j.name, j.origin
                )));
            }
            if has_axis(j.joint_type) && crate::lie::unit_vector(&j.axis, MIN_AXIS_NORM).is_none() {
                return Err(self.error(format!(
                    "joint '{}': <axis xyz> {:?} is not finite or gives no direction (length below {MIN_AXIS_NORM:e})",
                    j.name, j.axis.as_slice()
                )));
            }
            check_limits(&j.name, j.lower, j.upper).map_err(|msg| self.error(msg))?;
            if j.effort.is_nan() || j.velocity.is_nan() {
                return Err(self.error(format!("joint '{}': <limit> effort or velocity is NaN", j.name)));
            }
            if let Some(m) = &j.mimic {
                let ok = |x: f64, bound: f64| x.is_finite() && x.abs() <= bound;
                if !(ok(m.multiplier, MAX_MAGNITUDE) && ok(m.offset, MAX_JOINT_POSITION)) {
                    return Err(self.error(format!(
                        "joint '{}': <mimic> multiplier {} or offset {} is not finite or too large \
                         (at most {MAX_MAGNITUDE:e} and {MAX_JOINT_POSITION:e} in magnitude)",
                        j.name, m.multiplier, m.offset
                    )));
                }
            }
        }
        Ok(())
    }

    /// Resolve a mesh filename: `package://pkg/rest` is looked up as `<dir>/pkg/rest` in each
    /// package dir; `file://` and relative paths are taken from the URDF's folder.
    pub fn resolve_mesh(&self, filename: &str, package_dirs: &[PathBuf]) -> Result<PathBuf> {
        let p = resolve_uri(filename, self.dir.as_deref(), package_dirs, Path::is_file).ok_or_else(|| Error::Mesh {
            path: PathBuf::from(filename),
            msg: format!(
                "not found in package dirs [{}]",
                package_dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
            ),
        })?;
        if p.is_file() {
            Ok(p)
        } else {
            Err(Error::Mesh {
                path: p,
                msg: "file does not exist".into(),
            })
        }
    }
}

/// Joint limits `lower..=upper` as the model uses them: not NaN, lower <= upper (equal is a
/// joint that cannot move), finite ones at most [`MAX_JOINT_POSITION`] in magnitude (infinite
/// ones: no limit on that side). The error names the joint.
fn check_limits(joint: &str, lower: f64, upper: f64) -> std::result::Result<(), String> {
    if lower.is_nan() || upper.is_nan() {
        return Err(format!("joint '{joint}': <limit> lower {lower} or upper {upper} is NaN"));
    }
    for (which, x) in [("lower", lower), ("upper", upper)] {
        if x.is_finite() && x.abs() > MAX_JOINT_POSITION {
            return Err(format!(
                "joint '{joint}': <limit {which}> {x:e} is too large (at most {MAX_JOINT_POSITION:e} in magnitude)"
            ));
        }
    }
    if lower > upper || lower == f64::INFINITY || upper == f64::NEG_INFINITY {
        return Err(format!(
            "joint '{joint}': <limit> lower {lower} is above upper {upper} (reversed limits)"
        ));
    }
    Ok(())
}

fn parse_joint(node: roxmltree::Node) -> Result<Joint> {
    let name = node
        .attribute("name")
        .ok_or_else(|| parse_error("a <joint> has no name".into()))?;
    let ctx = format!("joint '{name}'");
    let ctx = ctx.as_str();
    let joint_type = match node.attribute("type") {
        Some("fixed") => JointType::Fixed,
        Some("revolute") => JointType::Revolute,
        Some("continuous") => JointType::Continuous,
        Some("prismatic") => JointType::Prismatic,
        Some("floating") => JointType::Floating,
        Some("planar") => JointType::Planar,
        other => {
            return Err(parse_error(format!(
                "joint '{name}' has unknown type {other:?}"
            )))
        }
    };
    let link_attr = |tag: &str| -> Result<String> {
        child(node, tag)
            .and_then(|n| n.attribute("link"))
            .map(str::to_string)
            .ok_or_else(|| parse_error(format!("joint '{name}' lacks <{tag} link=...>")))
    };
    // Any finite length: only the direction counts (normalised without overflow).
    let mut axis = match child(node, "axis") {
        Some(a) => vec3_attr(ctx, a, "xyz", Vector3::x(), f64::INFINITY)?,
        None => Vector3::x(),
    };
    if has_axis(joint_type) {
        axis = crate::lie::unit_vector(&axis, MIN_AXIS_NORM)
            .ok_or_else(|| {
                parse_error(format!(
                    "joint '{name}': <axis xyz> {:?} gives no direction (length below {MIN_AXIS_NORM:e})",
                    axis.as_slice()
                ))
            })?
            .into_inner();
    }
    let (mut lower, mut upper) = (f64::NEG_INFINITY, f64::INFINITY);
    let (mut effort, mut velocity) = (f64::INFINITY, f64::INFINITY);
    if let Some(limit) = child(node, "limit") {
        if matches!(joint_type, JointType::Revolute | JointType::Prismatic) {
            lower = f64_attr(ctx, limit, "lower", MAX_JOINT_POSITION)?.unwrap_or(0.0);
            upper = f64_attr(ctx, limit, "upper", MAX_JOINT_POSITION)?.unwrap_or(0.0);
            check_limits(name, lower, upper).map_err(parse_error)?;
        }
        effort = f64_attr(ctx, limit, "effort", f64::INFINITY)?.unwrap_or(f64::INFINITY);
        velocity = f64_attr(ctx, limit, "velocity", f64::INFINITY)?.unwrap_or(f64::INFINITY);
    }
    let mimic = match child(node, "mimic") {
        None => None,
        Some(m) => Some(Mimic {
            joint: m
                .attribute("joint")
                .ok_or_else(|| parse_error(format!("joint '{name}': <mimic> lacks attribute 'joint'")))?
                .to_string(),
            multiplier: f64_attr(ctx, m, "multiplier", MAX_MAGNITUDE)?.unwrap_or(1.0),
            offset: f64_attr(ctx, m, "offset", MAX_JOINT_POSITION)?.unwrap_or(0.0),
        }),
    };
    Ok(Joint {
        name: name.to_string(),
        joint_type,
        parent: link_attr("parent")?,
        child: link_attr("child")?,
        origin: origin_of(ctx, node)?,
        axis,
        lower,
        upper,
        effort,
        velocity,
        mimic,
    })
}

/// Where a file URI of a robot description points: `package://PKG/rest` is the first
/// `<dir>/PKG/rest` of `package_dirs` that satisfies `found` (None when none does); `file://`
/// and plain paths are taken as they are when absolute, else relative to `base` (the current
/// folder when None). The one resolution of URDF meshes and robot files' paths.
pub fn resolve_uri(value: &str, base: Option<&Path>, package_dirs: &[PathBuf], found: impl Fn(&Path) -> bool) -> Option<PathBuf> {
    if let Some(rest) = value.strip_prefix("package://") {
        return package_dirs.iter().map(|d| d.join(rest)).find(|p| found(p));
    }
    let p = PathBuf::from(value.strip_prefix("file://").unwrap_or(value));
    Some(match base {
        Some(b) if p.is_relative() => b.join(p),
        _ => p,
    })
}

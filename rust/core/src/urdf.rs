//! A small, strict URDF reader: links with their collision geometry, and joints.
//!
//! Only what kinematics, collision and dynamics need is read (no visuals).
//! Only `<link>` and `<joint>` elements that are direct children of `<robot>` count
//! (Talos' `<transmission>` blocks also contain `<joint>` tags).

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
    /// Axis in the joint frame (`<axis xyz>`, default x).
    pub axis: Vector3<f64>,
    /// Lower limit (`<limit lower>` of a revolute or prismatic joint, default 0); -inf otherwise.
    pub lower: f64,
    /// Upper limit (`<limit upper>` of a revolute or prismatic joint, default 0); +inf otherwise.
    pub upper: f64,
    /// Largest effort (`<limit effort>`: N m for a revolute joint, N for a prismatic one);
    /// +inf when not given.
    pub effort: f64,
    /// Largest speed (`<limit velocity>`: rad/s or m/s); +inf when not given.
    pub velocity: f64,
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
}

/// Rotation of a URDF `rpy` attribute: fixed-axis roll about x, then pitch about y, then yaw
/// about z, i.e. R = Rz(yaw) Ry(pitch) Rx(roll) (the same as Pinocchio's `rpyToMatrix`).
pub fn rpy_to_rotation(roll: f64, pitch: f64, yaw: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll, pitch, yaw)
}

fn parse_floats(what: &str, text: &str, n: usize) -> Result<Vec<f64>> {
    let values: std::result::Result<Vec<f64>, _> =
        text.split_whitespace().map(str::parse::<f64>).collect();
    match values {
        Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => Err(Error::Parse {
            what: "URDF".into(),
            msg: format!("{what}: expected {n} finite numbers, got '{text}'"),
        }),
    }
}

fn vec3_attr(node: roxmltree::Node, attr: &str, default: Vector3<f64>) -> Result<Vector3<f64>> {
    match node.attribute(attr) {
        None => Ok(default),
        Some(t) => {
            let v = parse_floats(&format!("<{} {attr}>", node.tag_name().name()), t, 3)?;
            Ok(Vector3::new(v[0], v[1], v[2]))
        }
    }
}

fn f64_attr(node: roxmltree::Node, attr: &str) -> Result<Option<f64>> {
    match node.attribute(attr) {
        None => Ok(None),
        Some(t) => {
            Ok(Some(parse_floats(&format!("<{} {attr}>", node.tag_name().name()), t, 1)?[0]))
        }
    }
}

fn required_f64(node: roxmltree::Node, attr: &str) -> Result<f64> {
    f64_attr(node, attr)?.ok_or_else(|| Error::Parse {
        what: "URDF".into(),
        msg: format!("<{}> lacks attribute '{attr}'", node.tag_name().name()),
    })
}

fn child<'a, 'i>(node: roxmltree::Node<'a, 'i>, tag: &str) -> Option<roxmltree::Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == tag)
}

fn origin_of(node: roxmltree::Node) -> Result<Isometry3<f64>> {
    match child(node, "origin") {
        None => Ok(Isometry3::identity()),
        Some(o) => {
            let xyz = vec3_attr(o, "xyz", Vector3::zeros())?;
            let rpy = vec3_attr(o, "rpy", Vector3::zeros())?;
            Ok(Isometry3::from_parts(
                Translation3::from(xyz),
                rpy_to_rotation(rpy.x, rpy.y, rpy.z),
            ))
        }
    }
}

fn parse_geometry(link: &str, node: roxmltree::Node) -> Result<Option<Geometry>> {
    let geom = match child(node, "geometry") {
        Some(g) => g,
        None => {
            return Err(Error::Parse {
                what: "URDF".into(),
                msg: format!("a <collision> of link '{link}' has no <geometry>"),
            })
        }
    };
    let shape = match geom.children().find(|c| c.is_element()) {
        Some(s) => s,
        None => return Ok(None),
    };
    let g = match shape.tag_name().name() {
        "box" => Geometry::Box {
            size: vec3_attr(shape, "size", Vector3::zeros())?,
        },
        "cylinder" => Geometry::Cylinder {
            radius: required_f64(shape, "radius")?,
            length: required_f64(shape, "length")?,
        },
        "capsule" => Geometry::Capsule {
            radius: required_f64(shape, "radius")?,
            length: required_f64(shape, "length")?,
        },
        "sphere" => Geometry::Sphere {
            radius: required_f64(shape, "radius")?,
        },
        "mesh" => Geometry::Mesh {
            filename: shape
                .attribute("filename")
                .ok_or_else(|| Error::Parse {
                    what: "URDF".into(),
                    msg: format!("a <mesh> of link '{link}' has no filename"),
                })?
                .to_string(),
            scale: vec3_attr(shape, "scale", Vector3::new(1.0, 1.0, 1.0))?,
        },
        other => {
            return Err(Error::Parse {
                what: "URDF".into(),
                msg: format!("link '{link}': unsupported collision geometry <{other}>"),
            })
        }
    };
    Ok(Some(g))
}

impl Urdf {
    /// Parse URDF text.
    pub fn parse(text: &str) -> Result<Urdf> {
        let doc = roxmltree::Document::parse(text).map_err(|e| Error::Parse {
            what: "URDF".into(),
            msg: e.to_string(),
        })?;
        let robot = doc.root_element();
        if robot.tag_name().name() != "robot" {
            return Err(Error::Parse {
                what: "URDF".into(),
                msg: format!("root element is <{}>, not <robot>", robot.tag_name().name()),
            });
        }
        let mut links = Vec::new();
        let mut joints = Vec::new();
        for node in robot.children().filter(|n| n.is_element()) {
            match node.tag_name().name() {
                "link" => {
                    let name = node.attribute("name").ok_or_else(|| Error::Parse {
                        what: "URDF".into(),
                        msg: "a <link> has no name".into(),
                    })?;
                    let mut collisions = Vec::new();
                    for c in node
                        .children()
                        .filter(|c| c.is_element() && c.tag_name().name() == "collision")
                    {
                        if let Some(geometry) = parse_geometry(name, c)? {
                            collisions.push(Collision {
                                origin: origin_of(c)?,
                                geometry,
                            });
                        }
                    }
                    let inertial = match child(node, "inertial") {
                        None => None,
                        Some(i) => {
                            let mass = child(i, "mass")
                                .map(|m| required_f64(m, "value"))
                                .transpose()?
                                .unwrap_or(0.0);
                            if mass < 0.0 {
                                return Err(Error::Parse {
                                    what: "URDF".into(),
                                    msg: format!("link '{name}' has negative mass {mass}"),
                                });
                            }
                            let (com, rpy) = match child(i, "origin") {
                                Some(o) => (
                                    vec3_attr(o, "xyz", Vector3::zeros())?,
                                    vec3_attr(o, "rpy", Vector3::zeros())?,
                                ),
                                None => (Vector3::zeros(), Vector3::zeros()),
                            };
                            let inertia = match child(i, "inertia") {
                                None => Matrix3::zeros(),
                                Some(t) => {
                                    let get = |a: &str| -> Result<f64> {
                                        Ok(f64_attr(t, a)?.unwrap_or(0.0))
                                    };
                                    let (xx, xy, xz) = (get("ixx")?, get("ixy")?, get("ixz")?);
                                    let (yy, yz, zz) = (get("iyy")?, get("iyz")?, get("izz")?);
                                    let local = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
                                    let r = rpy_to_rotation(rpy.x, rpy.y, rpy.z)
                                        .to_rotation_matrix()
                                        .into_inner();
                                    r * local * r.transpose()
                                }
                            };
                            Some(Inertial { mass, com, inertia })
                        }
                    };
                    links.push(Link {
                        name: name.to_string(),
                        collisions,
                        inertial,
                    });
                }
                "joint" => joints.push(parse_joint(node)?),
                _ => {}
            }
        }
        if links.is_empty() {
            return Err(Error::Parse {
                what: "URDF".into(),
                msg: "no <link> elements".into(),
            });
        }
        Ok(Urdf {
            name: robot.attribute("name").unwrap_or("").to_string(),
            links,
            joints,
            dir: None,
        })
    }

    /// Read and parse a URDF file.
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
        Ok(urdf)
    }

    /// Resolve a mesh filename: `package://pkg/rest` is looked up as `<dir>/pkg/rest` in each
    /// package dir; `file://` and relative paths are taken from the URDF's folder.
    pub fn resolve_mesh(&self, filename: &str, package_dirs: &[PathBuf]) -> Result<PathBuf> {
        if let Some(rest) = filename.strip_prefix("package://") {
            for dir in package_dirs {
                let p = dir.join(rest);
                if p.is_file() {
                    return Ok(p);
                }
            }
            return Err(Error::Mesh {
                path: PathBuf::from(filename),
                msg: format!(
                    "not found in package dirs [{}]",
                    package_dirs
                        .iter()
                        .map(|d| d.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            });
        }
        let raw = filename.strip_prefix("file://").unwrap_or(filename);
        let p = PathBuf::from(raw);
        let p = if p.is_absolute() {
            p
        } else {
            self.dir.clone().unwrap_or_default().join(p)
        };
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

fn parse_joint(node: roxmltree::Node) -> Result<Joint> {
    let name = node.attribute("name").ok_or_else(|| Error::Parse {
        what: "URDF".into(),
        msg: "a <joint> has no name".into(),
    })?;
    let joint_type = match node.attribute("type") {
        Some("fixed") => JointType::Fixed,
        Some("revolute") => JointType::Revolute,
        Some("continuous") => JointType::Continuous,
        Some("prismatic") => JointType::Prismatic,
        Some("floating") => JointType::Floating,
        Some("planar") => JointType::Planar,
        other => {
            return Err(Error::Parse {
                what: "URDF".into(),
                msg: format!("joint '{name}' has unknown type {other:?}"),
            })
        }
    };
    let link_attr = |tag: &str| -> Result<String> {
        child(node, tag)
            .and_then(|n| n.attribute("link"))
            .map(str::to_string)
            .ok_or_else(|| Error::Parse {
                what: "URDF".into(),
                msg: format!("joint '{name}' lacks <{tag} link=...>"),
            })
    };
    let axis = match child(node, "axis") {
        Some(a) => vec3_attr(a, "xyz", Vector3::x())?,
        None => Vector3::x(),
    };
    let (mut lower, mut upper) = (f64::NEG_INFINITY, f64::INFINITY);
    let (mut effort, mut velocity) = (f64::INFINITY, f64::INFINITY);
    if let Some(limit) = child(node, "limit") {
        if matches!(joint_type, JointType::Revolute | JointType::Prismatic) {
            lower = f64_attr(limit, "lower")?.unwrap_or(0.0);
            upper = f64_attr(limit, "upper")?.unwrap_or(0.0);
        }
        effort = f64_attr(limit, "effort")?.unwrap_or(f64::INFINITY);
        velocity = f64_attr(limit, "velocity")?.unwrap_or(f64::INFINITY);
    }
    Ok(Joint {
        name: name.to_string(),
        joint_type,
        parent: link_attr("parent")?,
        child: link_attr("child")?,
        origin: origin_of(node)?,
        axis,
        lower,
        upper,
        effort,
        velocity,
    })
}

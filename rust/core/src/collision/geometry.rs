//! Robot collision geometry from the URDF's `<collision>` elements: primitives become parry
//! shapes, meshes (STL, OBJ, Collada) the convex hull of their vertices ([`load_mesh_vertices`]); each piece is a
//! [`RobotGeometry`] with the bounding volumes the broad phase uses.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder, SharedShape};

use super::Hull;
use crate::error::{Error, Result};
use crate::kinematics::KinematicModel;
use crate::urdf::{Geometry, Urdf};

/// One piece of robot collision geometry, rigidly attached to a link.
#[derive(Clone)]
pub struct RobotGeometry {
    /// `<link>_<i>`, the i-th `<collision>` of the link (Pinocchio's naming).
    pub name: String,
    /// Index of the link it is attached to.
    pub link: usize,
    /// Pose of the shape in the link frame (includes the cylinder axis change y -> z).
    pub offset: Isometry3<f64>,
    /// The parry shape, in its own frame.
    pub shape: SharedShape,
    /// Bounding sphere in the shape frame: centre and radius.
    pub(super) center: Point3<f64>,
    pub(super) radius: f64,
    /// Bounding box in the shape frame (moved to the world per query: a cheap, tight broadphase).
    pub(super) local_aabb: Aabb,
}

/// The bounding sphere of a shape in its own frame: centre and radius.
pub(super) fn bounding_sphere(shape: &SharedShape) -> (Point3<f64>, f64) {
    let s = shape.compute_local_bounding_sphere();
    (s.center, s.radius)
}

/// The vertices of a mesh file (STL, OBJ or Collada, read by [`crate::mesh::read_mesh`]), scaled;
/// at least 4 finite ones (a convex hull needs them).
pub fn load_mesh_vertices(path: &Path, scale: &Vector3<f64>) -> Result<Vec<Point3<f64>>> {
    let mesh = crate::mesh::read_mesh(path)?;
    let points: Vec<Point3<f64>> =
        mesh.vertices.iter().map(|v| Point3::new(v.x * scale.x, v.y * scale.y, v.z * scale.z)).collect();
    if points.len() < 4 || points.iter().any(|p| !p.coords.iter().all(|c| c.is_finite())) {
        return Err(Error::Mesh {
            path: path.to_path_buf(),
            msg: format!("{} vertices, need at least 4 finite ones", points.len()),
        });
    }
    Ok(points)
}

fn positive(what: &str, link: &str, v: f64) -> Result<f64> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(Error::Invalid(format!(
            "link '{link}': {what} must be positive, got {v}"
        )))
    }
}

/// Convert a URDF geometry to a parry shape and the extra local transform it needs.
fn shape_of(
    urdf: &Urdf,
    link: &str,
    geometry: &Geometry,
    package_dirs: &[PathBuf],
    hull_cache: &mut HashMap<(PathBuf, [u64; 3]), SharedShape>,
) -> Result<(SharedShape, Isometry3<f64>)> {
    // URDF cylinders and capsules run along z; parry's along y. Rx(+90 deg) maps y to z.
    let y_to_z = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
    );
    Ok(match geometry {
        Geometry::Box { size } => {
            for k in 0..3 {
                positive("box size", link, size[k])?;
            }
            (
                SharedShape::new(Cuboid::new(size / 2.0)),
                Isometry3::identity(),
            )
        }
        Geometry::Sphere { radius } => (
            SharedShape::new(Ball::new(positive("sphere radius", link, *radius)?)),
            Isometry3::identity(),
        ),
        Geometry::Cylinder { radius, length } => (
            SharedShape::new(Cylinder::new(
                positive("cylinder length", link, *length)? / 2.0,
                positive("cylinder radius", link, *radius)?,
            )),
            y_to_z,
        ),
        Geometry::Capsule { radius, length } => (
            SharedShape::new(Capsule::new_y(
                positive("capsule length", link, *length)? / 2.0,
                positive("capsule radius", link, *radius)?,
            )),
            y_to_z,
        ),
        Geometry::Mesh { filename, scale } => {
            let path = urdf.resolve_mesh(filename, package_dirs)?;
            let key = (path.clone(), [scale.x.to_bits(), scale.y.to_bits(), scale.z.to_bits()]);
            if let Some(s) = hull_cache.get(&key) {
                return Ok((s.clone(), Isometry3::identity()));
            }
            let points = load_mesh_vertices(&path, scale)?;
            let hull = Hull::from_points(&points).map(SharedShape::new).ok_or_else(|| Error::Mesh {
                path: path.clone(),
                msg: "convex hull failed (degenerate mesh?)".into(),
            })?;
            hull_cache.insert(key, hull.clone());
            (hull, Isometry3::identity())
        }
    })
}

/// Every `<collision>` of the URDF's links (the links must be the model's), in link order.
pub(super) fn robot_geometries(model: &KinematicModel, urdf: &Urdf, package_dirs: &[PathBuf]) -> Result<Vec<RobotGeometry>> {
    let mut geometries = Vec::new();
    let mut cache = HashMap::new();
    for link in &urdf.links {
        if link.collisions.is_empty() {
            continue;
        }
        let li = model.link_index(&link.name)?;
        for (i, c) in link.collisions.iter().enumerate() {
            let (shape, extra) = shape_of(urdf, &link.name, &c.geometry, package_dirs, &mut cache)?;
            let (center, radius) = bounding_sphere(&shape);
            let local_aabb = shape.compute_local_aabb();
            geometries.push(RobotGeometry {
                name: format!("{}_{}", link.name, i),
                link: li,
                offset: c.origin * extra,
                shape,
                center,
                radius,
                local_aabb,
            });
        }
    }
    Ok(geometries)
}

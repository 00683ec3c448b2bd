//! The collision world: the robot's geometry, its self-collision pairs and the obstacles
//! ([`CollisionWorld`]), and the queries on it (in collision?, signed minimum distance, close
//! pairs), with their reusable buffers ([`Scratch`]).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::query;
use parry3d_f64::query::gjk::{CSOPoint, VoronoiSimplex};
use parry3d_f64::query::details::intersection_test_support_map_support_map_with_params;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder, HalfSpace, SharedShape};

use super::broad_phase::{self_pairs, Obb, Target};
use super::groups::{GroupPair, LinkGroups};
use super::obstacles::Obstacles;
use super::geometry::{bounding_sphere, has_mesh, inside_solid, intersects, mesh_shape, robot_geometries};
use super::{Cloud, Hull, MeshShape, RobotGeometry};
use crate::error::{check_finite, check_vector, unknown, Error, Result};
use crate::lie::{stable_norm, unit_vector};
use crate::kinematics::KinematicModel;
use crate::srdf::Srdf;
use crate::urdf::Urdf;

/// The largest size of an obstacle (a box's half extent, a sphere's, cylinder's or capsule's
/// radius, a cylinder's half height, a capsule's half length, a mesh's scale and the largest
/// coordinate of its scaled vertices) and the largest absolute coordinate of its position (a
/// shape's centre, a half-space's offset): 1e6 m.
/// Beyond it the narrow phase's squared norms lose every digit of a robot-sized distance (and
/// overflow past ~1e154).
pub const MAX_OBSTACLE_EXTENT: f64 = 1e6;

/// A half-space normal no longer than this (computed without overflow or underflow) is refused
/// as zero.
pub const MIN_NORMAL_NORM: f64 = 1e-12;

/// How far the rotation of an obstacle's pose may be from a unit quaternion (| |q| - 1 |).
pub const QUATERNION_TOLERANCE: f64 = 1e-6;

/// The largest clearance margin a world or an obstacle may ask for (m).
pub const MAX_PADDING: f64 = 10.0;

/// An environment obstacle, fixed in the world.
#[derive(Clone)]
pub struct Obstacle {
    /// Its unique name in the world.
    pub name: String,
    /// Pose of the parry shape in the world. For a cylinder this is the pose it was added with
    /// composed with the rotation that takes parry's cylinder axis (local y) to the caller's
    /// local z ([`CollisionWorld::add_cylinder`]); for every other shape it is the pose given.
    pub pose: Isometry3<f64>,
    /// The parry shape, in its own frame.
    pub shape: SharedShape,
    /// World bounding sphere (infinite radius for a half-space).
    pub(super) center: Point3<f64>,
    pub(super) radius: f64,
    /// World bounding box (None for a half-space).
    pub(super) aabb: Option<Aabb>,
    /// World oriented bounding box: the shape's local box at its pose (None for a half-space).
    pub(super) obb: Option<Obb>,
    /// For a half-space {x : n.x <= offset}: its unit normal n and offset (None otherwise).
    pub(super) plane: Option<(Vector3<f64>, f64)>,
    /// For a point cloud ([`CollisionWorld::add_points`]): its radius, voxel and size (None for
    /// every other obstacle).
    pub cloud: Option<Cloud>,
    /// The clearance the robot keeps from this obstacle (m); None: the world's
    /// ([`CollisionWorld::padding`]). Set by [`CollisionWorld::set_obstacle_padding`].
    pub padding: Option<f64>,
}

impl Obstacle {
    /// How far a sphere (world centre `c`, radius `r`) stands above this half-space's plane
    /// (negative when it reaches below it); None for an obstacle that is not a half-space.
    #[inline]
    pub(super) fn plane_clearance(&self, c: &Point3<f64>, r: f64) -> Option<f64> {
        self.plane.map(|(n, offset)| n.dot(&c.coords) - offset - r)
    }
}

/// The answer to a distance query about one pair.
#[derive(Debug, Clone, PartialEq)]
pub struct PairDistance {
    /// Name of the robot geometry.
    pub a: String,
    /// Name of the other member: a robot geometry or an obstacle.
    pub b: String,
    /// Signed distance: positive apart, negative penetration depth.
    pub distance: f64,
}

/// The robot's collision geometry plus obstacles, answering collision and distance queries.
#[derive(Clone)]
pub struct CollisionWorld {
    /// The robot's kinematics.
    pub model: Arc<KinematicModel>,
    /// The robot's collision geometry ([`geometries`](Self::geometries)).
    pub(super) geometries: Vec<RobotGeometry>,
    /// Self-collision pairs, as indices into `geometries` ([`self_pairs`](Self::self_pairs)).
    pub(super) self_pairs: Vec<(usize, usize)>,
    /// The geometries grouped by link, and the self pairs by link pair (`groups.rs`), built
    /// with the two fields above, which never change afterwards.
    pub(super) groups: LinkGroups,
    /// The obstacles, in the order they were added, with the hierarchy over them (read-only:
    /// they change through `add_*`, [`remove_obstacle`](Self::remove_obstacle) and
    /// [`clear_obstacles`](Self::clear_obstacles)).
    pub obstacles: Obstacles,
    /// Check self-collision (default true).
    pub check_self: bool,
    /// The clearance the robot keeps from every obstacle without a padding of its own (m, >= 0;
    /// default 0): [`padding`](Self::padding), [`set_padding`](Self::set_padding).
    pub(super) padding: f64,
    /// The objects attached to the robot's links ([`attach`](Self::attach)), in the order
    /// attached: each is one more robot geometry.
    pub(super) attached: Vec<super::Attached>,
}

impl CollisionWorld {
    /// Build from the URDF that holds the collision geometry (its links must be the model's),
    /// and an optional SRDF whose disabled pairs are removed.
    pub fn from_urdf(
        model: Arc<KinematicModel>,
        urdf: &Urdf,
        package_dirs: &[PathBuf],
        srdf: Option<&Srdf>,
    ) -> Result<CollisionWorld> {
        Self::from_urdf_with(model, urdf, package_dirs, srdf, MeshShape::Hull)
    }

    /// [`from_urdf`](Self::from_urdf) with the robot's meshes made into `meshes` shapes
    /// ([`MeshShape`]: a robot file's `mesh_shape`).
    pub fn from_urdf_with(
        model: Arc<KinematicModel>,
        urdf: &Urdf,
        package_dirs: &[PathBuf],
        srdf: Option<&Srdf>,
        meshes: MeshShape,
    ) -> Result<CollisionWorld> {
        let geometries = robot_geometries(&model, urdf, package_dirs, meshes)?;
        let self_pairs = self_pairs(&model, &geometries, srdf);
        let groups = LinkGroups::new(&geometries, &self_pairs);
        Ok(CollisionWorld {
            model,
            geometries,
            self_pairs,
            groups,
            obstacles: Obstacles::default(),
            check_self: true,
            padding: 0.0,
            attached: Vec::new(),
        })
    }

    /// The robot's collision geometry (fixed when the world is built).
    pub fn geometries(&self) -> &[RobotGeometry] {
        &self.geometries
    }

    /// The self-collision pairs, as indices into [`geometries`](Self::geometries) (fixed when
    /// the world is built; [`check_self`](Self::check_self) turns them off).
    pub fn self_pairs(&self) -> &[(usize, usize)] {
        &self.self_pairs
    }

    fn add_obstacle(&mut self, name: &str, pose: Isometry3<f64>, shape: SharedShape) -> Result<()> {
        if self.obstacles.iter().any(|o| o.name == name) {
            return Err(Error::Invalid(format!("an obstacle named '{name}' already exists")));
        }
        self.obstacles.push(Self::make_obstacle(name, pose, shape));
        Ok(())
    }

    /// An obstacle with its bounding volumes (not a cloud: the caller sets [`Obstacle::cloud`]).
    pub(super) fn make_obstacle(name: &str, pose: Isometry3<f64>, shape: SharedShape) -> Obstacle {
        let (c, r, aabb, obb) = if shape.as_halfspace().is_some() {
            (Point3::origin(), f64::INFINITY, None, None)
        } else {
            let (c, r) = bounding_sphere(&shape);
            (pose * c, r, Some(shape.compute_aabb(&pose)), Some(Obb::new(&shape.compute_local_aabb(), &pose)))
        };
        let plane = shape.as_halfspace().map(|h| {
            let n = pose.rotation * h.normal.into_inner();
            (n, n.dot(&pose.translation.vector))
        });
        Obstacle { name: name.to_string(), pose, shape, center: c, radius: r, aabb, obb, plane, cloud: None, padding: None }
    }

    /// Add a box with the given half extents at `pose`: the half extents positive, finite and at
    /// most [`MAX_OBSTACLE_EXTENT`], the centre finite and within [`MAX_OBSTACLE_EXTENT`] of the
    /// origin in each coordinate, the rotation a unit quaternion (within
    /// [`QUATERNION_TOLERANCE`]).
    pub fn add_box(&mut self, name: &str, half_extents: [f64; 3], pose: Isometry3<f64>) -> Result<()> {
        let what = format!("box '{name}'");
        check_finite(&format!("{what} half extents"), &half_extents)?;
        if half_extents.iter().any(|&h| !(h > 0.0 && h <= MAX_OBSTACLE_EXTENT)) {
            return Err(Error::Invalid(format!(
                "{what}: half extents must be positive and at most {MAX_OBSTACLE_EXTENT:e} m, got {half_extents:?}"
            )));
        }
        check_isometry(&what, &pose)?;
        self.add_obstacle(name, pose, SharedShape::new(Cuboid::new(Vector3::from(half_extents))))
    }

    /// Add a sphere: the radius positive, finite and at most [`MAX_OBSTACLE_EXTENT`], the centre
    /// finite and within [`MAX_OBSTACLE_EXTENT`] of the origin in each coordinate.
    pub fn add_sphere(&mut self, name: &str, radius: f64, center: [f64; 3]) -> Result<()> {
        let what = format!("sphere '{name}'");
        check_vector(&format!("{what} centre"), &center, 3)?;
        if !(radius > 0.0 && radius <= MAX_OBSTACLE_EXTENT) {
            return Err(Error::Invalid(format!(
                "{what}: radius must be positive and at most {MAX_OBSTACLE_EXTENT:e} m, got {radius:?}"
            )));
        }
        check_position(&what, "centre", &center)?;
        self.add_obstacle(
            name,
            Isometry3::translation(center[0], center[1], center[2]),
            SharedShape::new(Ball::new(radius)),
        )
    }

    /// Add a solid cylinder of `radius` whose axis is the local z axis of `pose` (as in URDF and
    /// coal), spanning z in [-half_height, half_height] about the pose's origin. parry's cylinder
    /// runs along its local y, so the stored [`Obstacle::pose`] is `pose` composed with the
    /// rotation Rx(+90 deg) that maps y to z (the same change `geometry.rs` makes for URDF
    /// cylinders). Radius and half height positive, finite and at most [`MAX_OBSTACLE_EXTENT`];
    /// the pose checked as [`add_box`](Self::add_box)'s.
    pub fn add_cylinder(&mut self, name: &str, radius: f64, half_height: f64, pose: Isometry3<f64>) -> Result<()> {
        let what = format!("cylinder '{name}'");
        check_sizes(&what, &[("radius", radius), ("half height", half_height)])?;
        check_isometry(&what, &pose)?;
        self.add_obstacle(name, pose * y_to_z(), SharedShape::new(Cylinder::new(half_height, radius)))
    }

    /// Add a capsule (the points within `radius` of a segment) whose segment runs along the local
    /// z axis of `pose` from z = -half_length to z = +half_length (as in URDF and coal; parry's
    /// `Capsule::new_z`, so the stored pose is `pose` itself). Radius and half length positive,
    /// finite and at most [`MAX_OBSTACLE_EXTENT`]; the pose checked as [`add_box`](Self::add_box)'s.
    pub fn add_capsule(&mut self, name: &str, radius: f64, half_length: f64, pose: Isometry3<f64>) -> Result<()> {
        let what = format!("capsule '{name}'");
        check_sizes(&what, &[("radius", radius), ("half length", half_length)])?;
        check_isometry(&what, &pose)?;
        self.add_obstacle(name, pose, SharedShape::new(Capsule::new_z(half_length, radius)))
    }

    /// Add the **convex hull** of a mesh file's vertices (STL, OBJ or Collada, read by
    /// [`crate::mesh::read_mesh`] through [`load_mesh_vertices`](crate::collision::load_mesh_vertices), as the robot's mesh geometry is:
    /// a concave mesh is filled in), each vertex scaled per axis by `scale` in the file's frame,
    /// then placed at `pose`. The scale positive, finite and at most [`MAX_OBSTACLE_EXTENT`]; the
    /// scaled vertices within [`MAX_OBSTACLE_EXTENT`] of the file's origin in each coordinate;
    /// the pose checked as [`add_box`](Self::add_box)'s. A file that cannot be read gives
    /// [`Error::Io`], one that is malformed or has fewer than 4 vertices
    /// [`Error::Mesh`]; both name the file. A flat mesh gives a plate of zero thickness.
    pub fn add_mesh(&mut self, name: &str, path: &Path, scale: [f64; 3], pose: Isometry3<f64>) -> Result<()> {
        self.add_mesh_as(name, path, scale, pose, MeshShape::Hull)
    }

    /// [`add_mesh`](Self::add_mesh) with the mesh made into the shape `kind` says
    /// ([`MeshShape`]: its convex hull, the triangles themselves (a closed mesh a solid, an open
    /// one a surface) or V-HACD's convex parts); a mesh that cannot be made into that shape gives
    /// [`Error::Mesh`] naming the file.
    pub fn add_mesh_as(&mut self, name: &str, path: &Path, scale: [f64; 3], pose: Isometry3<f64>, kind: MeshShape) -> Result<()> {
        let what = format!("mesh '{name}'");
        check_finite(&format!("{what} scale"), &scale)?;
        if scale.iter().any(|&s| !(s > 0.0 && s <= MAX_OBSTACLE_EXTENT)) {
            return Err(Error::Invalid(format!(
                "{what}: scale must be positive and at most {MAX_OBSTACLE_EXTENT:e}, got {scale:?}"
            )));
        }
        check_isometry(&what, &pose)?;
        if self.obstacles.iter().any(|o| o.name == name) {
            // refused before the (possibly slow) file read; add_obstacle checks again
            return Err(Error::Invalid(format!("an obstacle named '{name}' already exists")));
        }
        let mesh = crate::mesh::read_mesh(path)?.scaled(&Vector3::from(scale));
        if let Some(p) = mesh.vertices.iter().find(|p| p.coords.amax() > MAX_OBSTACLE_EXTENT) {
            return Err(Error::Mesh {
                path: path.to_path_buf(),
                msg: format!("{what}: a scaled vertex {:?} lies beyond {MAX_OBSTACLE_EXTENT:e} m", p.coords.as_slice()),
            });
        }
        let shape = mesh_shape(&mesh, kind, path).map_err(|e| match e {
            Error::Mesh { path, msg } => Error::Mesh { path, msg: format!("{what} (shape \"{}\"): {msg}", kind.name()) },
            e => e,
        })?;
        self.add_obstacle(name, pose, shape)
    }

    /// Add the half-space {x : n.x <= offset} (everything below the plane n.x = offset), `n`
    /// the unit vector along `normal`: `normal` finite and not zero (its norm, computed without
    /// overflow, above [`MIN_NORMAL_NORM`]; any larger finite length is fine), `offset`
    /// finite and at most [`MAX_OBSTACLE_EXTENT`] in absolute value.
    pub fn add_halfspace(&mut self, name: &str, normal: [f64; 3], offset: f64) -> Result<()> {
        let what = format!("plane '{name}'");
        check_finite(&format!("{what} normal"), &normal)?;
        check_finite(&format!("{what} offset"), &[offset])?;
        if offset.abs() > MAX_OBSTACLE_EXTENT {
            return Err(Error::Invalid(format!(
                "{what}: offset must be at most {MAX_OBSTACLE_EXTENT:e} m in absolute value, got {offset:?}"
            )));
        }
        let n = unit_normal(&normal).ok_or_else(|| Error::Invalid(format!("{what}: the normal is zero")))?;
        let pose = Isometry3::translation(n.x * offset, n.y * offset, n.z * offset);
        self.add_obstacle(name, pose, SharedShape::new(HalfSpace::new(n)))
    }

    /// Remove every obstacle.
    pub fn clear_obstacles(&mut self) {
        self.obstacles.clear();
    }

    /// Remove an obstacle by name.
    pub fn remove_obstacle(&mut self, name: &str) -> Result<()> {
        match self.obstacles.iter().position(|o| o.name == name) {
            Some(i) => {
                self.obstacles.remove(i);
                Ok(())
            }
            None => {
                let known: Vec<&str> = self.obstacles.iter().map(|o| o.name.as_str()).collect();
                Err(unknown("obstacle", name, &known))
            }
        }
    }

    /// The clearance the robot keeps from every obstacle that has no padding of its own (m).
    pub fn padding(&self) -> f64 {
        self.padding
    }

    /// Set the world's padding ([`padding`](Self::padding)): finite, >= 0 and at most
    /// [`MAX_PADDING`]. Every check of the robot's geometry (its links and attached objects)
    /// against the obstacles then counts a pair closer than its obstacle's padding as a
    /// collision: [`in_collision`](Self::in_collision) and
    /// [`clear_by`](Self::clear_by) (certified motions); distances
    /// ([`min_distance`](Self::min_distance), [`close_pairs`](Self::close_pairs)) stay the
    /// geometric ones. Self pairs are not padded.
    pub fn set_padding(&mut self, padding: f64) -> Result<()> {
        self.padding = check_padding("padding", padding)?;
        Ok(())
    }

    /// Set obstacle `name`'s own padding (checked as [`set_padding`](Self::set_padding)'s),
    /// which replaces the world's for it; None: the world's again. An unknown name lists the
    /// obstacles.
    pub fn set_obstacle_padding(&mut self, name: &str, padding: Option<f64>) -> Result<()> {
        let Some(i) = self.obstacles.iter().position(|o| o.name == name) else {
            let known: Vec<&str> = self.obstacles.iter().map(|o| o.name.as_str()).collect();
            return Err(unknown("obstacle", name, &known));
        };
        let padding = padding.map(|p| check_padding(&format!("obstacle '{name}' padding"), p)).transpose()?;
        let mut o = self.obstacles[i].clone();
        o.padding = padding;
        self.obstacles.replace(i, o);
        Ok(())
    }

    /// The clearance the robot keeps from obstacle `k`: its own padding, else the world's.
    #[inline]
    pub(super) fn obstacle_padding(&self, k: usize) -> f64 {
        self.obstacles[k].padding.unwrap_or(self.padding)
    }

    /// The largest padding of any obstacle (0 without obstacles or padding).
    fn max_padding(&self) -> f64 {
        (0..self.obstacles.len()).map(|k| self.obstacle_padding(k)).fold(0.0, f64::max)
    }

    /// World poses and bounding boxes of the robot geometries for a checked q.
    pub(super) fn geometry_poses(&self, q: &[f64], s: &mut Scratch) {
        self.model.forward_kinematics_unchecked(q, &mut s.links);
        s.resize(self.geometries.len(), self.groups.groups.len());
        for i in 0..self.geometries.len() {
            self.pose_geometry(i, s);
        }
        self.place_group_spheres(s);
    }

    /// The world centres of the link groups' spheres (`s.group_centers`), from the link poses.
    #[inline]
    fn place_group_spheres(&self, s: &mut Scratch) {
        s.group_centers.clear();
        for g in &self.groups.groups {
            s.group_centers.push(s.links[g.link] * g.center);
        }
    }

    /// World pose, oriented box and world box of geometry `i` from the link poses in `s`.
    #[inline]
    fn pose_geometry(&self, i: usize, s: &mut Scratch) {
        let g = &self.geometries[i];
        let pose = s.links[g.link] * g.offset;
        let obb = Obb::new(&g.local_aabb, &pose);
        s.aabbs[i] = obb.aabb();
        s.obbs[i] = obb;
        s.poses[i] = pose;
        s.posed[i] = true;
    }

    /// Pose the geometries of link group `k` that are not posed yet.
    #[inline]
    fn pose_group(&self, k: usize, s: &mut Scratch) {
        for &i in &self.groups.groups[k].geometries {
            if !s.posed[i] {
                self.pose_geometry(i, s);
            }
        }
    }

    /// Compute the oriented box of link group `k` unless this query already has.
    #[inline]
    fn group_obb(&self, k: usize, s: &mut Scratch) {
        if !s.group_obb_done[k] {
            let g = &self.groups.groups[k];
            s.group_obbs[k] = Obb::new(&g.local_aabb, &s.links[g.link]);
            s.group_obb_done[k] = true;
        }
    }

    /// Do the oriented boxes of the two link groups of `gp` overlap (their spheres do)?
    #[inline(always)]
    fn group_boxes_touch(&self, gp: &GroupPair, s: &mut Scratch) -> bool {
        let (a, b) = (gp.a as usize, gp.b as usize);
        self.group_obb(a, s);
        self.group_obb(b, s);
        !s.group_obbs[a].separated(&s.group_obbs[b])
    }

    /// True when obstacle `k` is a half-space and robot geometry `i` (bounding sphere centred at
    /// `ca`, then its oriented box) stands more than `margin` above its plane.
    #[inline]
    fn above_plane(&self, i: usize, ca: &Point3<f64>, k: usize, margin: f64, s: &Scratch) -> bool {
        let o = &self.obstacles[k];
        o.plane_clearance(ca, self.geometries[i].radius).is_some_and(|h| h > margin)
            || o.plane.is_some_and(|(n, offset)| s.obbs[i].lowest_along(&n) - offset > margin)
    }

    /// Does robot geometry `i` intersect target `t`? The bounding-volume filters (boxes, spheres,
    /// oriented boxes), then the exact narrow phase.
    #[inline]
    pub(super) fn pair_intersects(&self, i: usize, t: Target, s: &Scratch) -> bool {
        !self.ruled_out(i, t, s) && self.narrow_phase(i, t, s)
    }

    /// parry's intersection test of robot geometry `i` and target `t` at their poses in `s`.
    #[inline]
    fn narrow_phase(&self, i: usize, t: Target, s: &Scratch) -> bool {
        if let Some(hit) = self.cloud_within(i, t, 0.0, s) {
            return hit;
        }
        let (pose_b, shape_b, _, _) = self.target(t, &s.poses);
        // Unsupported shape pairs cannot occur with the shapes built here; `intersects` counts
        // them as colliding to stay on the safe side (and a closed mesh as a solid).
        intersects(&s.poses[i], &*self.geometries[i].shape, &pose_b, &**shape_b)
    }

    /// Does self pair `k` of the link groups' order (geometries `i` and `j`) intersect? As
    /// [`pair_intersects`](Self::pair_intersects), except that two hulls are first tested along
    /// the last [`AXES`] axes that separated them (`Scratch::axes`, in `i`'s frame, most recently
    /// useful first): two support points prove the pair apart along an axis, where GJK takes
    /// several (the test is GJK's own for one axis, and an axis only ever proves a pair apart).
    /// Otherwise GJK, started from the first axis, answers, and the axis it separates them by
    /// goes first. `filter`: whether to apply the pair's bounding-volume filters first (they
    /// can only rule a pair out, so skipping them never changes the answer).
    #[inline]
    fn self_pair_intersects(&self, i: usize, j: usize, k: usize, filter: bool, s: &mut Scratch) -> bool {
        if filter && self.ruled_out(i, Target::Robot(j), s) {
            return false;
        }
        let (a, b) = (&*self.geometries[i].shape, &*self.geometries[j].shape);
        let (Some(ha), Some(hb)) = (a.as_shape::<Hull>(), b.as_shape::<Hull>()) else {
            return self.narrow_phase(i, Target::Robot(j), s);
        };
        let pos12 = s.poses[i].inv_mul(&s.poses[j]);
        for m in 0..AXES {
            let Some(d) = Unit::try_new(s.axes[k][m], 1e-12) else { break };
            // a's highest point along d below b's lowest: apart
            if d.dot(&CSOPoint::from_shapes(&pos12, ha, hb, &d).point.coords) < 0.0 {
                s.axes[k][..=m].rotate_right(1);
                return false;
            }
        }
        let cached = Unit::try_new(s.axes[k][0], 1e-12);
        let (hit, dir) = intersection_test_support_map_support_map_with_params(&pos12, ha, hb, &mut VoronoiSimplex::new(), cached);
        if !hit {
            s.axes[k].rotate_right(1);
            s.axes[k][0] = dir.into_inner();
        }
        hit
    }

    /// The bounding-volume filters of a pair (boxes, spheres, oriented boxes, a half-space's
    /// plane): true when they prove robot geometry `i` and target `t` apart.
    #[inline]
    fn ruled_out(&self, i: usize, t: Target, s: &Scratch) -> bool {
        if !self.may_touch(i, t, s, 0.0) {
            return true;
        }
        let g = &self.geometries[i];
        let (_, _, cb, rb) = self.target(t, &s.poses);
        let ca = s.poses[i] * g.center;
        if rb.is_finite() && (ca - cb).norm() > g.radius + rb {
            return true;
        }
        if let Target::Obstacle(k) = t {
            if self.above_plane(i, &ca, k, 0.0, s) {
                return true;
            }
        }
        // The shapes' boxes in their own frames are much tighter than world-aligned boxes on
        // tilted links: a separating axis between them rules the pair out before GJK.
        self.target_obb(t, s).is_some_and(|b| s.obbs[i].separated(b))
    }

    /// True when any checked pair intersects.
    pub fn in_collision(&self, q: &[f64]) -> Result<bool> {
        self.model.check_configuration(q)?;
        let mut scratch = Scratch::default();
        Ok(self.in_collision_unchecked(q, &mut scratch))
    }

    /// [`in_collision`](Self::in_collision) without input checks, reusing buffers.
    ///
    /// Link volumes first (`groups.rs`): each link's bounding sphere is placed in the world; a
    /// link is tested against the obstacles whose box meets the box around its sphere (found by
    /// the hierarchy over the obstacles, `obstacles.rs`: first those near the whole robot; when
    /// there are more than 24 of them (`NEAR_LINEAR_MAX`), each link asks for its own), and a
    /// link pair's geometry pairs are tested only when the links' spheres and oriented boxes
    /// overlap. A link's geometries are posed when first needed. Each geometry pair left goes
    /// through the same filters and narrow phase as in an exhaustive loop, and the link volumes
    /// contain their geometries, so the answer is the exhaustive loop's.
    pub fn in_collision_unchecked(&self, q: &[f64], s: &mut Scratch) -> bool {
        self.model.forward_kinematics_unchecked(q, &mut s.links);
        let groups = &self.groups.groups;
        s.resize(self.geometries.len(), groups.len());
        self.place_group_spheres(s);
        let pad = self.max_padding();
        if pad > 0.0 {
            // padded obstacles: the clearance test of certified motions, every geometry posed,
            // each pair against its obstacle's padding
            for i in 0..self.geometries.len() {
                self.pose_geometry(i, s);
            }
            if !self.obstacles_clear_by(None, pad, s) {
                return true;
            }
            return self.check_self && self.collides_with_itself(s);
        }
        let mut robot = Aabb::new_invalid();
        for (g, c) in groups.iter().zip(&s.group_centers) {
            robot.merge(&sphere_aabb(c, g.radius));
        }
        if self.collides_with_obstacles(&robot, s) {
            return true;
        }
        self.check_self && self.collides_with_itself(s)
    }

    /// The obstacle part of [`in_collision_unchecked`](Self::in_collision_unchecked), after its
    /// link spheres are placed (`robot`: the box around them).
    fn collides_with_obstacles(&self, robot: &Aabb, s: &mut Scratch) -> bool {
        let mut near = std::mem::take(&mut s.near);
        self.obstacles.overlapping(robot, &mut near);
        let mut mine = std::mem::take(&mut s.candidates);
        let mut hit = false;
        if !near.is_empty() {
            'groups: for (k, g) in self.groups.groups.iter().enumerate() {
                let (c, r) = (s.group_centers[k], g.radius);
                let b = sphere_aabb(&c, r);
                let list = if near.len() <= NEAR_LINEAR_MAX {
                    &near
                } else {
                    self.obstacles.overlapping(&b, &mut mine);
                    &mine
                };
                for &o in list {
                    let obstacle = &self.obstacles[o];
                    if let Some(ob) = &obstacle.aabb {
                        let rr = r + obstacle.radius;
                        if !b.intersects(ob) || (c - obstacle.center).norm_squared() > rr * rr {
                            continue;
                        }
                    } else if obstacle.plane_clearance(&c, r).is_some_and(|h| h > 0.0) {
                        continue;
                    }
                    // a cloud: the link's sphere against the cloud's clearance field
                    if obstacle.cloud.is_some() && self.cloud_clears(o, &c, r, 0.0) {
                        continue;
                    }
                    if let Some(ob) = &obstacle.obb {
                        self.group_obb(k, s);
                        if s.group_obbs[k].separated(ob) {
                            continue;
                        }
                    }
                    self.pose_group(k, s);
                    for &i in &g.geometries {
                        if self.pair_intersects(i, Target::Obstacle(o), s) {
                            hit = true;
                            break 'groups;
                        }
                    }
                }
            }
        }
        s.near = near;
        s.candidates = mine;
        hit
    }

    /// The self-collision part of [`in_collision_unchecked`](Self::in_collision_unchecked),
    /// after its link spheres are placed. The link pairs are tested in the order of
    /// `Scratch::order`, the pair that was last found in contact first (move to front): a check
    /// that collides stops at its first contact, and contacts recur between the same links (the
    /// states of one edge, a robot's usual self contacts), so the search is short; every pair is
    /// still tested before an answer of no collision, so the answer is the same in any order.
    fn collides_with_itself(&self, s: &mut Scratch) -> bool {
        if s.axes.len() != self.groups.pairs.len() {
            s.axes.clear();
            s.axes.resize(self.groups.pairs.len(), [Vector3::zeros(); AXES]);
        }
        // the link pairs themselves, not indices, so that the sphere tests below (most of the
        // pairs stop there) read one array in order; the copies are this world's (`groups.id`)
        let mut order = std::mem::take(&mut s.order);
        if s.order_of != self.groups.id || order.len() != self.groups.group_pairs.len() {
            order.clear();
            order.extend_from_slice(&self.groups.group_pairs);
            s.order_of = self.groups.id;
        }
        let centers = std::mem::take(&mut s.group_centers);
        let mut hit = None;
        'blocks: for (b, block) in order.chunks(BLOCK).enumerate() {
            let mut near = spheres_overlapping(block, &centers);
            while near != 0 {
                let p = near.trailing_zeros() as usize;
                near &= near - 1;
                if self.link_pair_intersects(&block[p], s) {
                    hit = Some(b * BLOCK + p);
                    break 'blocks;
                }
            }
        }
        s.group_centers = centers;
        if let Some(p) = hit {
            order[..=p].rotate_right(1);
        }
        s.order = order;
        hit.is_some()
    }

    /// Does any self pair of link pair `gp` intersect, its groups' spheres overlapping? Their
    /// oriented boxes, then each geometry pair.
    #[inline(always)]
    fn link_pair_intersects(&self, gp: &GroupPair, s: &mut Scratch) -> bool {
        if !self.group_boxes_touch(gp, s) {
            return false;
        }
        self.pose_group(gp.a as usize, s);
        self.pose_group(gp.b as usize, s);
        // two links of one shape each: the links' box and sphere are built around the shape's
        // own, and have just been found to overlap, so the pair's filters would mostly repeat
        // those tests (skipping filters never changes the answer; every Talos link has one shape)
        let filter = self.groups.groups[gp.a as usize].geometries.len() > 1 || self.groups.groups[gp.b as usize].geometries.len() > 1;
        for k in gp.start as usize..gp.end as usize {
            let (i, j) = self.groups.pairs[k];
            if self.self_pair_intersects(i, j, k, filter, s) {
                return true;
            }
        }
        false
    }

    /// [`in_collision`](Self::in_collision) with every pair through the exact narrow phase (no
    /// bounding-volume filters): the reference the filtered check is tested against.
    pub fn in_collision_exhaustive(&self, q: &[f64]) -> Result<bool> {
        self.model.check_configuration(q)?;
        let mut s = Scratch::default();
        self.geometry_poses(q, &mut s);
        Ok(self.pair_iter().any(|(i, t)| self.narrow_phase(i, t, &s)))
    }

    /// Signed distance of one pair of shapes (negative: penetration depth).
    fn pair_distance(pa: &Isometry3<f64>, a: &SharedShape, pb: &Isometry3<f64>, b: &SharedShape) -> f64 {
        if query::intersection_test(pa, &**a, pb, &**b).unwrap_or(true) {
            // parry 0.25.3 returns a wrong depth for contact(support map, half-space); the
            // half-space-first order is right (checked in tests/collision.rs).
            let contact = if b.as_halfspace().is_some() {
                query::contact(pb, &**b, pa, &**a, 0.0)
            } else {
                query::contact(pa, &**a, pb, &**b, 0.0)
            };
            match contact {
                Ok(Some(c)) => c.dist.min(0.0),
                _ => 0.0,
            }
        } else {
            let d = query::distance(pa, &**a, pb, &**b).unwrap_or(0.0);
            // wholly inside a closed mesh's solid: at least that deep
            if has_mesh(&**a, &**b) && inside_solid(pa, &**a, pb, &**b) {
                -d
            } else {
                d
            }
        }
    }

    /// Minimum signed distance over all checked pairs (+inf when there is no pair).
    pub fn min_distance(&self, q: &[f64]) -> Result<f64> {
        self.model.check_configuration(q)?;
        let mut s = Scratch::default();
        Ok(self.min_distance_unchecked(q, &mut s))
    }

    /// [`min_distance`](Self::min_distance) without input checks, reusing buffers.
    ///
    /// Obstacle pairs are visited in the exhaustive loop's order (each geometry in turn against
    /// the obstacles in index order) and skipped by the same tests; the hierarchy over the
    /// obstacles only leaves out, for each geometry, the obstacles whose box is already farther
    /// than the best distance so far (which that loop would skip too). The first geometry's
    /// list, asked for before any distance is known, is asked for again after the first one.
    /// Self pairs are visited link pair by link pair (`groups.rs`), skipping the link pairs
    /// whose spheres are at least the best distance so far apart. Every pair left out is one
    /// whose lower bound cannot beat the minimum, so the value is the exhaustive loop's (to the
    /// narrow phase's rounding: tests/collision_broad_phase.rs).
    pub fn min_distance_unchecked(&self, q: &[f64], s: &mut Scratch) -> f64 {
        self.geometry_poses(q, s);
        let mut best = f64::INFINITY;
        let mut cands = std::mem::take(&mut s.candidates);
        for i in 0..self.geometries.len() {
            let mut from = 0;
            loop {
                let bound = best;
                self.obstacles.within(&s.aabbs[i], bound, from, &mut cands);
                let mut again = false;
                for &k in &cands {
                    best = self.pair_min_distance(i, Target::Obstacle(k), s, best);
                    if bound == f64::INFINITY && best < f64::INFINITY {
                        from = k + 1;
                        again = true;
                        break;
                    }
                }
                if !again {
                    break;
                }
            }
        }
        s.candidates = cands;
        if self.check_self {
            // link pairs whose spheres are at least `best` apart hold no closer pair
            let lg = &self.groups;
            for gp in &lg.group_pairs {
                let (a, b) = (gp.a as usize, gp.b as usize);
                let gap = (s.group_centers[a] - s.group_centers[b]).norm() - lg.groups[a].radius - lg.groups[b].radius;
                if gap >= best {
                    continue;
                }
                for &(i, j) in &lg.pairs[gp.start as usize..gp.end as usize] {
                    best = self.pair_min_distance(i, Target::Robot(j), s, best);
                }
            }
        }
        best
    }

    /// `best` lowered to the distance of pair (i, t) unless bounds show it cannot beat `best`.
    #[inline]
    pub(super) fn pair_min_distance(&self, i: usize, t: Target, s: &Scratch, best: f64) -> f64 {
        let g = &self.geometries[i];
        let (pose_b, shape_b, cb, rb) = self.target(t, &s.poses);
        let ca = s.poses[i] * g.center;
        // Lower bounds from the bounding spheres and boxes: skip pairs that cannot beat `best`.
        if rb.is_finite() && (ca - cb).norm() - g.radius - rb >= best {
            return best;
        }
        // The box gap bounds only a separated pair's distance: overlapping boxes (gap 0) may
        // hide a penetration deeper than `best`, so they are never skipped.
        let gap = self.aabb_gap(i, t, s);
        if gap > 0.0 && gap >= best {
            return best;
        }
        let d = self.cloud_distance(i, t, s, best).unwrap_or_else(|| Self::pair_distance(&s.poses[i], &g.shape, &pose_b, shape_b));
        best.min(d)
    }

    /// True when every checked pair is farther apart than its margin: robot geometry i from
    /// every obstacle by more than `geometry[i]`, self pair p (in `self_pairs` order) by more
    /// than `pairs[p]` (margins >= 0; a half-space counts its signed distance). With the margins
    /// of a [`MotionBounds`](super::MotionBounds) sweep halved, true at both ends of a motion
    /// certifies the whole motion collision-free. Conservative where parry cannot answer (a
    /// pair it does not support counts as too close). No input checks: a checked q, one margin
    /// per geometry and per self pair.
    pub fn clear_by(&self, q: &[f64], geometry: &[f64], pairs: &[f64], s: &mut Scratch) -> bool {
        self.pose(q, s);
        self.clear_by_posed(geometry, pairs, s)
    }

    /// Pose the robot's links and geometries at a checked `q` into `s` (for
    /// [`clear_by_posed`](Self::clear_by_posed) and [`MotionBounds::levers`](super::MotionBounds::levers)).
    pub fn pose(&self, q: &[f64], s: &mut Scratch) {
        self.geometry_poses(q, s);
    }

    /// [`clear_by`](Self::clear_by) at the configuration last posed into `s` ([`pose`](Self::pose)).
    /// An obstacle's padding ([`Obstacle::padding`], else the world's [`padding`](Self::padding))
    /// adds to the margin of every pair with it.
    pub fn clear_by_posed(&self, geometry: &[f64], pairs: &[f64], s: &mut Scratch) -> bool {
        debug_assert_eq!(geometry.len(), self.geometries.len());
        debug_assert!(!self.check_self || pairs.len() == self.self_pairs.len());
        if !self.obstacles_clear_by(Some(geometry), self.max_padding(), s) {
            return false;
        }
        if !self.check_self {
            return true;
        }
        let lg = &self.groups;
        lg.group_pairs.iter().all(|gp| {
            let (start, end) = (gp.start as usize, gp.end as usize);
            let m = lg.index[start..end].iter().map(|&p| pairs[p]).fold(0.0, f64::max);
            let (a, b) = (gp.a as usize, gp.b as usize);
            let reach = lg.groups[a].radius + lg.groups[b].radius + m;
            (s.group_centers[a] - s.group_centers[b]).norm_squared() > reach * reach
                || lg.pairs[start..end].iter().zip(&lg.index[start..end]).all(|(&(i, j), &p)| self.far(i, Target::Robot(j), pairs[p], s))
        })
    }

    /// Is robot geometry `i` farther than `m` from target `t` (both posed in `s`)? The bounding
    /// volumes first, then parry's closest points within `m`; conservative where parry cannot
    /// answer.
    fn far(&self, i: usize, t: Target, m: f64, s: &Scratch) -> bool {
        let g = &self.geometries[i];
        let (pose_b, shape_b, cb, rb) = self.target(t, &s.poses);
        let ca = s.poses[i] * g.center;
        if rb.is_finite() && (ca - cb).norm() - g.radius - rb > m {
            return true;
        }
        if self.aabb_gap(i, t, s) > m {
            return true;
        }
        if let Target::Obstacle(k) = t {
            if self.above_plane(i, &ca, k, m, s) {
                return true;
            }
        }
        if let Some(b) = self.target_obb(t, s) {
            if s.obbs[i].separated_by(b, m) {
                return true;
            }
        }
        if let Some(hit) = self.cloud_within(i, t, m, s) {
            return !hit;
        }
        matches!(
            query::closest_points(&s.poses[i], &*g.shape, &pose_b, &**shape_b, m),
            Ok(query::ClosestPoints::Disjoint)
        ) && !(has_mesh(&*g.shape, &**shape_b) && inside_solid(&s.poses[i], &*g.shape, &pose_b, &**shape_b))
    }

    /// The obstacle part of [`clear_by_posed`](Self::clear_by_posed): every robot geometry `i`
    /// farther from every obstacle `k` than `geometry[i]` (0 for None) plus `k`'s padding
    /// (`pad`: the largest padding, which grows the search). Link spheres first (`groups.rs`):
    /// a link whose sphere, grown by its geometries' largest margin and the padding, is clear
    /// of an obstacle's sphere or box is far by every margin of its geometries.
    fn obstacles_clear_by(&self, geometry: Option<&[f64]>, pad: f64, s: &mut Scratch) -> bool {
        let margin = |i: usize| geometry.map_or(0.0, |g| g[i]);
        let mut near = std::mem::take(&mut s.near);
        let mut clear = true;
        'outer: for (k, g) in self.groups.groups.iter().enumerate() {
            let mg = g.geometries.iter().map(|&i| margin(i)).fold(0.0, f64::max);
            let c = s.group_centers[k];
            self.obstacles.overlapping(&sphere_aabb(&c, g.radius + mg + pad), &mut near);
            for &o in &near {
                let obstacle = &self.obstacles[o];
                let mk = mg + self.obstacle_padding(o);
                if obstacle.radius.is_finite() && (c - obstacle.center).norm() - g.radius - obstacle.radius > mk {
                    continue;
                }
                if obstacle.plane_clearance(&c, g.radius).is_some_and(|h| h > mk) {
                    continue;
                }
                if obstacle.cloud.is_some() && self.cloud_clears(o, &c, g.radius, mk) {
                    continue;
                }
                for &i in &g.geometries {
                    let m = margin(i) + self.obstacle_padding(o);
                    if obstacle.aabb.as_ref().is_some_and(|b| !s.aabbs[i].loosened(m).intersects(b)) {
                        continue;
                    }
                    if !self.far(i, Target::Obstacle(o), m, s) {
                        clear = false;
                        break 'outer;
                    }
                }
            }
        }
        s.near = near;
        clear
    }

    /// Every checked pair closer than `margin` (signed distance < margin), with its distance.
    pub fn close_pairs(&self, q: &[f64], margin: f64) -> Result<Vec<PairDistance>> {
        self.model.check_configuration(q)?;
        check_finite("margin", &[margin])?;
        let mut s = Scratch::default();
        self.geometry_poses(q, &mut s);
        // the obstacles whose box meets each geometry's box loosened by the margin (the test of
        // `may_touch`), then the self pairs: the exhaustive loop's order
        let mut pairs = Vec::new();
        let mut near = Vec::new();
        for i in 0..self.geometries.len() {
            let b = if margin > 0.0 { s.aabbs[i].loosened(margin) } else { s.aabbs[i] };
            self.obstacles.overlapping(&b, &mut near);
            pairs.extend(near.iter().map(|&k| (i, Target::Obstacle(k))));
        }
        if self.check_self {
            pairs.extend(self.self_pairs.iter().map(|&(i, j)| (i, Target::Robot(j))));
        }
        let mut out = Vec::new();
        for (i, t) in pairs {
            if !self.may_touch(i, t, &s, margin) {
                continue;
            }
            let g = &self.geometries[i];
            let (pose_b, shape_b, cb, rb) = self.target(t, &s.poses);
            let ca = s.poses[i] * g.center;
            if rb.is_finite() && (ca - cb).norm() - g.radius - rb >= margin {
                continue;
            }
            let d = self.cloud_distance(i, t, &s, margin).unwrap_or_else(|| Self::pair_distance(&s.poses[i], &g.shape, &pose_b, shape_b));
            if d < margin {
                out.push(PairDistance {
                    a: g.name.clone(),
                    b: self.target_name(t).to_string(),
                    distance: d,
                });
            }
        }
        out.sort_by(|x, y| x.distance.total_cmp(&y.distance));
        Ok(out)
    }

    /// Names of the self-collision pairs that are checked.
    pub fn self_pair_names(&self) -> Vec<(String, String)> {
        self.self_pairs
            .iter()
            .map(|&(i, j)| (self.geometries[i].name.clone(), self.geometries[j].name.clone()))
            .collect()
    }
}

/// Above this many obstacles near the whole robot, [`CollisionWorld::in_collision_unchecked`]
/// asks the hierarchy for each geometry's own instead of testing each geometry against all of
/// them.
const NEAR_LINEAR_MAX: usize = 24;

/// Reusable buffers for repeated queries (empty by default: sized by the first query).
#[derive(Clone, Default)]
pub struct Scratch {
    pub(super) links: Vec<Isometry3<f64>>,
    pub(super) poses: Vec<Isometry3<f64>>,
    pub(super) aabbs: Vec<Aabb>,
    pub(super) obbs: Vec<Obb>,
    /// Obstacles near the whole robot, and near one geometry (indices, ascending).
    near: Vec<usize>,
    candidates: Vec<usize>,
    /// Which geometries this query has posed (`poses`, `aabbs`, `obbs` hold stale values for
    /// the others).
    pub(super) posed: Vec<bool>,
    /// Per link group (`groups.rs`): the sphere's world centre, the oriented box and whether
    /// this query has computed it.
    group_centers: Vec<Point3<f64>>,
    group_obbs: Vec<Obb>,
    group_obb_done: Vec<bool>,
    /// Per self pair of the link groups' order: the last axes (in the first shape's frame) that
    /// separated its two hulls, most recently useful first, zero where none yet
    /// (`CollisionWorld::self_pair_intersects`).
    axes: Vec<[Vector3<f64>; AXES]>,
    /// The link pairs (`LinkGroups::group_pairs` of the world whose `LinkGroups::id` is
    /// `order_of`) in the order the self-collision check visits them, most recently in contact
    /// first (`CollisionWorld::collides_with_itself`); empty until the first check.
    order: Vec<GroupPair>,
    order_of: u64,
}

impl Scratch {
    /// Size the buffers for `ng` geometries and `nk` link groups and mark everything unposed
    /// (the link poses are kept).
    fn resize(&mut self, ng: usize, nk: usize) {
        self.poses.resize(ng, Isometry3::identity());
        self.aabbs.resize(ng, Aabb::new_invalid());
        self.obbs.resize(ng, Obb::default());
        self.posed.clear();
        self.posed.resize(ng, false);
        self.group_centers.clear();
        self.group_obbs.resize(nk, Obb::default());
        self.group_obb_done.clear();
        self.group_obb_done.resize(nk, false);
    }
}

/// How many separating axes a self pair of hulls keeps (`Scratch::axes`). Criterion
/// (`collision_check/talos`, the builds interleaved by benches/criterion_ab.py,
/// benches/results/criterion_ab_kept_axes_count.json), against none: on collision-free
/// configurations (every pair tested) 1.11x with 1 axis, 1.21x with 3, 1.29x with 4; on random
/// ones 1.30x, 1.13x, 1.24x; 6 slower than 4 on both.
const AXES: usize = 4;

/// How many link pairs the self-collision check tests at the sphere level in one pass
/// ([`spheres_overlapping`]) before it looks closer at those that pass.
const BLOCK: usize = 64;

/// The link pairs among the first [`BLOCK`] of `pairs` whose groups' spheres (centres
/// `centers`) overlap, as a bit mask (bit p: `pairs[p]`). A loop of its own, without branches
/// or stores that depend on the outcome, so that the sphere tests, which rule out most pairs,
/// run at the machine's pace rather than in the register pressure of the whole check. A NaN
/// distance counts as overlapping (the narrow phase decides).
#[inline(never)]
fn spheres_overlapping(pairs: &[GroupPair], centers: &[Point3<f64>]) -> u64 {
    let mut mask = 0u64;
    for (p, gp) in pairs.iter().enumerate().take(BLOCK) {
        let apart = (centers[gp.a as usize] - centers[gp.b as usize]).norm_squared() > gp.reach2;
        mask |= u64::from(!apart) << p;
    }
    mask
}

/// The world box around a sphere.
#[inline]
fn sphere_aabb(c: &Point3<f64>, r: f64) -> Aabb {
    let e = Vector3::repeat(r);
    Aabb::new(c - e, c + e)
}

/// An obstacle's pose: finite, its translation within [`MAX_OBSTACLE_EXTENT`] of the origin in
/// each coordinate, its rotation a unit quaternion. `what`: the obstacle ("box 'crate'").
fn check_isometry(what: &str, pose: &Isometry3<f64>) -> Result<()> {
    let t = pose.translation.vector;
    let r = pose.rotation.coords;
    check_finite(&format!("{what} pose"), &[t.x, t.y, t.z, r.x, r.y, r.z, r.w])?;
    check_position(what, "centre", &[t.x, t.y, t.z])?;
    // |q| without overflow: the components of a finite quaternion far from unit may be huge
    let norm = stable_norm(r.as_slice());
    if (norm - 1.0).abs() > QUATERNION_TOLERANCE {
        return Err(Error::Invalid(format!("{what}: the pose's rotation is not a unit quaternion (norm {norm:?})")));
    }
    Ok(())
}

/// Named sizes of an obstacle (radius, half height, ...), each positive, finite and at most
/// [`MAX_OBSTACLE_EXTENT`].
fn check_sizes(what: &str, sizes: &[(&str, f64)]) -> Result<()> {
    for &(field, v) in sizes {
        check_finite(&format!("{what} {field}"), &[v])?;
        if !(v > 0.0 && v <= MAX_OBSTACLE_EXTENT) {
            return Err(Error::Invalid(format!(
                "{what}: {field} must be positive and at most {MAX_OBSTACLE_EXTENT:e} m, got {v:?}"
            )));
        }
    }
    Ok(())
}

/// A padding (`field` names it): finite, >= 0 and at most [`MAX_PADDING`].
fn check_padding(field: &str, p: f64) -> Result<f64> {
    if !(p.is_finite() && (0.0..=MAX_PADDING).contains(&p)) {
        return Err(Error::Invalid(format!("{field} must be a finite distance in [0, {MAX_PADDING}] m, got {p:?}")));
    }
    Ok(p)
}

/// Rx(+90 deg): maps a shape's local y axis (parry's cylinder axis) to z (URDF's and coal's).
fn y_to_z() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
    )
}

/// Each coordinate of a finite position within [`MAX_OBSTACLE_EXTENT`] of the origin.
pub(super) fn check_position(what: &str, field: &str, p: &[f64; 3]) -> Result<()> {
    if p.iter().any(|x| x.abs() > MAX_OBSTACLE_EXTENT) {
        return Err(Error::Invalid(format!(
            "{what}: {field} must be within {MAX_OBSTACLE_EXTENT:e} m of the origin in each coordinate, got {p:?}"
        )));
    }
    Ok(())
}

/// The unit vector along a finite `v`, or None when its norm is at most [`MIN_NORMAL_NORM`]
/// (both computed without overflow or underflow by `crate::lie`).
fn unit_normal(v: &[f64; 3]) -> Option<nalgebra::Unit<Vector3<f64>>> {
    if stable_norm(v) <= MIN_NORMAL_NORM {
        return None;
    }
    unit_vector(&Vector3::from(*v), 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::preset;
    use rand::{Rng, SeedableRng};

    /// A configuration drawn uniformly within the joint limits (0 for an unbounded joint), a
    /// floating base upright at 1 m.
    fn draw(model: &KinematicModel, rng: &mut rand::rngs::StdRng) -> Vec<f64> {
        let mut q: Vec<f64> =
            model.lower.iter().zip(&model.upper).map(|(l, u)| if l.is_finite() { rng.random_range(*l..=*u) } else { 0.0 }).collect();
        if model.floating_base {
            (q[2], q[6]) = (1.0, 1.0);
        }
        q
    }

    /// After a check that finds a self contact, the link pair in contact is first in
    /// `Scratch::order` (and the order stays a permutation); the verdicts, in whatever order
    /// the pairs are visited, stay the exhaustive ones.
    #[test]
    fn the_link_pair_last_in_contact_is_tested_first() {
        let (model, world) = preset("talos").unwrap().load().unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut s = Scratch::default();
        let (mut hits, mut moved) = (0, 0);
        for _ in 0..300 {
            let q = draw(&model, &mut rng);
            let before = s.order.first().map(|gp| gp.start);
            let hit = world.in_collision_unchecked(&q, &mut s);
            assert_eq!(hit, world.in_collision_exhaustive(&q).unwrap());
            assert_eq!(s.order_of, world.groups.id);
            let mut sorted = s.order.clone();
            sorted.sort_unstable_by_key(|gp| gp.start);
            assert_eq!(sorted, world.groups.group_pairs, "the link pairs, reordered");
            if hit {
                hits += 1;
                moved += usize::from(before != s.order.first().map(|gp| gp.start));
                let gp = s.order[0];
                let mut e = Scratch::default();
                world.geometry_poses(&q, &mut e);
                assert!(
                    (gp.start as usize..gp.end as usize).any(|k| {
                        let (i, j) = world.groups.pairs[k];
                        world.narrow_phase(i, Target::Robot(j), &e)
                    }),
                    "the first link pair is in contact"
                );
            }
        }
        assert!(hits > 50 && moved > 0 && moved < hits, "{hits} hits, the first pair changed {moved} times");
    }

    /// One `Scratch` passed to several worlds in turn (two Talos worlds, each with its own
    /// grouping id, and the Panda's, with other link pairs) gives every world's exhaustive
    /// verdicts.
    #[test]
    fn a_scratch_shared_by_worlds_keeps_their_link_pairs_apart() {
        let (talos, a) = preset("talos").unwrap().load().unwrap();
        let (_, mut b) = preset("talos").unwrap().load().unwrap();
        // the second Talos: another grouping of the same pairs, and a box at its chest
        b.add_box("box", [0.1, 0.1, 0.1], Isometry3::translation(0.0, 0.0, 1.1)).unwrap();
        let (panda, c) = preset("panda").unwrap().load().unwrap();
        assert_ne!(a.groups.id, b.groups.id);
        assert_eq!(a.groups.group_pairs.len(), b.groups.group_pairs.len());
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let mut s = Scratch::default();
        let mut hits = 0;
        for _ in 0..100 {
            for (world, model) in [(&a, &talos), (&b, &talos), (&c, &panda)] {
                let q = draw(model, &mut rng);
                let hit = world.in_collision_unchecked(&q, &mut s);
                assert_eq!(hit, world.in_collision_exhaustive(&q).unwrap());
                hits += usize::from(hit);
            }
        }
        assert!(hits > 30, "{hits} hits");
    }
}

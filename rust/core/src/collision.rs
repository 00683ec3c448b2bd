//! Collision world in parry: the robot's collision geometry, self-collision pairs, obstacles.
//!
//! Robot geometry comes from the URDF's `<collision>` elements: boxes, spheres, cylinders and
//! capsules become parry primitives; meshes become the convex hull of their vertices. Self-
//! collision pairs are all pairs of geometries on different rigid bodies (links joined by fixed
//! or locked joints form one body, as in Pinocchio's `addAllCollisionPairs`), minus the SRDF's
//! disabled link pairs.

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder, HalfSpace, SharedShape};

use crate::error::{check_finite, check_vector, unknown, Error, Result};
use crate::kinematics::KinematicModel;
use crate::srdf::Srdf;
use crate::urdf::{Geometry, Urdf};

/// One piece of robot collision geometry, rigidly attached to a link.
#[derive(Clone)]
pub struct RobotGeometry {
    /// `<link>_<i>`, the i-th `<collision>` of the link (Pinocchio's naming).
    pub name: String,
    pub link: usize,
    /// Pose of the shape in the link frame (includes the cylinder axis change y -> z).
    pub offset: Isometry3<f64>,
    pub shape: SharedShape,
    /// Bounding sphere in the shape frame: centre and radius.
    center: Point3<f64>,
    radius: f64,
    /// Bounding box in the shape frame (moved to the world per query: a cheap, tight broadphase).
    local_aabb: Aabb,
}

/// An environment obstacle, fixed in the world.
#[derive(Clone)]
pub struct Obstacle {
    pub name: String,
    pub pose: Isometry3<f64>,
    pub shape: SharedShape,
    /// World bounding sphere (infinite radius for a half-space).
    center: Point3<f64>,
    radius: f64,
    /// World bounding box (None for a half-space).
    aabb: Option<Aabb>,
    /// World oriented bounding box: the shape's local box at its pose (None for a half-space).
    obb: Option<Obb>,
}

/// The answer to a distance query about one pair.
#[derive(Debug, Clone, PartialEq)]
pub struct PairDistance {
    pub a: String,
    pub b: String,
    /// Signed distance: positive apart, negative penetration depth.
    pub distance: f64,
}

fn bounding_sphere(shape: &SharedShape) -> (Point3<f64>, f64) {
    let s = shape.compute_local_bounding_sphere();
    (s.center, s.radius)
}

/// Load the vertices of an STL file (binary or ASCII), scaled.
pub fn load_stl_vertices(path: &Path, scale: &Vector3<f64>) -> Result<Vec<Point3<f64>>> {
    let file = File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mesh = stl_io::read_stl(&mut BufReader::new(file)).map_err(|e| Error::Mesh {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })?;
    let points: Vec<Point3<f64>> = mesh
        .vertices
        .iter()
        .map(|v| {
            Point3::new(
                v[0] as f64 * scale.x,
                v[1] as f64 * scale.y,
                v[2] as f64 * scale.z,
            )
        })
        .collect();
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
            let ext = path
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            if ext != "stl" {
                return Err(Error::Mesh {
                    path,
                    msg: "only STL collision meshes are supported".into(),
                });
            }
            let points = load_stl_vertices(&path, scale)?;
            let hull = SharedShape::convex_hull(&points).ok_or_else(|| Error::Mesh {
                path: path.clone(),
                msg: "convex hull failed (degenerate mesh?)".into(),
            })?;
            hull_cache.insert(key, hull.clone());
            (hull, Isometry3::identity())
        }
    })
}

/// The robot's collision geometry plus obstacles, answering collision and distance queries.
#[derive(Clone)]
pub struct CollisionWorld {
    pub model: Arc<KinematicModel>,
    pub geometries: Vec<RobotGeometry>,
    /// Self-collision pairs, as indices into `geometries`.
    pub self_pairs: Vec<(usize, usize)>,
    pub obstacles: Vec<Obstacle>,
    /// Check self-collision (default true).
    pub check_self: bool,
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
        let mut disabled: HashSet<(usize, usize)> = HashSet::new();
        if let Some(srdf) = srdf {
            for (a, b) in &srdf.disabled_pairs {
                // SRDFs often name links of a fuller model; pairs of unknown links are ignored.
                if let (Ok(a), Ok(b)) = (model.link_index(a), model.link_index(b)) {
                    disabled.insert((a.min(b), a.max(b)));
                }
            }
        }
        let mut self_pairs = Vec::new();
        for i in 0..geometries.len() {
            for j in (i + 1)..geometries.len() {
                let (la, lb) = (geometries[i].link, geometries[j].link);
                if model.body_of_link[la] == model.body_of_link[lb] {
                    continue;
                }
                if disabled.contains(&(la.min(lb), la.max(lb))) {
                    continue;
                }
                self_pairs.push((i, j));
            }
        }
        Ok(CollisionWorld {
            model,
            geometries,
            self_pairs,
            obstacles: Vec::new(),
            check_self: true,
        })
    }

    fn add_obstacle(&mut self, name: &str, pose: Isometry3<f64>, shape: SharedShape) -> Result<()> {
        if self.obstacles.iter().any(|o| o.name == name) {
            return Err(Error::Invalid(format!("an obstacle named '{name}' already exists")));
        }
        let (c, r, aabb, obb) = if shape.as_halfspace().is_some() {
            (Point3::origin(), f64::INFINITY, None, None)
        } else {
            let (c, r) = bounding_sphere(&shape);
            (pose * c, r, Some(shape.compute_aabb(&pose)), Some(Obb::new(&shape.compute_local_aabb(), &pose)))
        };
        self.obstacles.push(Obstacle {
            name: name.to_string(),
            pose,
            shape,
            center: c,
            radius: r,
            aabb,
            obb,
        });
        Ok(())
    }

    /// Add a box with the given half extents at `pose`.
    pub fn add_box(&mut self, name: &str, half_extents: [f64; 3], pose: Isometry3<f64>) -> Result<()> {
        check_finite(&format!("box '{name}' half extents"), &half_extents)?;
        if half_extents.iter().any(|&h| h <= 0.0) {
            return Err(Error::Invalid(format!(
                "box '{name}': half extents must be positive, got {half_extents:?}"
            )));
        }
        check_isometry(name, &pose)?;
        self.add_obstacle(name, pose, SharedShape::new(Cuboid::new(Vector3::from(half_extents))))
    }

    /// Add a sphere.
    pub fn add_sphere(&mut self, name: &str, radius: f64, center: [f64; 3]) -> Result<()> {
        check_vector(&format!("sphere '{name}' centre"), &center, 3)?;
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(Error::Invalid(format!("sphere '{name}': radius must be positive, got {radius}")));
        }
        self.add_obstacle(
            name,
            Isometry3::translation(center[0], center[1], center[2]),
            SharedShape::new(Ball::new(radius)),
        )
    }

    /// Add the half-space {x : n.x <= offset} (everything below the plane n.x = offset).
    pub fn add_halfspace(&mut self, name: &str, normal: [f64; 3], offset: f64) -> Result<()> {
        check_finite(&format!("plane '{name}' normal"), &normal)?;
        check_finite(&format!("plane '{name}' offset"), &[offset])?;
        let n = nalgebra::Unit::try_new(Vector3::from(normal), 1e-12).ok_or_else(|| {
            Error::Invalid(format!("plane '{name}': the normal is zero"))
        })?;
        let pose = Isometry3::translation(n.x * offset, n.y * offset, n.z * offset);
        self.add_obstacle(name, pose, SharedShape::new(HalfSpace::new(n)))
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

    /// World poses and bounding boxes of the robot geometries for a checked q.
    fn geometry_poses(&self, q: &[f64], s: &mut Scratch) {
        self.model.forward_kinematics_unchecked(q, &mut s.links);
        s.poses.clear();
        s.aabbs.clear();
        s.obbs.clear();
        for g in &self.geometries {
            let pose = s.links[g.link] * g.offset;
            let obb = Obb::new(&g.local_aabb, &pose);
            s.aabbs.push(obb.aabb());
            s.obbs.push(obb);
            s.poses.push(pose);
        }
    }

    /// World bounding box of a pair's second member (None for a half-space).
    #[inline]
    fn target_aabb<'a>(&'a self, t: Target, s: &'a Scratch) -> Option<&'a Aabb> {
        match t {
            Target::Robot(j) => Some(&s.aabbs[j]),
            Target::Obstacle(k) => self.obstacles[k].aabb.as_ref(),
        }
    }

    /// Oriented bounding box of a pair's second member (None for a half-space).
    #[inline]
    fn target_obb<'a>(&'a self, t: Target, s: &'a Scratch) -> Option<&'a Obb> {
        match t {
            Target::Robot(j) => Some(&s.obbs[j]),
            Target::Obstacle(k) => self.obstacles[k].obb.as_ref(),
        }
    }

    /// Distance between the bounding boxes of a pair (0 when they overlap): a lower bound on
    /// the distance of the shapes.
    #[inline]
    fn aabb_gap(&self, i: usize, t: Target, s: &Scratch) -> f64 {
        let a = &s.aabbs[i];
        let Some(b) = self.target_aabb(t, s) else {
            return f64::NEG_INFINITY;
        };
        let lo = (a.mins - b.maxs).sup(&(b.mins - a.maxs)).sup(&Vector3::zeros());
        lo.norm()
    }

    /// Broadphase: can robot geometry `i` touch target `t` (boxes overlap)?
    #[inline]
    fn may_touch(&self, i: usize, t: Target, s: &Scratch, margin: f64) -> bool {
        let a = &s.aabbs[i];
        let Some(b) = self.target_aabb(t, s) else {
            return true;
        };
        if margin > 0.0 {
            a.loosened(margin).intersects(b)
        } else {
            a.intersects(b)
        }
    }

    /// Pairs to test: (robot geometry, Either robot geometry or obstacle).
    fn pair_iter(&self) -> impl Iterator<Item = (usize, Target)> + '_ {
        let selfs = self
            .self_pairs
            .iter()
            .filter(move |_| self.check_self)
            .map(|&(i, j)| (i, Target::Robot(j)));
        let envs = (0..self.geometries.len())
            .flat_map(move |i| (0..self.obstacles.len()).map(move |k| (i, Target::Obstacle(k))));
        envs.chain(selfs)
    }

    fn target<'a>(&'a self, t: Target, poses: &[Isometry3<f64>]) -> (Isometry3<f64>, &'a SharedShape, Point3<f64>, f64) {
        match t {
            Target::Robot(j) => {
                let g = &self.geometries[j];
                (poses[j], &g.shape, poses[j] * g.center, g.radius)
            }
            Target::Obstacle(k) => {
                let o = &self.obstacles[k];
                (o.pose, &o.shape, o.center, o.radius)
            }
        }
    }

    fn target_name(&self, t: Target) -> &str {
        match t {
            Target::Robot(j) => &self.geometries[j].name,
            Target::Obstacle(k) => &self.obstacles[k].name,
        }
    }

    /// True when any checked pair intersects.
    pub fn in_collision(&self, q: &[f64]) -> Result<bool> {
        self.model.check_configuration(q)?;
        let mut scratch = Scratch::default();
        Ok(self.in_collision_unchecked(q, &mut scratch))
    }

    /// [`in_collision`](Self::in_collision) without input checks, reusing buffers.
    pub fn in_collision_unchecked(&self, q: &[f64], s: &mut Scratch) -> bool {
        self.geometry_poses(q, s);
        for (i, t) in self.pair_iter() {
            if !self.may_touch(i, t, s, 0.0) {
                continue;
            }
            let g = &self.geometries[i];
            let (pose_b, shape_b, cb, rb) = self.target(t, &s.poses);
            let ca = s.poses[i] * g.center;
            if rb.is_finite() && (ca - cb).norm() > g.radius + rb {
                continue;
            }
            // The shapes' boxes in their own frames are much tighter than world-aligned boxes on
            // tilted links: a separating axis between them rules the pair out before GJK.
            if let Some(b) = self.target_obb(t, s) {
                if s.obbs[i].separated(b) {
                    continue;
                }
            }
            // Unsupported shape pairs cannot occur with the shapes built here; count them as
            // colliding to stay on the safe side.
            if query::intersection_test(&s.poses[i], &*g.shape, &pose_b, &**shape_b).unwrap_or(true) {
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
        for (i, t) in self.pair_iter() {
            let (pose_b, shape_b, _, _) = self.target(t, &s.poses);
            if query::intersection_test(&s.poses[i], &*self.geometries[i].shape, &pose_b, &**shape_b).unwrap_or(true) {
                return Ok(true);
            }
        }
        Ok(false)
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
            query::distance(pa, &**a, pb, &**b).unwrap_or(0.0)
        }
    }

    /// Minimum signed distance over all checked pairs (+inf when there is no pair).
    pub fn min_distance(&self, q: &[f64]) -> Result<f64> {
        self.model.check_configuration(q)?;
        let mut s = Scratch::default();
        Ok(self.min_distance_unchecked(q, &mut s))
    }

    pub fn min_distance_unchecked(&self, q: &[f64], s: &mut Scratch) -> f64 {
        self.geometry_poses(q, s);
        let mut best = f64::INFINITY;
        for (i, t) in self.pair_iter() {
            let g = &self.geometries[i];
            let (pose_b, shape_b, cb, rb) = self.target(t, &s.poses);
            let ca = s.poses[i] * g.center;
            // Lower bounds from the bounding spheres and boxes: skip pairs that cannot beat `best`.
            if rb.is_finite() && (ca - cb).norm() - g.radius - rb >= best {
                continue;
            }
            if self.aabb_gap(i, t, s) >= best {
                continue;
            }
            let d = Self::pair_distance(&s.poses[i], &g.shape, &pose_b, shape_b);
            best = best.min(d);
        }
        best
    }

    /// Every checked pair closer than `margin` (signed distance < margin), with its distance.
    pub fn close_pairs(&self, q: &[f64], margin: f64) -> Result<Vec<PairDistance>> {
        self.model.check_configuration(q)?;
        check_finite("margin", &[margin])?;
        let mut s = Scratch::default();
        self.geometry_poses(q, &mut s);
        let mut out = Vec::new();
        for (i, t) in self.pair_iter() {
            if !self.may_touch(i, t, &s, margin) {
                continue;
            }
            let g = &self.geometries[i];
            let (pose_b, shape_b, cb, rb) = self.target(t, &s.poses);
            let ca = s.poses[i] * g.center;
            if rb.is_finite() && (ca - cb).norm() - g.radius - rb >= margin {
                continue;
            }
            let d = Self::pair_distance(&s.poses[i], &g.shape, &pose_b, shape_b);
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

#[derive(Clone, Copy)]
enum Target {
    Robot(usize),
    Obstacle(usize),
}

/// An oriented bounding box in the world: centre, axes (columns) and half extents.
#[derive(Debug, Clone)]
pub(crate) struct Obb {
    center: Vector3<f64>,
    axes: Matrix3<f64>,
    half: Vector3<f64>,
}

impl Obb {
    /// `local` (a box in the shape frame) placed at `pose`.
    fn new(local: &Aabb, pose: &Isometry3<f64>) -> Obb {
        Obb {
            center: (pose * local.center()).coords,
            axes: pose.rotation.to_rotation_matrix().into_inner(),
            half: local.half_extents(),
        }
    }

    /// The world-aligned box around it (what `Aabb::transform_by` gives for the local box).
    fn aabb(&self) -> Aabb {
        let e = self.axes.abs() * self.half;
        Aabb::new((self.center - e).into(), (self.center + e).into())
    }

    /// True when a separating axis exists (the boxes do not overlap): the 15-axis test of
    /// Gottschalk, Lin and Manocha (1996), with a small epsilon on the cross-product axes so
    /// that near-parallel edges never separate by round-off (the test only errs towards
    /// "overlap", which sends the pair to the exact narrow phase).
    fn separated(&self, o: &Obb) -> bool {
        const EPS: f64 = 1e-9;
        let r = self.axes.transpose() * o.axes; // o's axes in self's frame
        let t = self.axes.transpose() * (o.center - self.center);
        let abs_r = r.map(|x| x.abs() + EPS);
        let (a, b) = (&self.half, &o.half);
        for i in 0..3 {
            let rb = b[0] * abs_r[(i, 0)] + b[1] * abs_r[(i, 1)] + b[2] * abs_r[(i, 2)];
            if t[i].abs() > a[i] + rb {
                return true;
            }
        }
        for j in 0..3 {
            let ra = a[0] * abs_r[(0, j)] + a[1] * abs_r[(1, j)] + a[2] * abs_r[(2, j)];
            let tj = t[0] * r[(0, j)] + t[1] * r[(1, j)] + t[2] * r[(2, j)];
            if tj.abs() > ra + b[j] {
                return true;
            }
        }
        for i in 0..3 {
            let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
            for j in 0..3 {
                let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                let ra = a[i1] * abs_r[(i2, j)] + a[i2] * abs_r[(i1, j)];
                let rb = b[j1] * abs_r[(i, j2)] + b[j2] * abs_r[(i, j1)];
                let tt = t[i2] * r[(i1, j)] - t[i1] * r[(i2, j)];
                if tt.abs() > ra + rb {
                    return true;
                }
            }
        }
        false
    }
}

/// Reusable buffers for repeated queries.
#[derive(Default, Clone)]
pub struct Scratch {
    links: Vec<Isometry3<f64>>,
    poses: Vec<Isometry3<f64>>,
    aabbs: Vec<Aabb>,
    obbs: Vec<Obb>,
}

fn check_isometry(name: &str, pose: &Isometry3<f64>) -> Result<()> {
    let t = pose.translation.vector;
    let r = pose.rotation.coords;
    check_finite(
        &format!("obstacle '{name}' pose"),
        &[t.x, t.y, t.z, r.x, r.y, r.z, r.w],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_pose(rng: &mut rand::rngs::StdRng, spread: f64) -> Isometry3<f64> {
        let t = Vector3::new(rng.random_range(-spread..spread), rng.random_range(-spread..spread), rng.random_range(-spread..spread));
        let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        Isometry3::new(t, axis * rng.random_range(0.0..3.0))
    }

    #[test]
    fn obb_separation_is_exact_for_boxes() {
        // For two boxes the 15-axis test is exact: it must agree with parry's GJK everywhere
        // except within round-off of touching (where it may only say "overlap").
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (mut sep, mut agree) = (0, 0);
        for _ in 0..20_000 {
            let ha = Vector3::new(rng.random_range(0.01..0.5), rng.random_range(0.01..0.5), rng.random_range(0.01..0.5));
            let hb = Vector3::new(rng.random_range(0.01..0.5), rng.random_range(0.01..0.5), rng.random_range(0.01..0.5));
            let (pa, pb) = (random_pose(&mut rng, 0.6), random_pose(&mut rng, 0.6));
            let (a, b) = (Cuboid::new(ha), Cuboid::new(hb));
            let oa = Obb::new(&Aabb::new((-ha).into(), ha.into()), &pa);
            let ob = Obb::new(&Aabb::new((-hb).into(), hb.into()), &pb);
            let world = Aabb::new((-ha).into(), ha.into()).transform_by(&pa);
            assert!((oa.aabb().mins - world.mins).norm() < 1e-12 && (oa.aabb().maxs - world.maxs).norm() < 1e-12);
            let hit = query::intersection_test(&pa, &a, &pb, &b).unwrap();
            let separated = oa.separated(&ob);
            assert_eq!(separated, ob.separated(&oa), "the test is symmetric");
            if separated {
                sep += 1;
                assert!(!hit, "separated boxes intersect: {pa:?} {ha:?} / {pb:?} {hb:?}");
            }
            if separated != hit {
                agree += 1;
            } else {
                let d = query::distance(&pa, &a, &pb, &b).unwrap();
                assert!(d < 1e-6, "overlap reported for boxes {d} apart");
            }
        }
        assert!(sep > 5_000 && agree > 19_900, "{sep} separated, {agree} agree");
    }
}

//! Point clouds as obstacles: each point a ball of one radius (the sensor's noise, or the voxel
//! size), all of a cloud's balls one obstacle ([`CollisionWorld::add_points`]) that a new frame
//! replaces in place ([`CollisionWorld::replace_points`]), optionally down-sampled to one point
//! per voxel ([`voxel_downsample`]), and the robot's own points found at a configuration
//! ([`CollisionWorld::robot_points`]) so that a camera's view of the arm can be dropped.
//!
//! The obstacle's shape is a [`CloudGrid`] (`cloud_grid.rs`: the balls sorted into a dense grid
//! of cells by one counting sort). The world's broad phase finds the cloud near a robot geometry
//! by the cloud's box, as it finds any obstacle; the pair's exact test then asks the grid:
//! `cloud_within` (`in_collision`, and `clear_by`, the certificates of motions, with their
//! margins) and `cloud_distance` (`min_distance`, `close_pairs`); `point_distances` asks [`CloudGrid::nearest`] and the sphere
//! checker [`CloudGrid::any_within`]. Space the sensor did not see is free.

use nalgebra::{Isometry3, Point3};
use parry3d_f64::shape::SharedShape;

use super::broad_phase::Target;
use super::world::{check_position, CollisionWorld, MAX_OBSTACLE_EXTENT};
use super::{CloudGrid, Scratch};
use crate::error::{unknown, Error, Result};

/// What a point-cloud obstacle keeps besides its balls ([`super::Obstacle::cloud`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cloud {
    /// The radius of every point's ball (m).
    pub radius: f64,
    /// The voxel edge each frame is down-sampled with (m), None: every point kept.
    pub voxel: Option<f64>,
    /// How many balls the obstacle holds (after down-sampling).
    pub points: usize,
}

/// One point per occupied voxel (cubes of edge `voxel` aligned with the world's axes, the origin
/// a corner): the centroid of the points in it, so each kept point lies within `voxel * sqrt(3)`
/// of every point it stands for. Voxels in the order of their integer coordinates (x, then y,
/// then z), so the output depends only on the set of input points and their order within a
/// voxel (rows of x, y, z, finite: checked by the caller). The voxels are found by sorting the
/// points' voxel coordinates (no hash table), each as one `u64` (its rank in the voxel box of the
/// cloud, x slowest) beside the point's index when the box's voxels fit one, else as three `i64`.
pub fn voxel_downsample(points: &[f64], voxel: f64) -> Vec<f64> {
    let inv = 1.0 / voxel;
    // a coordinate within MAX_OBSTACLE_EXTENT over a voxel >= MIN_VOXEL fits an i64
    let key = |p: &[f64]| [(p[0] * inv).floor() as i64, (p[1] * inv).floor() as i64, (p[2] * inv).floor() as i64];
    let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
    for p in points.chunks_exact(3) {
        let k = key(p);
        for i in 0..3 {
            lo[i] = lo[i].min(k[i]);
            hi[i] = hi[i].max(k[i]);
        }
    }
    let dims = [0, 1, 2].map(|i| (hi[i] - lo[i]) as u128 + 1);
    if points.len() / 3 <= u32::MAX as usize && dims[0] * dims[1] * dims[2] <= u64::MAX as u128 {
        let (dy, dz) = (dims[1] as u64, dims[2] as u64);
        let mut keys: Vec<(u64, u32)> = points
            .chunks_exact(3)
            .enumerate()
            .map(|(i, p)| {
                let k = key(p);
                let d = [0, 1, 2].map(|j| (k[j] - lo[j]) as u64);
                ((d[0] * dy + d[1]) * dz + d[2], i as u32)
            })
            .collect();
        keys.sort_unstable();
        centroids(points, &keys, |k| k.0, |k| k.1 as usize)
    } else {
        let mut keys: Vec<([i64; 3], usize)> = points.chunks_exact(3).enumerate().map(|(i, p)| (key(p), i)).collect();
        keys.sort_unstable();
        centroids(points, &keys, |k| k.0, |k| k.1)
    }
}

/// The centroid of each run of equal keys of `keys` (sorted), in their order.
fn centroids<K, V: PartialEq>(points: &[f64], keys: &[K], voxel: impl Fn(&K) -> V, index: impl Fn(&K) -> usize) -> Vec<f64> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < keys.len() {
        let (key, mut sum, mut n) = (voxel(&keys[k]), [0.0; 3], 0.0);
        while k < keys.len() && voxel(&keys[k]) == key {
            let i = index(&keys[k]) * 3;
            for (s, x) in sum.iter_mut().zip(&points[i..i + 3]) {
                *s += x;
            }
            n += 1.0;
            k += 1;
        }
        out.extend(sum.iter().map(|s| s / n));
    }
    out
}

/// The smallest voxel edge [`voxel_downsample`] takes (m): finer than any depth sensor resolves.
pub const MIN_VOXEL: f64 = 1e-6;

/// Check a cloud's points (rows of x, y, z; at least one; finite; each coordinate within
/// [`MAX_OBSTACLE_EXTENT`]) before any work. `what`: the cloud ("points 'kinect'").
fn check_points(what: &str, points: &[f64]) -> Result<()> {
    if points.len() % 3 != 0 {
        return Err(Error::Shape { what: format!("{what}: points (rows of x, y, z)"), expected: 3 * points.len().div_ceil(3), got: points.len() });
    }
    if points.is_empty() {
        return Err(Error::Invalid(format!("{what}: points: the cloud is empty (a cloud needs at least one point)")));
    }
    if let Some(i) = points.iter().position(|x| !x.is_finite()) {
        return Err(Error::NonFinite { what: format!("{what}: points row {} (column {})", i / 3, i % 3), index: i, value: points[i] });
    }
    if let Some(i) = points.iter().position(|x| x.abs() > MAX_OBSTACLE_EXTENT) {
        let r = i / 3;
        check_position(what, &format!("points row {r}"), &[points[3 * r], points[3 * r + 1], points[3 * r + 2]])?;
    }
    Ok(())
}

/// The radius and voxel of a cloud: radius positive, finite, at most [`MAX_OBSTACLE_EXTENT`];
/// voxel (when given) finite and at least [`MIN_VOXEL`].
fn check_cloud_settings(what: &str, radius: f64, voxel: Option<f64>) -> Result<()> {
    if !(radius.is_finite() && radius > 0.0 && radius <= MAX_OBSTACLE_EXTENT) {
        return Err(Error::Invalid(format!("{what}: radius must be positive and at most {MAX_OBSTACLE_EXTENT:e} m, got {radius:?}")));
    }
    if let Some(v) = voxel {
        if !(v.is_finite() && (MIN_VOXEL..=MAX_OBSTACLE_EXTENT).contains(&v)) {
            return Err(Error::Invalid(format!("{what}: voxel must be between {MIN_VOXEL:e} and {MAX_OBSTACLE_EXTENT:e} m, got {v:?}")));
        }
    }
    Ok(())
}

/// The balls of a checked cloud (down-sampled when `voxel` is given), as one [`CloudGrid`].
fn cloud_shape(points: &[f64], radius: f64, voxel: Option<f64>) -> (SharedShape, usize) {
    let grid = match voxel {
        Some(v) => CloudGrid::new(&voxel_downsample(points, v), radius),
        None => CloudGrid::new(points, radius),
    };
    let n = grid.len();
    (SharedShape::new(grid), n)
}

impl CollisionWorld {
    /// Add a point cloud: each point of `points` (rows of x, y, z in the world frame; at least
    /// one, finite, each coordinate within [`MAX_OBSTACLE_EXTENT`]) a ball of `radius` (positive,
    /// finite, at most [`MAX_OBSTACLE_EXTENT`]), after down-sampling to one point per `voxel`
    /// (m, at least [`MIN_VOXEL`]; [`voxel_downsample`]) when given. Every query treats the
    /// cloud as one obstacle named `name` (see the module's text). Everything is checked
    /// before any work.
    pub fn add_points(&mut self, name: &str, points: &[f64], radius: f64, voxel: Option<f64>) -> Result<()> {
        let what = format!("points '{name}'");
        check_cloud_settings(&what, radius, voxel)?;
        if self.obstacles.iter().any(|o| o.name == name) {
            return Err(Error::Invalid(format!("an obstacle named '{name}' already exists")));
        }
        check_points(&what, points)?;
        let (shape, n) = cloud_shape(points, radius, voxel);
        let mut o = Self::make_obstacle(name, Isometry3::identity(), shape);
        o.cloud = Some(Cloud { radius, voxel, points: n });
        self.obstacles.push(o);
        Ok(())
    }

    /// Replace the points of cloud `name` with a new frame (checked as
    /// [`add_points`](Self::add_points)' are), keeping its radius, its voxel, its padding and its
    /// place among the obstacles. An unknown name, or an obstacle that is not a cloud, is refused before any
    /// work; so is a bad frame, which leaves the old one in place.
    pub fn replace_points(&mut self, name: &str, points: &[f64]) -> Result<()> {
        let Some(i) = self.obstacles.iter().position(|o| o.name == name) else {
            let clouds: Vec<&str> = self.obstacles.iter().filter(|o| o.cloud.is_some()).map(|o| o.name.as_str()).collect();
            return Err(unknown("point cloud", name, &clouds));
        };
        let Some(cloud) = self.obstacles[i].cloud else {
            return Err(Error::Invalid(format!("obstacle '{name}' is not a point cloud: only a cloud's points can be replaced")));
        };
        check_points(&format!("points '{name}'"), points)?;
        let (shape, n) = cloud_shape(points, cloud.radius, cloud.voxel);
        let mut o = Self::make_obstacle(name, Isometry3::identity(), shape);
        o.cloud = Some(Cloud { points: n, ..cloud });
        o.padding = self.obstacles[i].padding; // the cloud's own clearance margin stays
        self.obstacles.replace(i, o);
        Ok(())
    }

    /// The cloud of target `t`, None when `t` is not a cloud obstacle.
    #[inline]
    fn cloud_of(&self, t: Target) -> Option<&CloudGrid> {
        match t {
            Target::Obstacle(k) if self.obstacles[k].cloud.is_some() => self.obstacles[k].shape.as_shape::<CloudGrid>(),
            _ => None,
        }
    }

    /// For a cloud target `t`: is robot geometry `i` (posed in `s`) within `margin` (>= 0) of one
    /// of its balls ([`CloudGrid::touches`])? None when `t` is not a cloud.
    #[inline]
    pub(super) fn cloud_within(&self, i: usize, t: Target, margin: f64, s: &Scratch) -> Option<bool> {
        let grid = self.cloud_of(t)?;
        let g = &self.geometries[i];
        Some(grid.touches(&*g.shape, &s.poses[i], &g.local_aabb, &s.aabbs[i], margin))
    }

    /// For a cloud target `t`: the signed distance of robot geometry `i` (posed in `s`) to its
    /// nearest ball when below `bound`, else a value >= `bound` ([`CloudGrid::distance`]). None
    /// when `t` is not a cloud.
    #[inline]
    pub(super) fn cloud_distance(&self, i: usize, t: Target, s: &Scratch, bound: f64) -> Option<f64> {
        let grid = self.cloud_of(t)?;
        Some(grid.distance(&*self.geometries[i].shape, &s.poses[i], &s.aabbs[i], bound))
    }

    /// Which of `points` (rows of x, y, z; finite) lie within `margin` (>= 0, finite) of the
    /// robot's collision geometry at configuration `q` (checked): the points a camera sees on
    /// the arm itself, to drop from a cloud before it is added. Each point is tested against the
    /// geometries whose world box, grown by `margin`, contains it (parry's point distance to
    /// the solid shape).
    pub fn robot_points(&self, q: &[f64], points: &[f64], margin: f64) -> Result<Vec<bool>> {
        self.model.check_configuration(q)?;
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(Error::Invalid(format!("margin must be a finite distance >= 0 (m), got {margin:?}")));
        }
        if points.len() % 3 != 0 {
            return Err(Error::Shape { what: "points (rows of x, y, z)".into(), expected: 3 * points.len().div_ceil(3), got: points.len() });
        }
        if let Some(i) = points.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite { what: format!("points row {} (column {})", i / 3, i % 3), index: i, value: points[i] });
        }
        let mut s = super::Scratch::default();
        self.pose(q, &mut s);
        let boxes: Vec<_> = s.aabbs.iter().map(|b| (b.mins - nalgebra::Vector3::repeat(margin), b.maxs + nalgebra::Vector3::repeat(margin))).collect();
        let geometries = self.geometries();
        Ok(points
            .chunks_exact(3)
            .map(|p| {
                let p = Point3::new(p[0], p[1], p[2]);
                boxes.iter().enumerate().any(|(i, (lo, hi))| {
                    (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k])
                        && geometries[i].shape.distance_to_point(&s.poses[i], &p, true) <= margin
                })
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_centroid_per_voxel_in_voxel_order() {
        let pts = [0.01, 0.01, 0.01, 0.03, 0.03, 0.03, 0.15, 0.0, 0.0, -0.01, 0.0, 0.0, 0.17, 0.0, 0.0];
        let out = voxel_downsample(&pts, 0.1);
        let want = [-0.01, 0.0, 0.0, 0.02, 0.02, 0.02, 0.16, 0.0, 0.0];
        assert_eq!(out.len(), want.len());
        for (a, b) in out.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{out:?}");
        }
    }
}

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

use std::sync::Arc;

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
/// points' voxel coordinates (no hash table): each as its rank in the voxel box of the cloud (x
/// slowest) packed with the point's index into one `u64` when both fit (a radix sort, linear in
/// the points), else as that rank beside the index or, when the box's voxels do
/// not fit a `u64`, as three `i64` (a comparison sort).
pub fn voxel_downsample(points: &[f64], voxel: f64) -> Vec<f64> {
    let mut out = Vec::new();
    voxel_downsample_into(points, voxel, &mut VoxelBuffers::default(), &mut out);
    out
}

/// The sort keys [`voxel_downsample_into`] keeps between frames.
#[derive(Debug, Default)]
pub(super) struct VoxelBuffers {
    keys: Vec<u64>,
    other: Vec<u64>,
}

/// [`voxel_downsample`] into `out` (cleared first), its keys sorted in `buffers`.
pub(super) fn voxel_downsample_into(points: &[f64], voxel: f64, buffers: &mut VoxelBuffers, out: &mut Vec<f64>) {
    out.clear();
    let inv = 1.0 / voxel;
    // the voxel coordinates' box: floor is monotone, so the floors of the extreme coordinates
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points.chunks_exact(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let (lo, hi) = (lo.map(|x| floor(x * inv)), hi.map(|x| floor(x * inv)));
    // a coordinate within MAX_OBSTACLE_EXTENT over a voxel >= MIN_VOXEL fits an i64
    let key = |p: &[f64]| [floor(p[0] * inv), floor(p[1] * inv), floor(p[2] * inv)];
    let dims = [0, 1, 2].map(|i| (hi[i] - lo[i]) as u128 + 1);
    let n = points.len() / 3;
    let voxels = dims[0] * dims[1] * dims[2];
    if voxels > u64::MAX as u128 || n > u32::MAX as usize {
        let mut keys: Vec<([i64; 3], usize)> = points.chunks_exact(3).enumerate().map(|(i, p)| (key(p), i)).collect();
        keys.sort_unstable();
        return centroids(points, &keys, |k| k.0, |k| k.1, out);
    }
    let (dy, dz) = (dims[1] as u64, dims[2] as u64);
    let rank = |p: &[f64]| {
        let k = key(p);
        let d = [0, 1, 2].map(|j| (k[j] - lo[j]) as u64);
        (d[0] * dy + d[1]) * dz + d[2]
    };
    let max_rank = (voxels - 1) as u64;
    let index_bits = u64::BITS - (n as u64).saturating_sub(1).leading_zeros();
    let rank_bits = u64::BITS - max_rank.leading_zeros();
    if index_bits + rank_bits <= u64::BITS {
        // rank above the index: the sort on the rank's bits keeps each voxel's points in order
        let keys = &mut buffers.keys;
        keys.clear();
        keys.extend(points.chunks_exact(3).enumerate().map(|(i, p)| (rank(p) << index_bits) | i as u64));
        radix_sort(keys, &mut buffers.other, index_bits, rank_bits);
        let mask = (1u64 << index_bits) - 1;
        centroids(points, keys, |k| k >> index_bits, |k| (k & mask) as usize, out);
    } else {
        let mut keys: Vec<(u64, u32)> = points.chunks_exact(3).enumerate().map(|(i, p)| (rank(p), i as u32)).collect();
        keys.sort_unstable();
        centroids(points, &keys, |k| k.0, |k| k.1 as usize, out);
    }
}

/// `x.floor()` as an `i64` for `|x| < 2^53` without a call into libm (which `f64::floor` is
/// without SSE4.1): truncation, one less for a negative non-integer.
#[inline(always)]
fn floor(x: f64) -> i64 {
    let t = x as i64;
    t - i64::from((t as f64) > x)
}

/// The bits of a key [`radix_sort`] sorts by in one pass, at most (a pass's counts, 2^12 of
/// them, stay in the first-level cache).
const RADIX_BITS: u32 = 12;

/// Sort `keys` by their bits `shift..shift + bits` (the bits below `shift` kept in their order:
/// a stable sort; `other`: scratch), least significant digit first: as many passes of at most [`RADIX_BITS`] bits
/// as `bits` needs (two for a cloud in a box of 16 million voxels), each a count and a scatter,
/// linear in the keys where a comparison sort is n log n.
fn radix_sort(keys: &mut Vec<u64>, other: &mut Vec<u64>, shift: u32, bits: u32) {
    let passes = bits.div_ceil(RADIX_BITS);
    if passes == 0 || keys.len() < 2 {
        return;
    }
    let width = bits.div_ceil(passes);
    let mask = (1u64 << width) - 1;
    other.clear();
    other.resize(keys.len(), 0);
    let mut count = vec![0usize; 1 << width];
    for pass in 0..passes {
        let s = shift + pass * width;
        count.fill(0);
        for k in keys.iter() {
            count[((k >> s) & mask) as usize] += 1;
        }
        let mut sum = 0;
        for c in count.iter_mut() {
            (*c, sum) = (sum, sum + *c);
        }
        for &k in keys.iter() {
            let d = &mut count[((k >> s) & mask) as usize];
            other[*d] = k;
            *d += 1;
        }
        std::mem::swap(keys, other);
    }
}

/// Into `out` (empty), the centroid of each run of equal voxels (`voxel`) of `keys` (sorted), in
/// their order, the points read through `index`.
fn centroids<K, V: PartialEq>(points: &[f64], keys: &[K], voxel: impl Fn(&K) -> V, index: impl Fn(&K) -> usize, out: &mut Vec<f64>) {
    let runs = 1 + keys.windows(2).filter(|w| voxel(&w[0]) != voxel(&w[1])).count();
    out.reserve(3 * runs);
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
    let mut grid = CloudGrid::new(&[0.0; 3], radius);
    grid.rebuild(points, radius, voxel);
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
        let old = self.obstacles.get_mut(i);
        // the new frame in the old one's memory when no one else holds the grid (a clone of the
        // world shares it until then), else in a new grid
        let shape = match Arc::get_mut(&mut old.shape.0).and_then(|s| s.downcast_mut::<CloudGrid>()) {
            Some(grid) => {
                grid.rebuild(points, cloud.radius, cloud.voxel);
                old.shape.clone()
            }
            None => cloud_shape(points, cloud.radius, cloud.voxel).0,
        };
        let n = shape.as_shape::<CloudGrid>().map_or(0, CloudGrid::len);
        let mut o = Self::make_obstacle(name, Isometry3::identity(), shape);
        o.cloud = Some(Cloud { points: n, ..cloud });
        o.padding = old.padding; // the cloud's own clearance margin stays
        *old = o;
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

    /// Is the sphere of radius `r` about `c` farther than `margin` (>= 0) from every ball of
    /// obstacle `k` by its cloud's clearance field ([`CloudGrid::clearance`]: one lookup)? The
    /// link volumes' test before any of a link's geometries is posed; false when `k` is not a
    /// cloud or the field cannot tell.
    #[inline]
    pub(super) fn cloud_clears(&self, k: usize, c: &Point3<f64>, r: f64, margin: f64) -> bool {
        self.cloud_of(Target::Obstacle(k)).is_some_and(|g| g.clearance(c) > r + g.radius() + margin)
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

    #[test]
    fn the_radix_sort_sorts_its_bits_as_a_stable_comparison_sort() {
        let mut state = 7u64;
        for (n, shift, bits) in [(1000usize, 10u32, 3u32), (5000, 13, 20), (3000, 17, 40), (200, 0, 64), (1, 0, 9), (0, 0, 0), (700, 20, 0)] {
            let mask = if bits == 64 { u64::MAX } else { (1u64 << bits) - 1 };
            let low = if shift == 0 { 0 } else { (1u64 << shift) - 1 };
            let mut keys: Vec<u64> = (0..n)
                .map(|i| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    (((state >> 5) & mask) << shift) | (i as u64 & low)
                })
                .collect();
            let mut want = keys.clone();
            want.sort_by_key(|k| k >> shift); // stable: the low bits keep their order
            radix_sort(&mut keys, &mut Vec::new(), shift, bits);
            assert_eq!(keys, want, "{n} keys, bits {shift}..{}", shift + bits);
        }
    }
}

//! A point cloud's balls in a dense grid of cells ([`CloudGrid`]): the obstacle shape of a
//! cloud ([`CollisionWorld::add_points`](super::CollisionWorld::add_points)), built in one
//! counting sort and queried by the cells a robot shape's box touches.
//!
//! The centres are sorted by cell, the cells numbered x fastest, so the cells of one row of a
//! query box (its x range at one y and z) hold one contiguous run of centres: a query reads one
//! pair of offsets per row, never one per cell. Blocks of 4 x 4 x 4 cells carry a flag (any
//! centre in them?), so a query skips the empty inside of a cloud's box a block at a time; each
//! row carries 64 occupancy bits (a bit per cell while a row has at most 64 cells), so a query
//! reads a row's offsets only where its range meets an occupied cell, and only between the
//! first and the last such cell; a robot shape's rows are clipped to its oriented box. Building
//! is two passes over the points and one over the cells (no hierarchy to build: a new frame
//! costs the sort), the number of cells bounded by [`MAX_CELLS_PER_BALL`] per ball so that a
//! sparse cloud spread over a room stays small.
//!
//! A clearance field rides on the grid ([`CloudGrid::clearance`]): on cells half the grid's edge
//! (while that stays within `FIELD_CELLS_PER_BALL` cells per ball), a lower bound on the
//! distance to the nearest centre, built with the grid by an exact separable Euclidean distance
//! transform of the occupied cells. One lookup then clears a sphere whose centre is farther
//! from every centre than its radius plus the balls' (the sphere checker's spheres, the parts of
//! a robot shape's box): far from the cloud's surfaces, no ball is visited. The bound only ever
//! clears what is clear, so the answers stay exact.
//!
//! The queries answer for the union of the balls exactly as parry's ball queries do, one ball at
//! a time, with cheap rejections first: a robot shape's box is cut into up to `MAX_PARTS` parts
//! per axis and the parts the clearance field clears are dropped; the shape is then tested
//! ([`CloudGrid::touches`]) against the balls near the remaining parts' box, each first against
//! that box in the shape's frame, then against the
//! planes that separated the shape from earlier balls of the same query (a dot product each),
//! then by GJK on the shape's support map, stopped as soon as the ball is found within reach or
//! a separating plane is found (which joins the planes). Distances ([`CloudGrid::distance`],
//! [`CloudGrid::nearest`]) visit rings of cells outward from the shape's box until a ring's lower
//! bound reaches the best distance, each ball's distance parry's ball-against-shape one.
//!
//! As a parry [`Shape`] (so that an obstacle holds it as it holds any shape) the grid is a
//! custom shape: parry's own queries do not support it, so every world query that meets a cloud
//! asks the grid (`world.rs`, `points.rs`, `spheres.rs`); one that did not would count the pair
//! as colliding (the world's fallback for unsupported pairs), never as free.

use nalgebra::{Isometry3, Point3, Unit, Vector3};
use parry3d_f64::bounding_volume::{Aabb, BoundingSphere};
use parry3d_f64::mass_properties::MassProperties;
use parry3d_f64::math::Real;
use parry3d_f64::query::gjk::{self, CSOPoint, ConstantOrigin, GJKResult, VoronoiSimplex};
use parry3d_f64::query::{PointProjection, PointQuery, Ray, RayCast, RayIntersection};
use parry3d_f64::shape::{FeatureId, Shape, ShapeType, TypedShape};

use super::cloud::{voxel_downsample_into, VoxelBuffers};

/// The cell edge in ball radii, before [`MAX_CELLS_PER_BALL`] widens it: measured on the Panda
/// shelf cloud (benches/point_clouds.py; docs/ARCHITECTURE.md "Point clouds").
pub const CELL_RADII: f64 = 4.0;

/// At most this many cells per ball (plus [`MIN_CELLS`]): a cloud whose box is large for its
/// number of points gets wider cells, so that the offsets never outweigh the centres.
pub const MAX_CELLS_PER_BALL: usize = 8;

/// Cells any grid may have whatever its number of balls.
pub const MIN_CELLS: usize = 1 << 15;

/// Cells per side of a block (the grid's occupancy flags).
const BLOCK: usize = 4;

/// The clearance field's cells per grid cell along each axis, when the field stays within
/// [`FIELD_CELLS_PER_BALL`] cells per ball (plus [`MIN_CELLS`]); else one.
const FIELD_SPLIT: usize = 2;

/// At most this many clearance-field cells per ball (plus [`MIN_CELLS`]).
const FIELD_CELLS_PER_BALL: usize = 4;

/// At most this many parts per axis a robot shape's box is split into, each part's bounding
/// sphere tested against the clearance field before any ball is ([`CloudGrid::touches`]).
const MAX_PARTS: usize = 3;

/// Half a unit cube's diagonal.
const HALF_DIAGONAL: f64 = 0.8660254037844386;

/// How many separating planes one query keeps (the most recent first).
const PLANES: usize = 4;

/// Added to a cell's bounds (m) when a query clips a row by them: a centre is sorted into its
/// cell by a rounded product and may lie this far outside it.
const EDGE: f64 = 1e-9;

/// A cloud's balls (one radius) sorted into a dense grid of cells (see the module's text).
#[derive(Clone, Debug)]
pub struct CloudGrid {
    radius: f64,
    /// The grid's lowest corner, the cell edge and its inverse.
    origin: Vector3<f64>,
    cell: f64,
    inv: f64,
    /// Cells per axis.
    dims: [usize; 3],
    /// The centres of cell `c` are `centers[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    /// Blocks of `BLOCK` cells a side (x fastest): whether any of their cells holds a centre,
    /// so that a query skips the empty space inside a cloud's box a block at a time.
    blocks: Vec<bool>,
    block_dims: [usize; 3],
    /// Per row (y, z) of cells (`y + dims[1] * z`): bit `b` set when a cell `x` with
    /// `x / row_bit == b` holds a centre, so that a query reads a row's offsets only where its
    /// x range meets occupied cells, and only from the first such cell to the last.
    rows: Vec<u64>,
    /// Cells per bit of `rows` (at least 1: the row's cells spread over 64 bits).
    row_bit: usize,
    centers: Vec<Point3<f64>>,
    /// The box of the centres.
    lo: Point3<f64>,
    hi: Point3<f64>,
    /// The clearance field: cells of edge `fcell` (the grid's cells split [`FIELD_SPLIT`] ways
    /// per axis when that fits the budget, else the grid's own) from `origin`, `fdims` per
    /// axis, x fastest; per cell a lower bound (m, rounded down) on the distance from the cell's
    /// centre to every ball centre ([`CloudGrid::clearance`]).
    fcell: f64,
    finv: f64,
    fdims: [usize; 3],
    field: Vec<f32>,
    /// Memory a new frame reuses ([`CloudGrid::rebuild`]).
    buffers: Buffers,
}

/// The working memory of a grid's build, kept for the next frame ([`CloudGrid::rebuild`]); a
/// clone of the grid starts without it.
#[derive(Debug, Default)]
struct Buffers {
    /// Per centre its cell.
    keys: Vec<u32>,
    /// Per clearance-field cell: does it hold a centre?
    occupied: Vec<bool>,
    /// The distance transform's squared distances, and its lines' scratch.
    dist: Vec<f64>,
    line: Vec<f64>,
    parabolas: Vec<usize>,
    bounds: Vec<f64>,
    /// The down-sampled points and the voxel sort's keys ([`voxel_downsample_into`]).
    points: Vec<f64>,
    voxel: VoxelBuffers,
}

impl Clone for Buffers {
    fn clone(&self) -> Self {
        Buffers::default()
    }
}

/// Cell ranges (inclusive) along each axis.
type Cells = ([usize; 3], [usize; 3]);

impl CloudGrid {
    /// The balls of radius `radius` (> 0) centred at `points` (rows of x, y, z, at least one,
    /// finite: checked by the caller).
    pub fn new(points: &[f64], radius: f64) -> CloudGrid {
        let mut grid = CloudGrid {
            radius,
            origin: Vector3::zeros(),
            cell: 1.0,
            inv: 1.0,
            dims: [1; 3],
            start: Vec::new(),
            blocks: Vec::new(),
            block_dims: [1; 3],
            rows: Vec::new(),
            row_bit: 1,
            centers: Vec::new(),
            lo: Point3::origin(),
            hi: Point3::origin(),
            fcell: 1.0,
            finv: 1.0,
            fdims: [1; 3],
            field: Vec::new(),
            buffers: Buffers::default(),
        };
        grid.rebuild(points, radius, None);
        grid
    }

    /// Make this grid the balls of radius `radius` (> 0) centred at `points` (rows of x, y, z,
    /// at least one, finite: checked by the caller), down-sampled first to one point per
    /// `voxel` when given ([`voxel_downsample`](super::voxel_downsample)): a new frame, built
    /// in the memory of the previous one (no allocation once the frames' sizes settle).
    pub fn rebuild(&mut self, points: &[f64], radius: f64, voxel: Option<f64>) {
        let mut buffers = std::mem::take(&mut self.buffers);
        match voxel {
            Some(v) => {
                let mut kept = std::mem::take(&mut buffers.points);
                voxel_downsample_into(points, v, &mut buffers.voxel, &mut kept);
                self.build(&kept, radius, &mut buffers);
                buffers.points = kept;
            }
            None => self.build(points, radius, &mut buffers),
        }
        self.buffers = buffers;
    }

    /// [`rebuild`](Self::rebuild) without the down-sampling, in `b`'s memory.
    fn build(&mut self, points: &[f64], radius: f64, b: &mut Buffers) {
        let n = points.len() / 3;
        let (mut lo, mut hi) = (Point3::from([f64::INFINITY; 3]), Point3::from([f64::NEG_INFINITY; 3]));
        for p in points.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent = hi - lo;
        let budget = (MAX_CELLS_PER_BALL * n + MIN_CELLS) as f64;
        let mut cell = CELL_RADII * radius;
        // widen the cells until they fit the budget (the volume's cube root, then doublings for
        // the rounding up of each axis)
        let cells_at = |c: f64| (0..3).map(|k| (extent[k] / c).floor() + 1.0).product::<f64>();
        if cells_at(cell) > budget {
            let e = extent.map(|x| x.max(MIN_CUBE_ROOT_EDGE));
            cell = cell.max((e.x * e.y * e.z / budget).cbrt());
            while cells_at(cell) > budget {
                cell *= 1.25;
            }
        }
        let dims = [0, 1, 2].map(|k| (extent[k] / cell) as usize + 1);
        let inv = 1.0 / cell;
        let ncells = dims[0] * dims[1] * dims[2];
        let key = |p: &[f64]| {
            let i = |k: usize| (((p[k] - lo[k]) * inv) as usize).min(dims[k] - 1);
            i(0) + dims[0] * (i(1) + dims[1] * i(2))
        };
        // counting sort of the centres by cell: counts at c + 1, their prefix sums, then each
        // centre placed at its cell's running offset, which ends at the next cell's start
        b.keys.clear();
        b.keys.extend(points.chunks_exact(3).map(|p| key(p) as u32));
        let start = &mut self.start;
        start.clear();
        start.resize(ncells + 1, 0);
        for &k in &b.keys {
            start[k as usize + 1] += 1;
        }
        for c in 0..ncells {
            start[c + 1] += start[c];
        }
        self.centers.clear();
        self.centers.resize(n, Point3::origin());
        for (p, &k) in points.chunks_exact(3).zip(&b.keys) {
            let slot = &mut start[k as usize];
            self.centers[*slot as usize] = Point3::new(p[0], p[1], p[2]);
            *slot += 1;
        }
        // the offsets moved one cell on: shift them back
        start.copy_within(0..ncells, 1);
        start[0] = 0;
        // the occupied cells, read off the offsets (one pass over the cells, no division)
        let block_dims = dims.map(|d| d.div_ceil(BLOCK));
        self.blocks.clear();
        self.blocks.resize(block_dims[0] * block_dims[1] * block_dims[2], false);
        let row_bit = dims[0].div_ceil(64);
        self.rows.clear();
        self.rows.resize(dims[1] * dims[2], 0);
        let split = if dims.iter().map(|&d| d * FIELD_SPLIT).product::<usize>() <= FIELD_CELLS_PER_BALL * n + MIN_CELLS { FIELD_SPLIT } else { 1 };
        let fdims = dims.map(|d| d * split);
        let fcell = cell / split as f64;
        let occupied = &mut b.occupied;
        occupied.clear();
        occupied.resize(fdims[0] * fdims[1] * fdims[2], false);
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                let base = dims[0] * (y + dims[1] * z);
                let block = block_dims[0] * (y / BLOCK + block_dims[1] * (z / BLOCK));
                let bits = &mut self.rows[y + dims[1] * z];
                for x in 0..dims[0] {
                    if start[base + x + 1] > start[base + x] {
                        *bits |= 1 << (x / row_bit);
                        if split == 1 {
                            occupied[base + x] = true;
                        }
                        self.blocks[block + x / BLOCK] = true;
                    }
                }
            }
        }
        if split != 1 {
            // the field's own cells: those holding a centre
            let finv = 1.0 / fcell;
            for c in &self.centers {
                let i = |k: usize| (((c[k] - lo[k]) * finv).max(0.0) as usize).min(fdims[k] - 1);
                occupied[i(0) + fdims[0] * (i(1) + fdims[1] * i(2))] = true;
            }
        }
        clearance_field(b, fcell, fdims, &mut self.field);
        (self.radius, self.origin, self.cell, self.inv, self.dims, self.block_dims, self.row_bit) = (radius, lo.coords, cell, inv, dims, block_dims, row_bit);
        (self.lo, self.hi, self.fcell, self.finv, self.fdims) = (lo, hi, fcell, 1.0 / fcell, fdims);
    }
    /// A lower bound on the distance from the world point `p` to every ball centre (possibly
    /// negative: no bound). For `p` in the centres' box: the field's value at the cell holding
    /// `p` less the distance from `p` to that cell's centre. Outside: `q`, `p` clamped to the
    /// box, is bounded so, and a centre `c` in the (convex) box has
    /// `|p - c|^2 >= |p - q|^2 + |q - c|^2`. A sphere of radius `s` about `p` is clear of every
    /// ball when this exceeds `s + radius`.
    #[inline]
    pub fn clearance(&self, p: &Point3<f64>) -> f64 {
        let (mut index, mut stride, mut d2, mut gap2) = (0, 1, 0.0, 0.0);
        for k in 0..3 {
            let q = p[k].clamp(self.lo[k], self.hi[k]);
            gap2 += (p[k] - q) * (p[k] - q);
            let i = (((q - self.origin[k]) * self.finv).max(0.0) as usize).min(self.fdims[k] - 1);
            let off = q - (self.origin[k] + (i as f64 + 0.5) * self.fcell);
            d2 += off * off;
            index += i * stride;
            stride *= self.fdims[k];
        }
        let inside = self.field[index] as f64 - d2.sqrt();
        if gap2 == 0.0 {
            inside - EDGE
        } else {
            (gap2 + inside.max(0.0).powi(2)).sqrt() - EDGE
        }
    }

    /// The clearance field's cell edge (m).
    pub fn field_cell(&self) -> f64 {
        self.fcell
    }

    /// The balls' radius (m).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The number of balls.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// True when there is no ball (never, for a grid built from a checked cloud).
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }

    /// The balls' centres, sorted by cell.
    pub fn centers(&self) -> &[Point3<f64>] {
        &self.centers
    }

    /// The cell edge (m).
    pub fn cell(&self) -> f64 {
        self.cell
    }

    /// The cells whose centres may lie in the world box `[lo, hi]`; None when none can.
    #[inline]
    fn cells(&self, lo: &Point3<f64>, hi: &Point3<f64>) -> Option<Cells> {
        let (mut a, mut b) = ([0usize; 3], [0usize; 3]);
        for k in 0..3 {
            if !(hi[k] >= self.lo[k] && lo[k] <= self.hi[k]) {
                return None;
            }
            a[k] = (((lo[k] - self.origin[k]) * self.inv).max(0.0) as usize).min(self.dims[k] - 1);
            b[k] = (((hi[k] - self.origin[k]) * self.inv).max(0.0) as usize).min(self.dims[k] - 1);
        }
        Some((a, b))
    }

    /// The centres of cells `x0..=x1` (`x0 <= x1`) of row (y, z): empty, without reading the
    /// offsets, when the row's occupancy bits say no cell of the range holds one; else the run
    /// from the range's first possibly occupied cell to its last.
    #[inline]
    fn row(&self, x0: usize, x1: usize, y: usize, z: usize) -> &[Point3<f64>] {
        let r = y + self.dims[1] * z;
        let bit = self.row_bit;
        let bits = self.rows[r] & span_bits(x0 / bit, x1 / bit);
        if bits == 0 {
            return &[];
        }
        let a = x0.max(bits.trailing_zeros() as usize * bit);
        let b = x1.min((63 - bits.leading_zeros() as usize) * bit + bit - 1);
        let base = self.dims[0] * r;
        &self.centers[self.start[base + a] as usize..self.start[base + b + 1] as usize]
    }

    /// Calls `f` on the centres of each row of `cells` until it returns true (then true).
    #[inline]
    fn any_row(&self, (a, b): Cells, mut f: impl FnMut(&[Point3<f64>]) -> bool) -> bool {
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                let r = self.row(a[0], b[0], y, z);
                if !r.is_empty() && f(r) {
                    return true;
                }
            }
        }
        false
    }

    /// Is any ball within `margin` (>= 0) of `shape` at `pose` (the ball's centre within
    /// `radius + margin` of the solid shape)? `local_aabb`: the shape's box in its frame;
    /// `world_aabb`: its box in the world. See the module's text for the order of the tests;
    /// a shape without a support map gets parry's point projection onto the solid per ball.
    pub fn touches(&self, shape: &dyn Shape, pose: &Isometry3<f64>, local_aabb: &Aabb, world_aabb: &Aabb, margin: f64) -> bool {
        let reach = self.radius + margin;
        let grow = Vector3::repeat(reach);
        let (wlo, whi) = (world_aabb.mins - grow, world_aabb.maxs + grow);
        if self.cells(&wlo, &whi).is_none() {
            return false;
        }
        // the parts of the shape's box (up to MAX_PARTS per axis, near cubes) whose bounding
        // spheres the clearance field cannot clear: a ball within reach of the shape is within
        // reach of one of them, so only the balls near their union are tested
        let (mins, maxs) = (local_aabb.mins.coords, local_aabb.maxs.coords);
        let ext = maxs - mins;
        let unit = ext.min().max(self.fcell);
        let parts = ext.map(|e| ((e / unit).round() as usize).clamp(1, MAX_PARTS));
        let cut = |k: usize, i: usize| if i == parts[k] { maxs[k] } else { mins[k] + ext[k] * i as f64 / parts[k] as f64 };
        let (mut plo, mut phi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
        for ix in 0..parts[0] {
            for iy in 0..parts[1] {
                for iz in 0..parts[2] {
                    let lo = Vector3::new(cut(0, ix), cut(1, iy), cut(2, iz));
                    let hi = Vector3::new(cut(0, ix + 1), cut(1, iy + 1), cut(2, iz + 1));
                    let c = (lo + hi) * 0.5;
                    if self.clearance(&(pose * Point3::from(c))) > (hi - c).norm() + reach {
                        continue;
                    }
                    plo = plo.inf(&lo);
                    phi = phi.sup(&hi);
                }
            }
        }
        if plo.x > phi.x {
            return false;
        }
        let (lc, lh) = ((plo + phi) * 0.5, (phi - plo) * 0.5 + grow);
        let rot = pose.rotation.to_rotation_matrix().into_inner();
        let t = pose.translation.vector;
        let support = shape.as_support_map();
        // the union's oriented box grown by the reach: its world centre, and per axis the
        // centre's coordinate along it; the world box is the shape's, clipped to that box's
        let center = pose * Point3::from(lc);
        let half = rot.abs() * lh;
        let (wlo, whi) = (wlo.coords.sup(&(center.coords - half)), whi.coords.inf(&(center.coords + half)));
        let (wlo, whi) = (Point3::from(wlo), Point3::from(whi));
        let Some((a, b)) = self.cells(&wlo, &whi) else { return false };
        let along = [0, 1, 2].map(|i| rot.column(i).dot(&center.coords));
        // separating planes in the shape's frame: (unit normal, the shape's support value)
        let mut planes = [(Vector3::zeros(), f64::INFINITY); PLANES];
        let mut simplex = VoronoiSimplex::new();
        let span = |i: usize, k: usize| (self.origin[i] + k as f64 * self.cell - EDGE, self.origin[i] + (k + 1) as f64 * self.cell + EDGE);
        let axes = [0, 1, 2].map(|i| rot.column(i).into_owned());
        let inv_x = axes.map(|ax| if ax.x.abs() < 1e-12 { 0.0 } else { 1.0 / ax.x });
        // the x range of row (y, z)'s prism that each slab of the oriented box allows
        // (|axis . (p - center)| <= half extent), within the grown world box
        let clip = |y: usize, z: usize| -> Option<(f64, f64)> {
            let ((y0, y1), (z0, z1)) = (span(1, y), span(2, z));
            let (mut x0, mut x1) = (wlo.x, whi.x);
            for i in 0..3 {
                let ax = &axes[i];
                let lo = (ax.y * y0).min(ax.y * y1) + (ax.z * z0).min(ax.z * z1);
                let hi = (ax.y * y0).max(ax.y * y1) + (ax.z * z0).max(ax.z * z1);
                let (l, u) = (along[i] - lh[i] - hi, along[i] + lh[i] - lo);
                if inv_x[i] == 0.0 {
                    if l > 0.0 || u < 0.0 {
                        return None;
                    }
                } else {
                    let (p, q) = (l * inv_x[i], u * inv_x[i]);
                    x0 = x0.max(p.min(q));
                    x1 = x1.min(p.max(q));
                }
            }
            (x0 <= x1).then_some((x0, x1))
        };
        let cx = |x: f64| (((x - self.origin.x) * self.inv).max(0.0) as usize).min(self.dims[0] - 1);
        let bd = self.block_dims;
        for bz in a[2] / BLOCK..=b[2] / BLOCK {
            for by in a[1] / BLOCK..=b[1] / BLOCK {
                for bx in a[0] / BLOCK..=b[0] / BLOCK {
                    if !self.blocks[bx + bd[0] * (by + bd[1] * bz)] {
                        continue;
                    }
                    let sub = |i: usize, k: usize| (a[i].max(k * BLOCK), b[i].min(k * BLOCK + BLOCK - 1));
                    let ((xa, xb), (ya, yb), (za, zb)) = (sub(0, bx), sub(1, by), sub(2, bz));
                    let span = span_bits(xa / self.row_bit, xb / self.row_bit);
                    for z in za..=zb {
                        for y in ya..=yb {
                            // no centre in the block's part of the row: no clip, no offsets read
                            if self.rows[y + self.dims[1] * z] & span == 0 {
                                continue;
                            }
                            let Some((x0, x1)) = clip(y, z) else { continue };
                            let (i0, i1) = (cx(x0).max(xa), cx(x1).min(xb));
                            if i0 > i1 {
                                continue;
                            }
                            let row = self.row(i0, i1, y, z);
                            if self.row_touches(row, shape, support, &rot, &t, &lc, &lh, reach, &mut planes, &mut simplex) {
                                return true;
                            }
                        }
                    }
                }
            }
        }
        false
    }

    /// [`touches`](Self::touches) for the centres of one row.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn row_touches(
        &self,
        row: &[Point3<f64>],
        shape: &dyn Shape,
        support: Option<&dyn parry3d_f64::shape::SupportMap>,
        rot: &nalgebra::Matrix3<f64>,
        t: &Vector3<f64>,
        lc: &Vector3<f64>,
        lh: &Vector3<f64>,
        reach: f64,
        planes: &mut [(Vector3<f64>, f64); PLANES],
        simplex: &mut VoronoiSimplex,
    ) -> bool {
        {
            for c in row {
                let p = rot.tr_mul(&(c.coords - t));
                if ((p - lc).abs() - lh).max() > 0.0 {
                    continue;
                }
                if planes.iter().any(|(d, h)| d.dot(&p) - h > reach) {
                    continue;
                }
                let Some(sm) = support else {
                    let proj = shape.project_local_point(&Point3::from(p), true);
                    if proj.is_inside || (proj.point.coords - p).norm_squared() <= reach * reach {
                        return true;
                    }
                    continue;
                };
                // GJK between the shape and the point, from the last plane's normal (or from the
                // shape's box centre towards the point)
                let at = Isometry3::translation(p.x, p.y, p.z);
                let dir = Unit::try_new(planes[0].0, 1e-12).or_else(|| Unit::try_new(p - lc, 1e-12)).unwrap_or(Vector3::x_axis());
                simplex.reset(CSOPoint::from_shapes(&at, sm, &ConstantOrigin, &dir));
                match gjk::closest_points(&at, sm, &ConstantOrigin, reach, false, simplex) {
                    GJKResult::NoIntersection(d) => {
                        let h = d.dot(&sm.local_support_point(&d).coords);
                        planes.rotate_right(1);
                        planes[0] = (d.into_inner(), h);
                    }
                    _ => return true,
                }
            }
            false
        }
    }

    /// Does the sphere of radius `sphere` at the world point `c` touch a ball (centres within
    /// the sum of the radii)?
    pub fn any_within(&self, c: &Point3<f64>, sphere: f64) -> bool {
        let r = sphere + self.radius;
        if self.clearance(c) > r {
            return false;
        }
        let grow = Vector3::repeat(r);
        let Some(cells) = self.cells(&(c - grow), &(c + grow)) else { return false };
        let r2 = r * r;
        self.any_row(cells, |row| row.iter().any(|p| (p - c).norm_squared() <= r2))
    }

    /// Visits the cells around the cell box `inner` in rings of growing Chebyshev distance k
    /// (k = 0: `inner` itself), calling `visit` on each row's centres with the ring's lower
    /// bound on the distance from `inner`'s cells ((k - 1) cell edges, 0 for k <= 1); stops when
    /// `stop` says the bound is reached or the rings cover the grid.
    fn rings(&self, inner: Cells, mut visit: impl FnMut(&[Point3<f64>]), stop: impl Fn(f64) -> bool) {
        let d = self.dims;
        let mut k = 0usize;
        loop {
            let bound = k.saturating_sub(1) as f64 * self.cell;
            if stop(bound) {
                return;
            }
            let (a, b) = (inner.0.map(|x| x.saturating_sub(k)), [0, 1, 2].map(|i| (inner.1[i] + k).min(d[i] - 1)));
            // the previous ring's box (nothing for k = 0)
            let (pa, pb) = (inner.0.map(|x| x.saturating_sub(k.saturating_sub(1))), [0, 1, 2].map(|i| (inner.1[i] + k.saturating_sub(1)).min(d[i] - 1)));
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    let edge = k == 0 || z < pa[2] || z > pb[2] || y < pa[1] || y > pb[1];
                    if edge {
                        visit(self.row(a[0], b[0], y, z));
                    } else {
                        if a[0] < pa[0] {
                            visit(self.row(a[0], pa[0] - 1, y, z));
                        }
                        if b[0] > pb[0] {
                            visit(self.row(pb[0] + 1, b[0], y, z));
                        }
                    }
                }
            }
            if a == [0, 0, 0] && b == [d[0] - 1, d[1] - 1, d[2] - 1] {
                return;
            }
            k += 1;
        }
    }

    /// The cell box of the world box `[lo, hi]` clamped to the grid (every cell box is inside it).
    fn clamped_cells(&self, lo: &Point3<f64>, hi: &Point3<f64>) -> Cells {
        let at = |p: &Point3<f64>| [0, 1, 2].map(|k| (((p[k] - self.origin[k]) * self.inv).max(0.0) as usize).min(self.dims[k] - 1));
        (at(lo), at(hi))
    }

    /// The least signed distance from `shape` at `pose` (world box `world_aabb`) to a ball when
    /// it is below `bound`, else a value >= `bound`: parry's ball-against-shape distance (the
    /// centre projected on the shape, minus the radius; negative, the depth, when they overlap),
    /// each ball visited unless its box gap from `world_aabb` already reaches the best so far.
    pub fn distance(&self, shape: &dyn Shape, pose: &Isometry3<f64>, world_aabb: &Aabb, bound: f64) -> f64 {
        let best = std::cell::Cell::new(bound);
        let r = self.radius;
        let inner = self.clamped_cells(&world_aabb.mins, &world_aabb.maxs);
        // a ball of ring k >= 2 lies at least the ring's bound from the box, so at least the
        // bound minus the radius from the shape; nearer balls (rings 0 and 1, whose centres may
        // be inside the shape) bound nothing
        self.rings(
            inner,
            |row| {
                for c in row {
                    let gap = point_box_gap(c, world_aabb);
                    if gap - r >= best.get() && gap > 0.0 {
                        continue;
                    }
                    let d = ball_distance(shape, pose, c, r);
                    if d < best.get() {
                        best.set(d);
                    }
                }
            },
            |ring| ring > 0.0 && ring - r >= best.get(),
        );
        best.get()
    }

    /// The least `|p - c| - radius` over the balls (the signed distance from the world point `p`
    /// to the union of the balls, inside the deepest ball when in several) and its gradient
    /// (the unit vector from that centre to `p`; +z at the centre itself) when below `bound`;
    /// else None.
    pub fn nearest(&self, p: &Point3<f64>, bound: f64) -> Option<(f64, Vector3<f64>)> {
        let best = std::cell::Cell::new((bound, None::<Vector3<f64>>));
        let r = self.radius;
        let inner = self.clamped_cells(p, p);
        // a centre in ring k is at least the ring's bound from `p` (farther still when `p` is
        // outside the grid)
        self.rings(
            inner,
            |row| {
                for c in row {
                    let v = p - c;
                    let len2 = v.norm_squared();
                    let b = best.get().0 + r;
                    if b > 0.0 && len2 >= b * b {
                        continue;
                    }
                    let len = len2.sqrt();
                    if len - r < best.get().0 {
                        best.set((len - r, Some(if len > 0.0 { v / len } else { Vector3::z() })));
                    }
                }
            },
            |ring| ring - r >= best.get().0,
        );
        let (d, g) = best.get();
        g.map(|g| (d, g))
    }
}

/// Bits `a..=b` (`a <= b < 64`) of a `u64`.
#[inline]
fn span_bits(a: usize, b: usize) -> u64 {
    (u64::MAX >> (63 - b)) & (u64::MAX << a)
}

/// The least extent (m) counted in the volume whose cube root widens the cells, so that a flat
/// or linear cloud (an extent of zero) still gets a finite cell.
const MIN_CUBE_ROOT_EDGE: f64 = 1e-3;

/// The clearance field of the cells `b.occupied` (those holding a ball centre; see
/// [`CloudGrid::clearance`]) into `field`: the squared distance in cells from each cell to the
/// nearest occupied one, by the exact separable Euclidean distance transform, one axis at a
/// time: along x (the rows, contiguous) the distance to the nearest occupied cell of the row by a
/// scan each way, along y and z Felzenszwalb and Huttenlocher's lower envelope of parabolas; then
/// per cell `cell * (sqrt(that) - half a diagonal)`: a centre lies within half a diagonal of its
/// own cell's centre. Rounded down to `f32`.
fn clearance_field(b: &mut Buffers, cell: f64, dims: [usize; 3], field: &mut Vec<f32>) {
    let d = &mut b.dist;
    d.clear();
    d.resize(b.occupied.len(), FAR);
    for (row, out) in b.occupied.chunks_exact(dims[0]).zip(d.chunks_exact_mut(dims[0])) {
        // the distance to the last occupied cell at or before each cell, then after it
        let mut last = None;
        for (x, (&o, e)) in row.iter().zip(out.iter_mut()).enumerate() {
            if o {
                last = Some(x);
            }
            if let Some(l) = last {
                *e = ((x - l) * (x - l)) as f64;
            }
        }
        let mut next = None;
        for (x, (&o, e)) in row.iter().zip(out.iter_mut()).enumerate().rev() {
            if o {
                next = Some(x);
            }
            if let Some(l) = next {
                *e = e.min(((l - x) * (l - x)) as f64);
            }
        }
    }
    let longest = dims.iter().copied().max().unwrap_or(1);
    let (f, v, z) = (&mut b.line, &mut b.parabolas, &mut b.bounds);
    f.resize(longest, 0.0);
    v.resize(longest, 0);
    z.resize(longest + 1, 0.0);
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 1..3 {
        let (len, step) = (dims[axis], strides[axis]);
        // every line along `axis`: its first cell's index runs over the other two axes
        let (a, c) = ([1, 0, 0][axis], [2, 2, 1][axis]);
        for j in 0..dims[c] {
            for i in 0..dims[a] {
                let first = i * strides[a] + j * strides[c];
                for (q, fq) in f[..len].iter_mut().enumerate() {
                    *fq = d[first + q * step];
                }
                envelope(&f[..len], v, z, |q, x| d[first + q * step] = x);
            }
        }
    }
    field.clear();
    field.extend(d.iter().map(|&e| {
        let bound = cell * (e.sqrt() - HALF_DIAGONAL);
        // rounded to f32 (relative error below 1e-7), then down by more than that
        (bound - 1e-6 * (1.0 + bound.abs())) as f32
    }));
}

/// A squared distance larger than any in a field (no centre on the line yet).
const FAR: f64 = 1e30;

/// One line of the distance transform: `out(q, min over p of (q - p)^2 + f[p])` for each `q`
/// (`v`, `z`: scratch of `f.len()` and `f.len() + 1`).
fn envelope(f: &[f64], v: &mut [usize], z: &mut [f64], mut out: impl FnMut(usize, f64)) {
    let n = f.len();
    let mut k = 0;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        let fq = f[q] + (q * q) as f64;
        // where q's parabola drops below the envelope's last one (z[0] = -inf stops the loop)
        let meet = |p: usize| (fq - (f[p] + (p * p) as f64)) / (2 * (q - p)) as f64;
        let mut s = meet(v[k]);
        while s <= z[k] {
            k -= 1;
            s = meet(v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for q in 0..n {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dq = q as f64 - p as f64;
        out(q, dq * dq + f[p]);
    }
}

/// The distance from `p` to the box `b` (0 inside).
#[inline]
fn point_box_gap(p: &Point3<f64>, b: &Aabb) -> f64 {
    let out = (b.mins - p).sup(&(p - b.maxs)).sup(&Vector3::zeros());
    out.norm()
}

/// parry's signed distance between `shape` at `pose` and the ball of radius `r` at world `c`
/// (the centre projected on the shape, inside by EPA; minus the radius).
#[inline]
fn ball_distance(shape: &dyn Shape, pose: &Isometry3<f64>, c: &Point3<f64>, r: f64) -> f64 {
    let proj = shape.project_point(pose, c, false);
    let len = (c - proj.point).norm();
    if proj.is_inside {
        -len - r
    } else {
        len - r
    }
}

impl PointQuery for CloudGrid {
    /// The projection on the ball with the least signed distance to `pt` ([`CloudGrid::nearest`]):
    /// inside it, `pt` itself when `solid`, else that ball's surface point.
    fn project_local_point(&self, pt: &Point3<Real>, solid: bool) -> PointProjection {
        let (d, g) = self.nearest(pt, f64::INFINITY).unwrap_or((f64::INFINITY, Vector3::z()));
        let surface = pt - g * d;
        if d <= 0.0 {
            PointProjection::new(true, if solid { *pt } else { surface })
        } else {
            PointProjection::new(false, surface)
        }
    }

    fn project_local_point_and_get_feature(&self, pt: &Point3<Real>) -> (PointProjection, FeatureId) {
        (self.project_local_point(pt, false), FeatureId::Unknown)
    }
}

impl RayCast for CloudGrid {
    /// The first ball the ray meets (every ball tested: no world query casts rays at obstacles).
    fn cast_local_ray_and_get_normal(&self, ray: &Ray, max_time_of_impact: Real, solid: bool) -> Option<RayIntersection> {
        let ball = parry3d_f64::shape::Ball::new(self.radius);
        let mut best: Option<RayIntersection> = None;
        for c in &self.centers {
            let local = Ray::new(ray.origin - c.coords, ray.dir);
            let limit = best.map_or(max_time_of_impact, |b| b.time_of_impact);
            if let Some(hit) = ball.cast_local_ray_and_get_normal(&local, limit, solid) {
                if best.is_none_or(|b| hit.time_of_impact < b.time_of_impact) {
                    best = Some(hit);
                }
            }
        }
        best
    }
}

impl Shape for CloudGrid {
    fn compute_local_aabb(&self) -> Aabb {
        let r = Vector3::repeat(self.radius);
        Aabb::new(self.lo - r, self.hi + r)
    }

    fn compute_local_bounding_sphere(&self) -> BoundingSphere {
        let c = nalgebra::center(&self.lo, &self.hi);
        BoundingSphere::new(c, 0.5 * (self.hi - self.lo).norm() + self.radius)
    }

    fn clone_dyn(&self) -> Box<dyn Shape> {
        Box::new(self.clone())
    }

    /// Balls scaled by a non-uniform factor are no longer balls: not supported.
    fn scale_dyn(&self, _scale: &Vector3<Real>, _num_subdivisions: u32) -> Option<Box<dyn Shape>> {
        None
    }

    /// The balls' masses summed (overlaps counted once per ball).
    fn mass_properties(&self, density: Real) -> MassProperties {
        let one = MassProperties::from_ball(density, self.radius);
        self.centers.iter().map(|c| one.transform_by(&Isometry3::translation(c.x, c.y, c.z))).sum()
    }

    fn is_convex(&self) -> bool {
        false
    }

    fn shape_type(&self) -> ShapeType {
        ShapeType::Custom
    }

    fn as_typed_shape(&self) -> TypedShape<'_> {
        TypedShape::Custom(self)
    }

    fn ccd_thickness(&self) -> Real {
        self.radius
    }

    fn ccd_angular_thickness(&self) -> Real {
        std::f64::consts::PI
    }
}

//! Constrained RRT: the GAN paper's Algorithm 1 (Section III-C), with projected extensions.
//!
//! The planner grows a tree from a start configuration towards K goal configurations (found by
//! IK beforehand). Each iteration samples a configuration, extends the tree from its nearest
//! node towards it ([`Planner`]'s *ConstrainedExtend*: steps of `step` radians, each projected
//! onto the constraint manifold with a posture task around the interpolated configuration), then
//! extends greedily from the reached node towards the nearest goal. It succeeds when a goal is
//! reached within `goal_tolerance`.
//!
//! Every part the planner calls is a trait object, so each can be native (Rust) or a user's
//! (the Python bindings wrap Python objects):
//!
//! * [`Sampler`]: batches of configurations (uniform, a GAN, a mixture of both);
//! * [`Projector`]: batches of configurations projected onto the manifold, each with its own
//!   nominal posture (the native one is [`crate::projection::Projector`]);
//! * [`ValidityChecker`]: batches of configurations, valid or not (collision, joint limits, any
//!   inequality the projector does not enforce);
//! * [`NearestNeighbors`]: the tree's nearest-neighbour index ([`LinearNearest`], [`KdForest`]).
//!
//! Beyond the paper, every tree edge is validated: the states between its ends are interpolated
//! at `edge_resolution`, projected and checked, so the returned path is a dense sequence of
//! states each on the manifold and valid (the paper checked the tree nodes only, 0.3 rad apart).
//! The projected intermediate states are kept and make up the returned dense path.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Matrix3, UnitQuaternion};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::collision::{CollisionWorld, Scratch};
use crate::kinematics::{KinematicModel, Motion};
use crate::lie::log3;

/// An error from a component the planner calls (e.g. a Python exception), kept intact so the
/// caller gets it back as it was raised.
pub type ComponentError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a plan stopped without a result.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// Bad input: wrong length, NaN, an invalid start, no valid goal, bad settings.
    #[error("{0}")]
    Invalid(String),
    /// A component (sampler, projector, validity checker, interrupt check) failed.
    #[error("{0}")]
    Component(ComponentError),
}

pub type PlanResult<T> = std::result::Result<T, PlanError>;

fn invalid<T>(msg: impl Into<String>) -> PlanResult<T> {
    Err(PlanError::Invalid(msg.into()))
}

// ---------------------------------------------------------------------------------------------
// Spaces
// ---------------------------------------------------------------------------------------------

/// The configuration space: how configurations are differenced, moved and charted.
pub trait Space: Send + Sync {
    /// Length of a configuration vector.
    fn nq(&self) -> usize;
    /// Dimension of the tangent space (and of the chart used for nearest neighbours).
    fn nv(&self) -> usize;
    /// `out = q1 (-) q0` (tangent vector, length nv).
    fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]);
    /// `out = q (+) v`.
    fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]);
    /// Coordinates of q in a chart (length nv) whose Euclidean distance approximates the tangent
    /// distance; the nearest-neighbour index works in it.
    fn coordinates(&self, q: &[f64], out: &mut [f64]);
    /// Check a configuration (length, finite values, ...).
    fn check(&self, q: &[f64], what: &str) -> PlanResult<()>;

    /// Tangent distance |q1 (-) q0|.
    fn distance(&self, q0: &[f64], q1: &[f64]) -> f64 {
        let mut v = vec![0.0; self.nv()];
        self.difference(q0, q1, &mut v);
        v.iter().map(|x| x * x).sum::<f64>().sqrt()
    }

    /// `out = q0 (+) t (q1 (-) q0)`.
    fn interpolate(&self, q0: &[f64], q1: &[f64], t: f64, out: &mut [f64]) {
        let mut v = vec![0.0; self.nv()];
        self.difference(q0, q1, &mut v);
        v.iter_mut().for_each(|x| *x *= t);
        self.integrate(q0, &v, out);
    }
}

impl Space for KinematicModel {
    fn nq(&self) -> usize {
        self.nq
    }
    fn nv(&self) -> usize {
        self.nv
    }
    fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]) {
        KinematicModel::difference(self, q0, q1, out)
    }
    fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        KinematicModel::integrate(self, q, v, out)
    }
    fn coordinates(&self, q: &[f64], out: &mut [f64]) {
        let mut iq = 0;
        let mut iv = 0;
        if self.floating_base {
            out[..3].copy_from_slice(&q[..3]);
            let rot = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[6], q[3], q[4], q[5]));
            let m: Matrix3<f64> = rot.to_rotation_matrix().into_inner();
            let (w, _) = log3(&m);
            out[3..6].copy_from_slice(w.as_slice());
            iq = 7;
            iv = 6;
        }
        for j in self.joints.iter().filter(|j| j.q_index != usize::MAX) {
            debug_assert!(j.q_index >= iq && j.v_index >= iv);
            match j.motion {
                Motion::Continuous { .. } => out[j.v_index] = q[j.q_index + 1].atan2(q[j.q_index]),
                Motion::Fixed => {}
                _ => out[j.v_index] = q[j.q_index],
            }
        }
    }
    fn check(&self, q: &[f64], what: &str) -> PlanResult<()> {
        self.check_configuration(q).map_err(|e| PlanError::Invalid(format!("{what}: {e}")))
    }
}

/// R^n with the Euclidean metric (tests, benches, toy problems).
#[derive(Debug, Clone, Copy)]
pub struct EuclideanSpace(pub usize);

impl Space for EuclideanSpace {
    fn nq(&self) -> usize {
        self.0
    }
    fn nv(&self) -> usize {
        self.0
    }
    fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]) {
        for i in 0..self.0 {
            out[i] = q1[i] - q0[i];
        }
    }
    fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for i in 0..self.0 {
            out[i] = q[i] + v[i];
        }
    }
    fn coordinates(&self, q: &[f64], out: &mut [f64]) {
        out.copy_from_slice(q);
    }
    fn check(&self, q: &[f64], what: &str) -> PlanResult<()> {
        if q.len() != self.0 {
            return invalid(format!("{what}: expected length {}, got {}", self.0, q.len()));
        }
        match q.iter().position(|x| !x.is_finite()) {
            Some(i) => invalid(format!("{what}: element {i} is not finite ({})", q[i])),
            None => Ok(()),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The component traits
// ---------------------------------------------------------------------------------------------

/// Draws configurations.
pub trait Sampler: Send {
    /// Fill `out` (n rows of nq, row-major) with n configurations.
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()>;
}

/// What one projection did.
#[derive(Debug, Clone, Copy, Default)]
pub struct Projection {
    pub success: bool,
    /// Optimisation steps (Gauss-Newton iterations) spent.
    pub iterations: usize,
}

/// Projects configurations onto the constraint manifold.
pub trait Projector: Send {
    /// Project the rows of `qs` (n x nq), row i with a posture task around row i of `q_noms`;
    /// write the projected rows to `out` and what happened to `reports` (length n).
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()>;
}

/// Says which configurations are valid (collision-free, within limits, ...).
pub trait ValidityChecker: Send {
    /// `valid[i]` for row i of `qs` (n x nq).
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()>;
}

/// A nearest-neighbour index over points of a fixed dimension; points are numbered in the order
/// they were added.
pub trait NearestNeighbors: Send {
    /// Forget every point; the next points have dimension `dim`.
    fn clear(&mut self, dim: usize);
    fn add(&mut self, point: &[f64]);
    /// Index and squared distance of the nearest point for which `keep(index)` holds, None when
    /// there is none.
    fn nearest_where(&self, point: &[f64], keep: &dyn Fn(usize) -> bool) -> Option<(usize, f64)>;
    /// Index and squared distance of the nearest point, None when empty.
    fn nearest(&self, point: &[f64]) -> Option<(usize, f64)> {
        self.nearest_where(point, &|_| true)
    }
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

// ---------------------------------------------------------------------------------------------
// Native samplers
// ---------------------------------------------------------------------------------------------

/// True when `lower..=upper` is a box: finite bounds, each lower <= upper (the samplers' target
/// and base boxes).
pub fn valid_box(lower: &[f64; 3], upper: &[f64; 3]) -> bool {
    (0..3).all(|k| lower[k].is_finite() && upper[k].is_finite() && lower[k] <= upper[k])
}

/// Uniform within the joint limits (continuous joints: any angle); a free-flyer base is set to
/// a fixed placement (`base`, 7 numbers), or with [`UniformSampler::with_base_box`] keeps the
/// placement's orientation and draws its position uniformly in a box (the paper's Talos sampler:
/// the centre-of-mass support box).
#[derive(Debug, Clone)]
pub struct UniformSampler {
    model: Arc<KinematicModel>,
    base: [f64; 7],
    base_box: Option<([f64; 3], [f64; 3])>,
    rng: StdRng,
}

impl UniformSampler {
    pub fn new(model: Arc<KinematicModel>, base: Option<[f64; 7]>, seed: u64) -> PlanResult<UniformSampler> {
        for j in model.joints.iter().filter(|j| j.q_index != usize::MAX) {
            if matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. })
                && !(model.lower[j.q_index].is_finite() && model.upper[j.q_index].is_finite())
            {
                return invalid(format!("uniform sampler: joint '{}' has no finite limits", j.name));
            }
        }
        let base = base.unwrap_or([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        if base.iter().any(|x| !x.is_finite()) {
            return invalid("uniform sampler: base placement is not finite");
        }
        Ok(UniformSampler { model, base, base_box: None, rng: StdRng::seed_from_u64(seed) })
    }

    /// Draw the free-flyer base position uniformly in `lower..=upper` (orientation: the base
    /// placement's).
    pub fn with_base_box(mut self, lower: [f64; 3], upper: [f64; 3]) -> PlanResult<UniformSampler> {
        if !self.model.floating_base {
            return invalid("uniform sampler: a base box needs a free-flyer base");
        }
        if !valid_box(&lower, &upper) {
            return invalid(format!("uniform sampler: bad base box {lower:?} .. {upper:?}"));
        }
        self.base_box = Some((lower, upper));
        Ok(self)
    }
}

impl Sampler for UniformSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let m = &self.model;
        for row in out.chunks_mut(m.nq).take(n) {
            if m.floating_base {
                row[..7].copy_from_slice(&self.base);
                if let Some((lo, hi)) = self.base_box {
                    for k in 0..3 {
                        row[k] = self.rng.random_range(lo[k]..=hi[k]);
                    }
                }
            }
            for j in m.joints.iter().filter(|j| j.q_index != usize::MAX) {
                let i = j.q_index;
                match j.motion {
                    Motion::Continuous { .. } => {
                        let a: f64 = self.rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
                        row[i] = a.cos();
                        row[i + 1] = a.sin();
                    }
                    Motion::Fixed => {}
                    _ => row[i] = self.rng.random_range(m.lower[i]..=m.upper[i]),
                }
            }
        }
        Ok(())
    }
}

/// Draws each configuration from `primary` with probability `p`, else from `secondary`: the
/// paper's hybrid sampler (GAN with p = 0.8, else uniform) keeps the planner probabilistically
/// complete. Both are asked for whole batches.
pub struct MixtureSampler {
    pub primary: Box<dyn Sampler>,
    pub secondary: Box<dyn Sampler>,
    pub p: f64,
    nq: usize,
    rng: StdRng,
    buf: Vec<f64>,
}

impl MixtureSampler {
    pub fn new(primary: Box<dyn Sampler>, secondary: Box<dyn Sampler>, p: f64, nq: usize, seed: u64) -> PlanResult<MixtureSampler> {
        if !(0.0..=1.0).contains(&p) {
            return invalid(format!("mixture sampler: p must be in [0, 1], got {p}"));
        }
        Ok(MixtureSampler { primary, secondary, p, nq, rng: StdRng::seed_from_u64(seed), buf: Vec::new() })
    }
}

impl Sampler for MixtureSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let pick: Vec<bool> = (0..n).map(|_| self.rng.random::<f64>() < self.p).collect();
        let n1 = pick.iter().filter(|&&b| b).count();
        let nq = self.nq;
        let mut rows_a = Vec::new();
        let mut rows_b = Vec::new();
        if n1 > 0 {
            self.buf.resize(n1 * nq, 0.0);
            self.primary.sample(n1, &mut self.buf)?;
            rows_a = self.buf.clone();
        }
        if n1 < n {
            self.buf.resize((n - n1) * nq, 0.0);
            self.secondary.sample(n - n1, &mut self.buf)?;
            rows_b = self.buf.clone();
        }
        let (mut ia, mut ib) = (0, 0);
        for (row, &a) in out.chunks_mut(nq).zip(&pick) {
            if a {
                row.copy_from_slice(&rows_a[ia * nq..(ia + 1) * nq]);
                ia += 1;
            } else {
                row.copy_from_slice(&rows_b[ib * nq..(ib + 1) * nq]);
                ib += 1;
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Native projectors and validity checkers
// ---------------------------------------------------------------------------------------------

/// The native damped Gauss-Newton projector; a batch runs on rayon's threads when `parallel`.
pub struct GaussNewtonProjector {
    pub inner: Arc<crate::projection::Projector>,
    pub parallel: bool,
}

impl Projector for GaussNewtonProjector {
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let nq = self.inner.model.nq;
        let solve = |(q, nom): (&[f64], &[f64])| {
            let o = self.inner.solve_unchecked(q, Some(nom));
            (o.q, Projection { success: o.success, iterations: o.iterations })
        };
        let results: Vec<(Vec<f64>, Projection)> = if self.parallel && reports.len() > 1 {
            qs.par_chunks(nq).zip(q_noms.par_chunks(nq)).map(solve).collect()
        } else {
            qs.chunks(nq).zip(q_noms.chunks(nq)).map(solve).collect()
        };
        for ((q, rep), (row, slot)) in results.into_iter().zip(out.chunks_mut(nq).zip(reports.iter_mut())) {
            row.copy_from_slice(&q);
            *slot = rep;
        }
        Ok(())
    }
}

/// Keeps a point of R^n on the sphere |x| = radius (OMPL's constrained-planning demo).
#[derive(Debug, Clone, Copy)]
pub struct SphereProjector {
    pub radius: f64,
}

impl Projector for SphereProjector {
    fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let n = reports.len();
        let dim = if n == 0 { 0 } else { qs.len() / n };
        for ((q, o), r) in qs.chunks(dim).zip(out.chunks_mut(dim)).zip(reports.iter_mut()) {
            let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            let ok = norm > 1e-12;
            for (a, b) in o.iter_mut().zip(q) {
                *a = if ok { b * self.radius / norm } else { *b };
            }
            *r = Projection { success: ok, iterations: 1 };
        }
        Ok(())
    }
}

/// Valid = within the joint limits and not in collision (parry world, self-collision included
/// when the world checks it).
pub struct CollisionChecker {
    pub world: Arc<CollisionWorld>,
    pub parallel: bool,
    scratch: Scratch,
}

impl CollisionChecker {
    pub fn new(world: Arc<CollisionWorld>, parallel: bool) -> CollisionChecker {
        CollisionChecker { world, parallel, scratch: Scratch::default() }
    }

    fn valid_one(world: &CollisionWorld, q: &[f64], s: &mut Scratch) -> bool {
        let m = &world.model;
        let in_limits = (0..m.nq).all(|i| q[i] >= m.lower[i] - 1e-9 && q[i] <= m.upper[i] + 1e-9);
        in_limits && !world.in_collision_unchecked(q, s)
    }
}

impl ValidityChecker for CollisionChecker {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        let nq = self.world.model.nq;
        if self.parallel && valid.len() > 1 {
            let world = &self.world;
            let res: Vec<bool> = qs
                .par_chunks(nq)
                .map_init(Scratch::default, |s, q| Self::valid_one(world, q, s))
                .collect();
            valid.copy_from_slice(&res);
        } else {
            for (q, v) in qs.chunks(nq).zip(valid.iter_mut()) {
                *v = Self::valid_one(&self.world, q, &mut self.scratch);
            }
        }
        Ok(())
    }
}

/// Every configuration is valid (no obstacles, no limits).
#[derive(Debug, Default, Clone, Copy)]
pub struct AlwaysValid;

impl ValidityChecker for AlwaysValid {
    fn check(&mut self, _qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        valid.fill(true);
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Nearest neighbours
// ---------------------------------------------------------------------------------------------

/// Squared distance, giving up (returning a value >= `bound`) as soon as the partial sum reaches
/// `bound`.
#[inline]
fn dist2_bounded(a: &[f64], b: &[f64], bound: f64) -> f64 {
    let mut s = 0.0;
    let mut chunks_a = a.chunks_exact(4);
    let mut chunks_b = b.chunks_exact(4);
    for (x, y) in (&mut chunks_a).zip(&mut chunks_b) {
        let d0 = x[0] - y[0];
        let d1 = x[1] - y[1];
        let d2 = x[2] - y[2];
        let d3 = x[3] - y[3];
        s += d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3;
        if s >= bound {
            return s;
        }
    }
    for (x, y) in chunks_a.remainder().iter().zip(chunks_b.remainder()) {
        let d = x - y;
        s += d * d;
    }
    s
}

/// Brute force over a contiguous array, with early exit on partial distances.
#[derive(Debug, Clone, Default)]
pub struct LinearNearest {
    dim: usize,
    points: Vec<f64>,
}

impl LinearNearest {
    pub fn new(dim: usize) -> LinearNearest {
        LinearNearest { dim, points: Vec::new() }
    }
}

impl NearestNeighbors for LinearNearest {
    fn clear(&mut self, dim: usize) {
        self.dim = dim;
        self.points.clear();
    }
    fn add(&mut self, point: &[f64]) {
        debug_assert_eq!(point.len(), self.dim);
        self.points.extend_from_slice(point);
    }
    fn nearest_where(&self, point: &[f64], keep: &dyn Fn(usize) -> bool) -> Option<(usize, f64)> {
        let mut best = (usize::MAX, f64::INFINITY);
        for (i, p) in self.points.chunks_exact(self.dim.max(1)).enumerate() {
            let d = dist2_bounded(p, point, best.1);
            if d < best.1 && !keep(i) {
                continue;
            }
            if d < best.1 {
                best = (i, d);
            }
        }
        (best.0 != usize::MAX).then_some(best)
    }
    fn len(&self) -> usize {
        self.points.len() / self.dim.max(1)
    }
}

#[derive(Debug, Clone)]
enum KdNode {
    Split { dim: usize, value: f64, left: usize, right: usize },
    Leaf { start: usize, end: usize },
}

/// A static kd-tree over a set of points (copied contiguously in tree order).
#[derive(Debug, Clone)]
struct StaticKd {
    ids: Vec<usize>,
    points: Vec<f64>,
    nodes: Vec<KdNode>,
}

const KD_LEAF: usize = 12;

impl StaticKd {
    fn build(dim: usize, all: &[f64], mut ids: Vec<usize>) -> StaticKd {
        let mut nodes = Vec::new();
        let n = ids.len();
        Self::build_rec(dim, all, &mut ids, 0, n, &mut nodes);
        let mut points = Vec::with_capacity(n * dim);
        for &id in &ids {
            points.extend_from_slice(&all[id * dim..(id + 1) * dim]);
        }
        StaticKd { ids, points, nodes }
    }

    fn build_rec(dim: usize, all: &[f64], ids: &mut [usize], start: usize, end: usize, nodes: &mut Vec<KdNode>) -> usize {
        let me = nodes.len();
        if end - start <= KD_LEAF {
            nodes.push(KdNode::Leaf { start, end });
            return me;
        }
        // split the widest dimension at its median
        let slice = &mut ids[start..end];
        let mut best = (0, -1.0);
        for d in 0..dim {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for &id in slice.iter() {
                let x = all[id * dim + d];
                lo = lo.min(x);
                hi = hi.max(x);
            }
            if hi - lo > best.1 {
                best = (d, hi - lo);
            }
        }
        let d = best.0;
        let mid = slice.len() / 2;
        slice.select_nth_unstable_by(mid, |&a, &b| all[a * dim + d].total_cmp(&all[b * dim + d]));
        let value = all[slice[mid] * dim + d];
        nodes.push(KdNode::Leaf { start: 0, end: 0 }); // placeholder, replaced below
        let left = Self::build_rec(dim, all, ids, start, start + mid, nodes);
        let right = Self::build_rec(dim, all, ids, start + mid, end, nodes);
        nodes[me] = KdNode::Split { dim: d, value, left, right };
        me
    }

    fn search(&self, dim: usize, node: usize, p: &[f64], best: &mut (usize, f64), keep: &dyn Fn(usize) -> bool) {
        match self.nodes[node] {
            KdNode::Leaf { start, end } => {
                for k in start..end {
                    let d = dist2_bounded(&self.points[k * dim..(k + 1) * dim], p, best.1);
                    if d < best.1 && keep(self.ids[k]) {
                        *best = (self.ids[k], d);
                    }
                }
            }
            KdNode::Split { dim: sd, value, left, right } => {
                let diff = p[sd] - value;
                let (near, far) = if diff < 0.0 { (left, right) } else { (right, left) };
                self.search(dim, near, p, best, keep);
                if diff * diff < best.1 {
                    self.search(dim, far, p, best, keep);
                }
            }
        }
    }
}

/// A dynamic kd-tree by the logarithmic method: a small unsorted buffer plus static kd-trees of
/// doubling sizes, merged and rebuilt as points arrive (amortised O(log^2 n) per insertion).
#[derive(Debug, Clone, Default)]
pub struct KdForest {
    dim: usize,
    points: Vec<f64>,
    buffer: Vec<usize>,
    trees: Vec<Option<StaticKd>>,
}

const KD_BUFFER: usize = 64;

impl KdForest {
    pub fn new(dim: usize) -> KdForest {
        KdForest { dim, ..Default::default() }
    }
}

impl NearestNeighbors for KdForest {
    fn clear(&mut self, dim: usize) {
        self.dim = dim;
        self.points.clear();
        self.buffer.clear();
        self.trees.clear();
    }
    fn add(&mut self, point: &[f64]) {
        debug_assert_eq!(point.len(), self.dim);
        let id = self.len();
        self.points.extend_from_slice(point);
        self.buffer.push(id);
        if self.buffer.len() < KD_BUFFER {
            return;
        }
        let mut ids = std::mem::take(&mut self.buffer);
        let mut level = 0;
        while level < self.trees.len() {
            match self.trees[level].take() {
                Some(t) => ids.extend(t.ids),
                None => break,
            }
            level += 1;
        }
        if level == self.trees.len() {
            self.trees.push(None);
        }
        self.trees[level] = Some(StaticKd::build(self.dim, &self.points, ids));
    }
    fn nearest_where(&self, point: &[f64], keep: &dyn Fn(usize) -> bool) -> Option<(usize, f64)> {
        let mut best = (usize::MAX, f64::INFINITY);
        let dim = self.dim;
        for &id in &self.buffer {
            let d = dist2_bounded(&self.points[id * dim..(id + 1) * dim], point, best.1);
            if d < best.1 && keep(id) {
                best = (id, d);
            }
        }
        // larger trees last: the buffer and small trees usually give a good bound quickly
        for t in self.trees.iter().flatten() {
            t.search(dim, 0, point, &mut best, keep);
        }
        (best.0 != usize::MAX).then_some(best)
    }
    fn len(&self) -> usize {
        self.points.len() / self.dim.max(1)
    }
}

/// Consecutive states of a validated edge are at most this many edge resolutions apart.
pub const MAX_SPACING: f64 = 1.25;

/// Which nearest-neighbour index the planner builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NeighborIndex {
    Linear,
    KdForest,
    /// The kd-forest up to [`KD_MAX_DIM`] dimensions, brute force above (measured: in 7-D the
    /// kd-forest answers 1.3x faster among 1k nodes and 4.9x among 10k; in 34-D brute force is
    /// 1.1-1.2x faster, `benches/planning.rs`).
    Auto,
}

/// Dimension up to which [`NeighborIndex::Auto`] picks the kd-forest.
pub const KD_MAX_DIM: usize = 16;

impl NeighborIndex {
    pub fn build(self, dim: usize) -> Box<dyn NearestNeighbors> {
        match self {
            NeighborIndex::Linear => Box::new(LinearNearest::new(dim)),
            NeighborIndex::KdForest => Box::new(KdForest::new(dim)),
            NeighborIndex::Auto if dim <= KD_MAX_DIM => Box::new(KdForest::new(dim)),
            NeighborIndex::Auto => Box::new(LinearNearest::new(dim)),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The planner
// ---------------------------------------------------------------------------------------------

/// Planner settings. Defaults: the GAN paper's public code (see DESIGN.md), plus edge
/// validation at 0.025 rad.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Length of one extension step (tangent norm, rad for joint spaces). Paper: 0.3.
    pub step: f64,
    /// Steps per extension (ConstrainedExtend) at most. Paper: 10.
    pub max_increments: usize,
    /// An extension stops when a projected state lands farther than this many steps from the
    /// previous one (the projection jumped to another branch of the manifold). Paper: 3.
    pub max_jump: f64,
    /// A goal is reached when the tree gets within this distance of it. Paper: 1e-3.
    pub goal_tolerance: f64,
    /// Iterations (sample + extension + extension to the goal) per attempt. Paper: 500.
    pub max_extensions: usize,
    /// Attempts after a failed one, each from a fresh tree. Paper: 2.
    pub retries: usize,
    /// Project each sample onto the manifold before extending towards it (as the authors' code).
    pub project_samples: bool,
    /// Samples requested from the sampler per call.
    pub sample_batch: usize,
    /// Spacing of the projected, checked states along each tree edge; 0 disables edge
    /// validation (then only the tree nodes are checked, as in the paper).
    pub edge_resolution: f64,
    /// Validate edges lazily: only those of a path that reaches a goal (a failing edge prunes its
    /// subtree and the search goes on). Otherwise every edge is validated as it is added.
    pub lazy_edges: bool,
    /// Shortcut the solution (greedy, each shortcut a projected, validated straight edge). Off
    /// by default: the paper's timings have none.
    pub simplify: bool,
    /// The nearest-neighbour index.
    pub neighbors: NeighborIndex,
    /// Give up after this many consecutive sample batches without one projectable sample.
    pub max_empty_batches: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            step: 0.3,
            max_increments: 10,
            max_jump: 3.0,
            goal_tolerance: 1e-3,
            max_extensions: 500,
            retries: 2,
            project_samples: true,
            sample_batch: 16,
            edge_resolution: 0.025,
            lazy_edges: true,
            simplify: false,
            neighbors: NeighborIndex::Auto,
            max_empty_batches: 100,
        }
    }
}

impl Settings {
    pub fn validate(&self) -> PlanResult<()> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                invalid(format!("settings: {name} must be positive and finite, got {v}"))
            }
        };
        pos("step", self.step)?;
        pos("max_jump", self.max_jump)?;
        pos("goal_tolerance", self.goal_tolerance)?;
        if !(self.edge_resolution.is_finite() && self.edge_resolution >= 0.0) {
            return invalid(format!("settings: edge_resolution must be >= 0, got {}", self.edge_resolution));
        }
        if self.max_increments == 0 || self.max_extensions == 0 || self.sample_batch == 0 || self.max_empty_batches == 0 {
            return invalid("settings: max_increments, max_extensions, sample_batch and max_empty_batches must be >= 1");
        }
        Ok(())
    }
}

/// What a plan cost.
#[derive(Debug, Clone, Default)]
pub struct Stats {
    pub success: bool,
    /// Attempts made after the first (0 when the first attempt succeeded).
    pub retries: usize,
    /// Iterations (the paper's extension steps E), over all attempts.
    pub extensions: usize,
    /// Optimisation steps of the projections of samples and extension steps (the paper's
    /// "Opt. Steps"), over all attempts.
    pub projections: usize,
    /// Projector calls for samples and extension steps (configurations projected).
    pub projection_calls: usize,
    /// Optimisation steps spent validating edges (states between tree nodes).
    pub edge_projections: usize,
    pub samples: usize,
    /// Samples whose projection failed.
    pub samples_rejected: usize,
    /// Configurations given to the validity checker.
    pub validity_checks: usize,
    /// Tree nodes at the end of the last attempt.
    pub nodes: usize,
    /// Nodes pruned because an edge above them failed (lazy) validation.
    pub pruned: usize,
    /// Shortcuts taken when simplifying the solution.
    pub shortcuts: usize,
    pub time_s: f64,
    /// Time spent in the sampler, the projector (samples, steps and edges) and the validity
    /// checker (the rest is the tree, nearest neighbours and bookkeeping).
    pub sampler_s: f64,
    pub projector_s: f64,
    pub checker_s: f64,
}

/// A plan's outcome.
#[derive(Debug, Clone)]
pub struct Solution {
    pub success: bool,
    /// The tree nodes from start to goal (rows of nq).
    pub waypoints: Vec<f64>,
    /// The dense path: waypoints and the validated states between them (rows of nq).
    pub path: Vec<f64>,
    /// Which goal was reached.
    pub goal_index: Option<usize>,
    pub stats: Stats,
}

/// The tree of one attempt: node configurations and, per node, the states on the edge from its
/// parent (exclusive of both ends).
struct Tree {
    nq: usize,
    q: Vec<f64>,
    parent: Vec<usize>,
    children: Vec<Vec<usize>>,
    /// The edge from the parent has been validated (its states are stored).
    validated: Vec<bool>,
    /// Pruned: an edge above it failed validation; never extended from again.
    dead: Vec<bool>,
    edge_start: Vec<usize>,
    edge_count: Vec<usize>,
    edge_states: Vec<f64>,
    nn: Box<dyn NearestNeighbors>,
    coords: Vec<f64>,
}

impl Tree {
    fn node(&self, i: usize) -> &[f64] {
        &self.q[i * self.nq..(i + 1) * self.nq]
    }
    fn len(&self) -> usize {
        self.parent.len()
    }
    fn new(nq: usize, nv: usize, neighbors: NeighborIndex) -> Tree {
        Tree {
            nq,
            q: Vec::new(),
            parent: Vec::new(),
            children: Vec::new(),
            validated: Vec::new(),
            dead: Vec::new(),
            edge_start: Vec::new(),
            edge_count: Vec::new(),
            edge_states: Vec::new(),
            nn: neighbors.build(nv),
            coords: vec![0.0; nv],
        }
    }
    /// Add a node; `edge`: the validated states from the parent, or None (validated later).
    fn add(&mut self, space: &dyn Space, q: &[f64], parent: usize, edge: Option<&[f64]>) -> usize {
        let id = self.len();
        self.q.extend_from_slice(q);
        self.parent.push(parent);
        self.children.push(Vec::new());
        if parent != usize::MAX {
            self.children[parent].push(id);
        }
        self.dead.push(false);
        self.validated.push(false);
        self.edge_start.push(0);
        self.edge_count.push(0);
        if let Some(e) = edge {
            self.set_edge(id, e);
        }
        space.coordinates(q, &mut self.coords);
        self.nn.add(&self.coords);
        id
    }
    fn set_edge(&mut self, node: usize, states: &[f64]) {
        self.edge_start[node] = self.edge_states.len() / self.nq.max(1);
        self.edge_count[node] = states.len() / self.nq.max(1);
        self.edge_states.extend_from_slice(states);
        self.validated[node] = true;
    }
    /// Mark `node` and everything below it dead; returns how many nodes died.
    fn prune(&mut self, node: usize) -> usize {
        let mut stack = vec![node];
        let mut n = 0;
        while let Some(i) = stack.pop() {
            if !self.dead[i] {
                self.dead[i] = true;
                n += 1;
            }
            stack.extend_from_slice(&self.children[i]);
        }
        n
    }
    fn nearest(&mut self, space: &dyn Space, q: &[f64]) -> usize {
        space.coordinates(q, &mut self.coords);
        let dead = &self.dead;
        self.nn.nearest_where(&self.coords, &|i| !dead[i]).map(|(i, _)| i).unwrap_or(0)
    }
    /// Node indices from the root to `node`.
    fn chain(&self, node: usize) -> Vec<usize> {
        let mut chain = vec![node];
        while let Some(&last) = chain.last() {
            match self.parent[last] {
                usize::MAX => break,
                p => chain.push(p),
            }
        }
        chain.reverse();
        chain
    }
}

/// The components of one plan.
pub struct Components<'a> {
    pub sampler: &'a mut dyn Sampler,
    pub projector: &'a mut dyn Projector,
    pub checker: &'a mut dyn ValidityChecker,
    /// Called once per iteration; an error (e.g. a KeyboardInterrupt) ends the plan.
    pub interrupt: &'a mut dyn FnMut() -> PlanResult<()>,
}

/// The constrained RRT of the GAN paper (Algorithm 1).
pub struct Planner {
    pub space: Arc<dyn Space>,
    pub settings: Settings,
}

/// State of one plan call (the planner itself stays immutable and shareable).
struct Run<'a, 'c> {
    space: &'a dyn Space,
    st: &'a Settings,
    c: &'a mut Components<'c>,
    stats: Stats,
    samples: VecDeque<Vec<f64>>,
}

impl Planner {
    pub fn new(space: Arc<dyn Space>, settings: Settings) -> PlanResult<Planner> {
        settings.validate()?;
        Ok(Planner { space, settings })
    }

    /// Plan from `start` to any of `goals` (rows of nq, on the manifold, e.g. from IK).
    /// Invalid goals are dropped; an invalid start or no valid goal is an error.
    pub fn plan(&self, start: &[f64], goals: &[f64], c: &mut Components<'_>) -> PlanResult<Solution> {
        let t0 = Instant::now();
        let space = &*self.space;
        let nq = space.nq();
        space.check(start, "start")?;
        if goals.is_empty() || goals.len() % nq != 0 {
            return invalid(format!("goals: expected rows of {nq} numbers, got {} numbers", goals.len()));
        }
        for (i, g) in goals.chunks(nq).enumerate() {
            space.check(g, &format!("goals[{i}]"))?;
        }
        let mut run = Run { space, st: &self.settings, c, stats: Stats::default(), samples: VecDeque::new() };
        let mut start_ok = [false];
        run.check_valid(start, &mut start_ok)?;
        if !start_ok[0] {
            return invalid("start: the configuration is not valid (in collision or outside the joint limits)");
        }
        let mut goal_ok = vec![false; goals.len() / nq];
        run.check_valid(goals, &mut goal_ok)?;
        let valid_goals: Vec<usize> = (0..goal_ok.len()).filter(|&i| goal_ok[i]).collect();
        if valid_goals.is_empty() {
            return invalid("goals: none of the goal configurations is valid (in collision or outside the joint limits)");
        }

        let mut solution = None;
        for attempt in 0..=self.settings.retries {
            run.stats.retries = attempt;
            let mut tree = Tree::new(nq, space.nv(), self.settings.neighbors);
            tree.add(space, start, usize::MAX, Some(&[]));
            if let Some((node, g)) = run.attempt(&mut tree, goals, &valid_goals)? {
                let (mut waypoints, mut edges) = extract(&tree, node);
                if self.settings.simplify {
                    (waypoints, edges) = run.shortcut(waypoints, edges)?;
                }
                let (w, path) = flatten(&waypoints, &edges);
                solution = Some((w, path, g));
            }
            run.stats.nodes = tree.len();
            if solution.is_some() {
                break;
            }
        }
        let mut stats = run.stats;
        stats.success = solution.is_some();
        stats.time_s = t0.elapsed().as_secs_f64();
        Ok(match solution {
            Some((waypoints, path, g)) => Solution { success: true, waypoints, path, goal_index: Some(g), stats },
            None => Solution { success: false, waypoints: Vec::new(), path: Vec::new(), goal_index: None, stats },
        })
    }
}

impl Planner {
    /// One ConstrainedExtend from `from` towards `target` (on the manifold when
    /// `target_on_manifold`: the last step lands on it unprojected), outside a plan. Returns the
    /// states added (rows of nq, `from` excluded) and whether `target` was reached. With lazy
    /// edges only the states are checked; otherwise each edge too.
    pub fn extend(&self, from: &[f64], target: &[f64], target_on_manifold: bool, c: &mut Components<'_>) -> PlanResult<(Vec<f64>, bool)> {
        let space = &*self.space;
        space.check(from, "from")?;
        space.check(target, "target")?;
        let mut run = Run { space, st: &self.settings, c, stats: Stats::default(), samples: VecDeque::new() };
        let mut tree = Tree::new(space.nq(), space.nv(), self.settings.neighbors);
        tree.add(space, from, usize::MAX, Some(&[]));
        let reach = run.extend(&mut tree, 0, target, target_on_manifold)?;
        Ok((tree.q[space.nq()..].to_vec(), reach.reached))
    }
}

/// The waypoints from the root to `goal_node` and, per waypoint after the first, the validated
/// states of the edge that leads to it.
fn extract(tree: &Tree, goal_node: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let nq = tree.nq;
    let chain = tree.chain(goal_node);
    let waypoints = chain.iter().map(|&i| tree.node(i).to_vec()).collect();
    let edges = chain
        .iter()
        .map(|&i| {
            let (s, n) = (tree.edge_start[i], tree.edge_count[i]);
            tree.edge_states[s * nq..(s + n) * nq].to_vec()
        })
        .collect();
    (waypoints, edges)
}

/// Flatten waypoints and their edges into (waypoints, dense path).
fn flatten(waypoints: &[Vec<f64>], edges: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let mut w = Vec::new();
    let mut path = Vec::new();
    for (q, e) in waypoints.iter().zip(edges) {
        path.extend_from_slice(e);
        path.extend_from_slice(q);
        w.extend_from_slice(q);
    }
    (w, path)
}

/// Where an extension ended.
struct Reach {
    node: usize,
    /// The target itself was added.
    reached: bool,
    added: usize,
}

impl Run<'_, '_> {
    fn check_valid(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        self.stats.validity_checks += valid.len();
        let t = Instant::now();
        let r = self.c.checker.check(qs, valid);
        self.stats.checker_s += t.elapsed().as_secs_f64();
        r
    }

    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let t = Instant::now();
        let r = self.c.projector.project(qs, q_noms, out, reports);
        self.stats.projector_s += t.elapsed().as_secs_f64();
        r
    }

    /// One attempt: returns the goal node and the goal's index on success.
    fn attempt(&mut self, tree: &mut Tree, goals: &[f64], valid_goals: &[usize]) -> PlanResult<Option<(usize, usize)>> {
        let nq = self.space.nq();
        for _ in 0..self.st.max_extensions {
            (self.c.interrupt)()?;
            self.stats.extensions += 1;
            let q_rand = self.next_sample()?;
            let near = tree.nearest(self.space, &q_rand);
            let a = self.extend(tree, near, &q_rand, self.st.project_samples)?;
            if a.added == 0 {
                continue;
            }
            let qa = tree.node(a.node).to_vec();
            let g = *valid_goals
                .iter()
                .min_by(|&&i, &&j| {
                    let di = self.space.distance(&qa, &goals[i * nq..(i + 1) * nq]);
                    let dj = self.space.distance(&qa, &goals[j * nq..(j + 1) * nq]);
                    di.total_cmp(&dj)
                })
                .expect("at least one valid goal");
            let goal = &goals[g * nq..(g + 1) * nq];
            let b = self.extend(tree, a.node, goal, true)?;
            if b.reached && self.space.distance(tree.node(b.node), goal) <= self.st.goal_tolerance && self.validate_path(tree, b.node)? {
                return Ok(Some((b.node, g)));
            }
        }
        Ok(None)
    }

    /// The next (projected, when `project_samples`) sample, refilling the buffer in batches.
    fn next_sample(&mut self) -> PlanResult<Vec<f64>> {
        let nq = self.space.nq();
        let mut empty = 0;
        while self.samples.is_empty() {
            (self.c.interrupt)()?;
            let n = self.st.sample_batch;
            let mut raw = vec![0.0; n * nq];
            let t = Instant::now();
            self.c.sampler.sample(n, &mut raw)?;
            self.stats.sampler_s += t.elapsed().as_secs_f64();
            for (i, q) in raw.chunks(nq).enumerate() {
                self.space
                    .check(q, &format!("sampler output row {i}"))
                    .map_err(|e| PlanError::Invalid(format!("the sampler returned a bad configuration: {e}")))?;
            }
            self.stats.samples += n;
            if self.st.project_samples {
                let mut out = vec![0.0; n * nq];
                let mut reps = vec![Projection::default(); n];
                self.project(&raw, &raw, &mut out, &mut reps)?;
                self.stats.projection_calls += n;
                for (q, r) in out.chunks(nq).zip(&reps) {
                    self.stats.projections += r.iterations;
                    if r.success && q.iter().all(|x| x.is_finite()) {
                        self.samples.push_back(q.to_vec());
                    } else {
                        self.stats.samples_rejected += 1;
                    }
                }
            } else {
                self.samples.extend(raw.chunks(nq).map(<[f64]>::to_vec));
            }
            if self.samples.is_empty() {
                empty += 1;
                if empty >= self.st.max_empty_batches {
                    return invalid(format!(
                        "no sample could be projected onto the manifold in {} batches of {n}: check the sampler and the projector's task",
                        empty
                    ));
                }
            }
        }
        Ok(self.samples.pop_front().expect("refilled above"))
    }

    /// ConstrainedExtend from tree node `from` towards `target` (on the manifold when
    /// `target_on_manifold`).
    fn extend(&mut self, tree: &mut Tree, from: usize, target: &[f64], target_on_manifold: bool) -> PlanResult<Reach> {
        let space = self.space;
        let nq = space.nq();
        let st = self.st;
        let mut cur = from;
        let mut added = 0;
        let mut q_next = vec![0.0; nq];
        for _ in 0..st.max_increments {
            let q_cur = tree.node(cur).to_vec();
            let dist = space.distance(&q_cur, target);
            let last = dist <= st.step;
            let mut candidate = if last {
                target.to_vec()
            } else {
                space.interpolate(&q_cur, target, st.step / dist, &mut q_next);
                q_next.clone()
            };
            if !(last && target_on_manifold) {
                let mut out = vec![0.0; nq];
                let mut rep = [Projection::default()];
                self.project(&candidate, &candidate, &mut out, &mut rep)?;
                self.stats.projection_calls += 1;
                self.stats.projections += rep[0].iterations;
                if !rep[0].success || out.iter().any(|x| !x.is_finite()) {
                    break;
                }
                candidate = out;
            }
            let jump = space.distance(&q_cur, &candidate);
            if jump > st.max_jump * st.step || jump < 1e-12 {
                break;
            }
            if st.lazy_edges {
                let mut ok = [false];
                self.check_valid(&candidate, &mut ok)?;
                if !ok[0] {
                    break;
                }
                cur = tree.add(space, &candidate, cur, None);
            } else {
                match self.validate_edge(&q_cur, &candidate, true)? {
                    Some(edge) => cur = tree.add(space, &candidate, cur, Some(&edge)),
                    None => break,
                }
            }
            added += 1;
            if last {
                return Ok(Reach { node: cur, reached: true, added });
            }
        }
        Ok(Reach { node: cur, reached: false, added })
    }

    /// Shortcut a solution greedily: from each waypoint, connect to the farthest later waypoint
    /// whose straight (projected, validated) edge holds, halving the span on failure.
    fn shortcut(&mut self, waypoints: Vec<Vec<f64>>, edges: Vec<Vec<f64>>) -> PlanResult<(Vec<Vec<f64>>, Vec<Vec<f64>>)> {
        let n = waypoints.len();
        let mut out_w = vec![waypoints[0].clone()];
        let mut out_e = vec![Vec::new()];
        let mut i = 0;
        while i + 1 < n {
            let mut j = n - 1;
            loop {
                if j == i + 1 {
                    out_w.push(waypoints[j].clone());
                    out_e.push(edges[j].clone());
                    break;
                }
                (self.c.interrupt)()?;
                if let Some(states) = self.validate_edge(&waypoints[i], &waypoints[j], false)? {
                    self.stats.shortcuts += 1;
                    out_w.push(waypoints[j].clone());
                    out_e.push(states);
                    break;
                }
                j = i + (j - i) / 2;
            }
            i = j;
        }
        Ok((out_w, out_e))
    }

    /// Validate the edges from the root to `node` that are not yet; prune below the first that
    /// fails. True when the whole path is valid.
    fn validate_path(&mut self, tree: &mut Tree, node: usize) -> PlanResult<bool> {
        for i in tree.chain(node) {
            if tree.validated[i] {
                continue;
            }
            let (a, b) = (tree.node(tree.parent[i]).to_vec(), tree.node(i).to_vec());
            match self.validate_edge(&a, &b, false)? {
                Some(states) => tree.set_edge(i, &states),
                None => {
                    self.stats.pruned += tree.prune(i);
                    return Ok(false);
                }
            }
        }
        Ok(true)
    }

    /// Check the edge from `a` to `b` (and `b` itself when `check_end`): interpolate at
    /// `edge_resolution`, project each intermediate state (posture around its interpolation),
    /// check every state. Returns the projected intermediate states (rows), or None when the edge
    /// is not valid.
    fn validate_edge(&mut self, a: &[f64], b: &[f64], check_end: bool) -> PlanResult<Option<Vec<f64>>> {
        let space = self.space;
        let nq = space.nq();
        let dist = space.distance(a, b);
        let n_mid = if self.st.edge_resolution > 0.0 {
            ((dist / self.st.edge_resolution).ceil() as usize).saturating_sub(1)
        } else {
            0
        };
        let mut states = vec![0.0; (n_mid + 1) * nq];
        if n_mid > 0 {
            let mut lin = vec![0.0; n_mid * nq];
            for k in 0..n_mid {
                let t = (k + 1) as f64 / (n_mid + 1) as f64;
                space.interpolate(a, b, t, &mut lin[k * nq..(k + 1) * nq]);
            }
            let mut reps = vec![Projection::default(); n_mid];
            self.project(&lin, &lin, &mut states[..n_mid * nq], &mut reps)?;
            self.stats.edge_projections += reps.iter().map(|r| r.iterations).sum::<usize>();
            if reps.iter().any(|r| !r.success) || states.iter().any(|x| !x.is_finite()) {
                return Ok(None);
            }
            // consecutive states must stay close (no jump to another branch of the manifold, and
            // chords short enough to stay on it): at most MAX_SPACING x the edge resolution apart
            let max_gap = MAX_SPACING * self.st.edge_resolution;
            let mut prev = a;
            for k in 0..n_mid {
                let s = &states[k * nq..(k + 1) * nq];
                if space.distance(prev, s) > max_gap {
                    return Ok(None);
                }
                prev = s;
            }
            if space.distance(prev, b) > max_gap {
                return Ok(None);
            }
        }
        states[n_mid * nq..].copy_from_slice(b);
        let n_check = n_mid + usize::from(check_end);
        let mut valid = vec![false; n_check];
        self.check_valid(&states[..n_check * nq], &mut valid)?;
        if valid.iter().all(|&v| v) {
            states.truncate(n_mid * nq);
            Ok(Some(states))
        } else {
            Ok(None)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kd_forest_agrees_with_brute_force() {
        let mut rng = StdRng::seed_from_u64(7);
        for &dim in &[2usize, 7, 34] {
            let mut kd = KdForest::new(dim);
            let mut lin = LinearNearest::new(dim);
            for n in 0..700 {
                let p: Vec<f64> = (0..dim).map(|_| rng.random_range(-1.0..1.0)).collect();
                kd.add(&p);
                lin.add(&p);
                if n % 37 == 0 {
                    let q: Vec<f64> = (0..dim).map(|_| rng.random_range(-1.2..1.2)).collect();
                    let (a, da) = kd.nearest(&q).unwrap();
                    let (b, db) = lin.nearest(&q).unwrap();
                    assert_eq!(a, b, "dim {dim} n {n}");
                    assert!((da - db).abs() < 1e-12);
                }
            }
            assert_eq!(kd.len(), 700);
        }
    }

    #[test]
    fn empty_index_has_no_nearest() {
        assert!(KdForest::new(3).nearest(&[0.0; 3]).is_none());
        assert!(LinearNearest::new(3).nearest(&[0.0; 3]).is_none());
    }
}

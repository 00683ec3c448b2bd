//! Nearest neighbours for the planner's tree: the [`NearestNeighbors`] trait, brute force
//! ([`LinearNearest`]), a dynamic kd-tree ([`KdForest`]), and the choice between them
//! ([`NeighborIndex`], [`KD_MAX_DIM`]).

/// A nearest-neighbour index over points of a fixed dimension; points are numbered in the order
/// they were added.
pub trait NearestNeighbors: Send {
    /// Forget every point; the next points have dimension `dim`.
    fn clear(&mut self, dim: usize);
    /// Add a point (its index is the number of points before it).
    fn add(&mut self, point: &[f64]);
    /// Index and squared distance of the nearest point for which `keep(index)` holds, None when
    /// there is none.
    fn nearest_where(&self, point: &[f64], keep: &dyn Fn(usize) -> bool) -> Option<(usize, f64)>;
    /// Index and squared distance of the nearest point, None when empty.
    fn nearest(&self, point: &[f64]) -> Option<(usize, f64)> {
        self.nearest_where(point, &|_| true)
    }
    /// Make room for `additional` more points (a hint; default: nothing).
    fn reserve(&mut self, _additional: usize) {}
    /// Number of points.
    fn len(&self) -> usize;
    /// True when there is no point.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

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
    /// An empty index of points of dimension `dim`.
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
    fn reserve(&mut self, additional: usize) {
        self.points.reserve(additional * self.dim);
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
/// Up to [`KD_BRUTE`] points it is all buffer, searched by brute force.
#[derive(Debug, Clone, Default)]
pub struct KdForest {
    dim: usize,
    points: Vec<f64>,
    /// The points in no static tree yet: the last `buffered` ones (indices `len - buffered..len`).
    buffered: usize,
    trees: Vec<Option<StaticKd>>,
}

/// Points the buffer takes before they go into a static tree (once there are [`KD_BRUTE`]).
const KD_BUFFER: usize = 64;

/// Points searched by brute force before the first static tree is built: below it a scan of the
/// contiguous points costs fewer instructions than building the trees and searching them, as a
/// free-space RRT-Connect tree of tens to hundreds of nodes does (the measurement is in the
/// commit that set it).
pub const KD_BRUTE: usize = 512;

impl KdForest {
    /// An empty index of points of dimension `dim`.
    pub fn new(dim: usize) -> KdForest {
        KdForest { dim, ..Default::default() }
    }
}

impl NearestNeighbors for KdForest {
    fn clear(&mut self, dim: usize) {
        self.dim = dim;
        self.points.clear();
        self.buffered = 0;
        self.trees.clear();
    }
    fn reserve(&mut self, additional: usize) {
        self.points.reserve(additional * self.dim);
    }
    fn add(&mut self, point: &[f64]) {
        debug_assert_eq!(point.len(), self.dim);
        self.points.extend_from_slice(point);
        self.buffered += 1;
        let n = self.len();
        if self.buffered < KD_BUFFER || n < KD_BRUTE {
            return;
        }
        let mut ids: Vec<usize> = (n - self.buffered..n).collect();
        self.buffered = 0;
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
        let first = self.len() - self.buffered;
        for (k, p) in self.points[first * dim..].chunks_exact(dim.max(1)).enumerate() {
            let d = dist2_bounded(p, point, best.1);
            if d < best.1 && keep(first + k) {
                best = (first + k, d);
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

/// Which nearest-neighbour index the planner builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NeighborIndex {
    /// Brute force ([`LinearNearest`]).
    Linear,
    /// The kd-forest ([`KdForest`]).
    KdForest,
    /// The kd-forest up to [`KD_MAX_DIM`] dimensions, brute force above (measured: in 7-D the
    /// kd-forest answers 1.3x faster among 1k nodes and 4.9x among 10k; in 34-D brute force is
    /// 1.1-1.2x faster, `benches/planning.rs`).
    Auto,
}

/// Dimension up to which [`NeighborIndex::Auto`] picks the kd-forest.
pub const KD_MAX_DIM: usize = 16;

impl NeighborIndex {
    /// An empty index of this kind for points of dimension `dim`.
    pub fn build(self, dim: usize) -> Box<dyn NearestNeighbors> {
        match self {
            NeighborIndex::Linear => Box::new(LinearNearest::new(dim)),
            NeighborIndex::KdForest => Box::new(KdForest::new(dim)),
            NeighborIndex::Auto if dim <= KD_MAX_DIM => Box::new(KdForest::new(dim)),
            NeighborIndex::Auto => Box::new(LinearNearest::new(dim)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn kd_forest_agrees_with_brute_force() {
        let mut rng = StdRng::seed_from_u64(7);
        for &dim in &[2usize, 7, 34] {
            let mut kd = KdForest::new(dim);
            let mut lin = LinearNearest::new(dim);
            // past KD_BRUTE (brute force alone) into static trees of several levels
            for n in 0..1300 {
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
            assert_eq!(kd.len(), 1300);
        }
    }

    #[test]
    fn empty_index_has_no_nearest() {
        assert!(KdForest::new(3).nearest(&[0.0; 3]).is_none());
        assert!(LinearNearest::new(3).nearest(&[0.0; 3]).is_none());
    }
}

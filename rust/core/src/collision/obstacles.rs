//! The obstacles of a world ([`Obstacles`]) and the static broad phase over them: a bounding-volume
//! hierarchy (parry's [`Bvh`]) over the world boxes of the bounded obstacles, plus the list of
//! the unbounded ones (half-spaces), which every query returns.
//!
//! The hierarchy is built on the first query after the obstacles change (an add, a removal, a
//! clear), so adding many obstacles one by one costs one build. The queries return *candidates*,
//! a superset of the obstacles that pass the world's own box filter (`broad_phase.rs`), in
//! ascending index order: the world then applies its unchanged per-pair filters to them in the
//! order it always did, so every answer is the one an exhaustive loop over the obstacles gives.

use std::ops::Deref;
use std::sync::OnceLock;

use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};

use super::broad_phase::box_gap;
use super::Obstacle;

/// The obstacles of a [`CollisionWorld`](super::CollisionWorld), in the order they were added
/// (read them as a slice: `world.obstacles.iter()`, `world.obstacles[0]`, `.len()`), with the
/// acceleration structure the queries use. They change only through the world's methods
/// (`add_*`, `remove_obstacle`, `clear_obstacles`), which keep the structure in step.
#[derive(Clone, Default)]
pub struct Obstacles {
    list: Vec<Obstacle>,
    index: OnceLock<Index>,
}

/// The broad phase over a fixed list of obstacles.
#[derive(Clone)]
struct Index {
    /// Over the world boxes of the bounded obstacles; leaf `l` is obstacle `bounded[l]` (parry
    /// 0.25.3's `Bvh::from_iter` wants the leaf ids 0..n when there are one or two leaves).
    bvh: Bvh,
    bounded: Vec<usize>,
    /// Indices of the obstacles without a box (half-spaces), ascending.
    unbounded: Vec<usize>,
}

impl Deref for Obstacles {
    type Target = [Obstacle];
    fn deref(&self) -> &[Obstacle] {
        &self.list
    }
}

impl Obstacles {
    pub(super) fn push(&mut self, o: Obstacle) {
        self.list.push(o);
        self.index = OnceLock::new();
    }

    pub(super) fn remove(&mut self, i: usize) {
        self.list.remove(i);
        self.index = OnceLock::new();
    }

    /// Put `o` in place of obstacle `i` (same index: the order of the others is kept).
    pub(super) fn replace(&mut self, i: usize, o: Obstacle) {
        self.list[i] = o;
        self.index = OnceLock::new();
    }

    /// Obstacle `i` to change in place (its index then rebuilt on the next query, as after
    /// [`replace`](Self::replace)).
    pub(super) fn get_mut(&mut self, i: usize) -> &mut Obstacle {
        self.index = OnceLock::new();
        &mut self.list[i]
    }

    pub(super) fn clear(&mut self) {
        self.list.clear();
        self.index = OnceLock::new();
    }

    fn index(&self) -> &Index {
        self.index.get_or_init(|| {
            let (mut unbounded, mut bounded, mut leaves) = (Vec::new(), Vec::new(), Vec::new());
            for (k, o) in self.list.iter().enumerate() {
                match &o.aabb {
                    Some(b) => {
                        leaves.push((bounded.len(), *b));
                        bounded.push(k);
                    }
                    None => unbounded.push(k),
                }
            }
            Index { bvh: Bvh::from_iter(BvhBuildStrategy::Binned, leaves), bounded, unbounded }
        })
    }

    /// Sort `out` and add the unbounded obstacles with index >= `from`, keeping it ascending.
    fn finish(&self, from: usize, out: &mut Vec<usize>) {
        out.extend(self.index().unbounded.iter().copied().filter(|&k| k >= from));
        out.sort_unstable();
    }

    /// Into `out` (cleared first), ascending: every obstacle whose world box intersects `aabb`
    /// (the test of `CollisionWorld::may_touch`) and every unbounded obstacle.
    pub(super) fn overlapping(&self, aabb: &Aabb, out: &mut Vec<usize>) {
        out.clear();
        let (list, ix) = (&self.list, self.index());
        // An inner node's box contains its leaves' boxes, so it intersects `aabb` whenever one
        // of its leaves does: pruning on it loses nothing.
        let leaves = ix.bvh.leaves(|n| n.aabb().intersects(aabb));
        out.extend(leaves.map(|l| ix.bounded[l as usize]).filter(|&k| list[k].aabb.as_ref().is_some_and(|b| b.intersects(aabb))));
        self.finish(0, out);
    }

    /// Into `out` (cleared first), ascending: every obstacle with index >= `from` whose world box
    /// may hold a pair closer than `bound` to a shape inside `aabb` (box gap 0, or below
    /// `bound`: the pairs `CollisionWorld::min_distance_unchecked` does not skip by box gap),
    /// and every unbounded obstacle with index >= `from`.
    pub(super) fn within(&self, aabb: &Aabb, bound: f64, from: usize, out: &mut Vec<usize>) {
        out.clear();
        let keep = |g: f64| !(g > 0.0 && g >= bound);
        let (list, ix) = (&self.list, self.index());
        // An inner node's box contains its leaves' boxes, so its gap is at most theirs (min and
        // max are exact and rounding is monotone): pruning on it loses nothing.
        let leaves = ix.bvh.leaves(|n| keep(box_gap(aabb, &n.aabb())));
        out.extend(
            leaves
                .map(|l| ix.bounded[l as usize])
                .filter(|&k| k >= from && list[k].aabb.as_ref().is_some_and(|b| keep(box_gap(aabb, b)))),
        );
        self.finish(from, out);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{CollisionWorld, Scratch};
    use crate::robot::preset;
    use nalgebra::{Isometry3, Vector3};
    use parry3d_f64::bounding_volume::BoundingVolume;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// Today's loops before the hierarchy: every robot geometry against every obstacle in index
    /// order, then the self pairs (`pair_iter`), through the same per-pair tests.
    fn linear_in_collision(w: &CollisionWorld, q: &[f64], s: &mut Scratch) -> bool {
        w.geometry_poses(q, s);
        w.pair_iter().any(|(i, t)| w.pair_intersects(i, t, s))
    }

    fn linear_min_distance(w: &CollisionWorld, q: &[f64], s: &mut Scratch) -> f64 {
        w.geometry_poses(q, s);
        w.pair_iter().fold(f64::INFINITY, |best, (i, t)| w.pair_min_distance(i, t, s, best))
    }

    /// `n` random boxes, spheres, capsules and cylinders within `spread` of the Panda's shoulder,
    /// and a half-space now and then.
    fn scatter(w: &mut CollisionWorld, rng: &mut StdRng, n: usize, spread: f64, tag: &str) {
        for k in 0..n {
            let name = format!("{tag}{k}");
            let c = Vector3::new(rng.random_range(-spread..spread), rng.random_range(-spread..spread), 0.3 + rng.random_range(-spread..spread));
            let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let pose = Isometry3::new(c, axis * rng.random_range(0.0..3.0));
            let size = |rng: &mut StdRng| rng.random_range(0.01..0.12);
            match rng.random_range(0..20) {
                0..=5 => w.add_box(&name, [size(rng), size(rng), size(rng)], pose).unwrap(),
                6..=10 => w.add_sphere(&name, size(rng), c.into()).unwrap(),
                11..=15 => w.add_capsule(&name, size(rng), size(rng), pose).unwrap(),
                16..=18 => w.add_cylinder(&name, size(rng), size(rng), pose).unwrap(),
                _ => {
                    let n = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
                    w.add_halfspace(&name, n, rng.random_range(-2.0..-0.6)).unwrap()
                }
            }
        }
    }

    fn compare(w: &CollisionWorld, qs: &[Vec<f64>]) -> (usize, usize) {
        let (mut s, mut r) = (Scratch::default(), Scratch::default());
        let mut hits = 0;
        let mut finite = 0;
        for q in qs {
            let hit = w.in_collision_unchecked(q, &mut s);
            assert_eq!(hit, linear_in_collision(w, q, &mut r), "in_collision at {q:?}");
            let d = w.min_distance_unchecked(q, &mut s);
            let e = linear_min_distance(w, q, &mut r);
            assert_eq!(d.to_bits(), e.to_bits(), "min_distance at {q:?}: {d} vs {e}");
            hits += hit as usize;
            finite += d.is_finite() as usize;
        }
        (hits, finite)
    }

    #[test]
    fn the_hierarchy_gives_the_linear_loops_answers_bit_for_bit() {
        let (model, base) = preset("panda").unwrap().load().unwrap();
        let mut rng = StdRng::seed_from_u64(3);
        let qs: Vec<Vec<f64>> =
            // 120 configurations: the comparison's linear loop takes ~1 min in a debug build (CI's)
            (0..120).map(|_| model.lower.iter().zip(&model.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect()).collect();
        let mut total_hits = 0;
        // sparse and far (few near the robot: the one-list path), dense and near (many near the
        // robot: the per-geometry path), one obstacle, none
        for (n, spread) in [(0, 1.0), (1, 0.5), (60, 2.5), (300, 1.0), (300, 0.6)] {
            let mut w = base.clone();
            scatter(&mut w, &mut rng, n, spread, "o");
            let (hits, finite) = compare(&w, &qs);
            assert_eq!(finite, qs.len());
            total_hits += hits;
            // the index follows removals, additions and a clear
            for k in (0..n).step_by(3) {
                w.remove_obstacle(&format!("o{k}")).unwrap();
            }
            scatter(&mut w, &mut rng, n / 4, spread, "p");
            compare(&w, &qs);
            w.check_self = false;
            compare(&w, &qs);
            w.clear_obstacles();
            assert!(w.obstacles.is_empty());
            compare(&w, &qs);
        }
        assert!(total_hits > 120, "{total_hits} configurations in collision: the scenes must be met");
    }

    #[test]
    fn half_spaces_before_one_or_two_shapes() {
        // parry's Bvh::from_iter with one or two leaves whose ids are not 0 and 1 panics: the
        // leaves are numbered apart from the obstacles
        let (model, base) = preset("panda").unwrap().load().unwrap();
        let q: Vec<f64> = model.lower.iter().zip(&model.upper).map(|(l, u)| 0.5 * (l + u)).collect();
        for shapes in 1..=3 {
            let mut w = base.clone();
            w.add_halfspace("floor", [0.0, 0.0, 1.0], -0.5).unwrap();
            w.add_halfspace("wall", [1.0, 0.0, 0.0], -1.0).unwrap();
            for k in 0..shapes {
                w.add_sphere(&format!("s{k}"), 0.1, [0.5, 0.2 * k as f64, 0.5]).unwrap();
            }
            let mut out = Vec::new();
            let everywhere = parry3d_f64::bounding_volume::Aabb::new([-9.0; 3].into(), [9.0; 3].into());
            w.obstacles.overlapping(&everywhere, &mut out);
            assert_eq!(out, (0..2 + shapes).collect::<Vec<_>>());
            compare(&w, std::slice::from_ref(&q));
        }
    }

    #[test]
    fn candidates_are_a_superset_of_the_box_filter() {
        let (_, mut w) = preset("panda").unwrap().load().unwrap();
        let mut rng = StdRng::seed_from_u64(5);
        scatter(&mut w, &mut rng, 500, 1.5, "o");
        let mut out = Vec::new();
        for _ in 0..300 {
            let c = Vector3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            let h = Vector3::new(rng.random_range(0.0..0.5), rng.random_range(0.0..0.5), rng.random_range(0.0..0.5));
            let b = parry3d_f64::bounding_volume::Aabb::new((c - h).into(), (c + h).into());
            w.obstacles.overlapping(&b, &mut out);
            let want: Vec<usize> = (0..w.obstacles.len())
                .filter(|&k| w.obstacles[k].aabb.as_ref().is_none_or(|o| o.intersects(&b)))
                .collect();
            assert_eq!(out, want);
            let bound = rng.random_range(0.0..0.5);
            let from = rng.random_range(0..w.obstacles.len());
            w.obstacles.within(&b, bound, from, &mut out);
            let want: Vec<usize> = (from..w.obstacles.len())
                .filter(|&k| {
                    w.obstacles[k].aabb.as_ref().is_none_or(|o| {
                        let g = super::box_gap(&b, o);
                        !(g > 0.0 && g >= bound)
                    })
                })
                .collect();
            assert_eq!(out, want);
        }
    }
}

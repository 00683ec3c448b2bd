//! Broad phase: which pairs are checked (the self-collision pairs, every robot geometry against
//! every obstacle) and the cheap filters that rule a pair out before the exact narrow phase
//! (world-aligned boxes, oriented boxes). Which obstacles are near a robot shape at all comes
//! from the hierarchy over the obstacles (`obstacles.rs`).

use std::collections::HashSet;

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::shape::SharedShape;

use super::{CollisionWorld, RobotGeometry, Scratch};
use crate::kinematics::KinematicModel;
use crate::srdf::Srdf;

/// The self-collision pairs (indices into `geometries`): geometries on different rigid bodies,
/// minus the SRDF's disabled link pairs.
pub(super) fn self_pairs(model: &KinematicModel, geometries: &[RobotGeometry], srdf: Option<&Srdf>) -> Vec<(usize, usize)> {
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
    self_pairs
}

/// Distance between two boxes (0 when they overlap): a lower bound on the distance of any
/// shapes inside them. Monotone: a box containing `b` is no farther from `a`.
#[inline]
pub(super) fn box_gap(a: &Aabb, b: &Aabb) -> f64 {
    let lo = (a.mins - b.maxs).sup(&(b.mins - a.maxs)).sup(&Vector3::zeros());
    lo.norm()
}

/// The second member of a pair: a robot geometry or an obstacle.
#[derive(Clone, Copy)]
pub(super) enum Target {
    Robot(usize),
    Obstacle(usize),
}

impl CollisionWorld {
    /// World bounding box of a pair's second member (None for a half-space).
    #[inline]
    pub(super) fn target_aabb<'a>(&'a self, t: Target, s: &'a Scratch) -> Option<&'a Aabb> {
        match t {
            Target::Robot(j) => Some(&s.aabbs[j]),
            Target::Obstacle(k) => self.obstacles[k].aabb.as_ref(),
        }
    }

    /// Oriented bounding box of a pair's second member (None for a half-space).
    #[inline]
    pub(super) fn target_obb<'a>(&'a self, t: Target, s: &'a Scratch) -> Option<&'a Obb> {
        match t {
            Target::Robot(j) => Some(&s.obbs[j]),
            Target::Obstacle(k) => self.obstacles[k].obb.as_ref(),
        }
    }

    /// Distance between the bounding boxes of a pair (0 when they overlap): a lower bound on
    /// the distance of the shapes.
    #[inline]
    pub(super) fn aabb_gap(&self, i: usize, t: Target, s: &Scratch) -> f64 {
        match self.target_aabb(t, s) {
            Some(b) => box_gap(&s.aabbs[i], b),
            None => f64::NEG_INFINITY,
        }
    }

    /// Broadphase: can robot geometry `i` touch target `t` (boxes overlap)?
    #[inline]
    pub(super) fn may_touch(&self, i: usize, t: Target, s: &Scratch, margin: f64) -> bool {
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
    pub(super) fn pair_iter(&self) -> impl Iterator<Item = (usize, Target)> + '_ {
        let selfs = self
            .self_pairs
            .iter()
            .filter(move |_| self.check_self)
            .map(|&(i, j)| (i, Target::Robot(j)));
        let envs = (0..self.geometries.len())
            .flat_map(move |i| (0..self.obstacles.len()).map(move |k| (i, Target::Obstacle(k))));
        envs.chain(selfs)
    }

    pub(super) fn target<'a>(&'a self, t: Target, poses: &[Isometry3<f64>]) -> (Isometry3<f64>, &'a SharedShape, Point3<f64>, f64) {
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

    pub(super) fn target_name(&self, t: Target) -> &str {
        match t {
            Target::Robot(j) => &self.geometries[j].name,
            Target::Obstacle(k) => &self.obstacles[k].name,
        }
    }
}

/// An oriented bounding box in the world: centre, axes (columns) and half extents.
#[derive(Debug, Clone, Default)]
pub(super) struct Obb {
    center: Vector3<f64>,
    axes: Matrix3<f64>,
    half: Vector3<f64>,
}

impl Obb {
    /// `local` (a box in the shape frame) placed at `pose`.
    pub(super) fn new(local: &Aabb, pose: &Isometry3<f64>) -> Obb {
        Obb {
            center: (pose * local.center()).coords,
            axes: pose.rotation.to_rotation_matrix().into_inner(),
            half: local.half_extents(),
        }
    }

    /// The world-aligned box around it (what `Aabb::transform_by` gives for the local box).
    pub(super) fn aabb(&self) -> Aabb {
        let e = self.axes.abs() * self.half;
        Aabb::new((self.center - e).into(), (self.center + e).into())
    }

    /// The smallest value of `dot(n, x)` over the box's points `x`.
    #[inline]
    pub(super) fn lowest_along(&self, n: &Vector3<f64>) -> f64 {
        let along = self.axes.tr_mul(n); // n in the box's axes
        n.dot(&self.center) - along.abs().dot(&self.half)
    }

    /// True when a separating axis exists (the boxes do not overlap): the 15-axis test of
    /// Gottschalk, Lin and Manocha (1996), with a small epsilon on the cross-product axes so
    /// that near-parallel edges never separate by round-off (the test only errs towards
    /// "overlap", which sends the pair to the exact narrow phase).
    pub(super) fn separated(&self, o: &Obb) -> bool {
        self.separated_by(o, 0.0)
    }

    /// [`separated`](Self::separated) with this box grown by `margin` (>= 0) along each of its
    /// axes: the grown box contains every point within `margin` of this one, so true means the
    /// shapes inside the two boxes are farther apart than `margin`.
    pub(super) fn separated_by(&self, o: &Obb, margin: f64) -> bool {
        const EPS: f64 = 1e-9;
        let r = self.axes.transpose() * o.axes; // o's axes in self's frame
        let t = self.axes.transpose() * (o.center - self.center);
        let abs_r = r.map(|x| x.abs() + EPS);
        let grown = self.half.add_scalar(margin);
        let (a, b) = (&grown, &o.half);
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

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::query;
    use parry3d_f64::shape::Cuboid;
    use rand::{Rng, SeedableRng};

    fn random_pose(rng: &mut rand::rngs::StdRng, spread: f64) -> Isometry3<f64> {
        let t = Vector3::new(rng.random_range(-spread..spread), rng.random_range(-spread..spread), rng.random_range(-spread..spread));
        let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        Isometry3::new(t, axis * rng.random_range(0.0..3.0))
    }

    #[test]
    fn lowest_along_is_the_lowest_corner() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for _ in 0..1000 {
            let h = Vector3::new(rng.random_range(0.01..0.5), rng.random_range(0.01..0.5), rng.random_range(0.01..0.5));
            let pose = random_pose(&mut rng, 1.0);
            let n = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize();
            let obb = Obb::new(&Aabb::new((-h).into(), h.into()), &pose);
            let corners = (0..8).map(|k| {
                let c = Vector3::new(if k & 1 == 0 { -h.x } else { h.x }, if k & 2 == 0 { -h.y } else { h.y }, if k & 4 == 0 { -h.z } else { h.z });
                n.dot(&(pose * nalgebra::Point3::from(c)).coords)
            });
            let lowest = corners.fold(f64::INFINITY, f64::min);
            assert!((obb.lowest_along(&n) - lowest).abs() < 1e-12, "{} vs {lowest}", obb.lowest_along(&n));
        }
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

//! Swept-motion bounds ([`MotionBounds`]): how far any point of each robot geometry can move
//! along a straight motion in the configuration space, `q(t) = q0 (+) t (q1 (-) q0)`, t in
//! [0, 1] (the interpolation of [`KinematicModel::integrate`] and
//! [`KinematicModel::difference`]), relative to the world (against obstacles) and relative to
//! each self-collision partner. With the clearance query
//! [`CollisionWorld::clear_by`](super::CollisionWorld::clear_by) they certify a whole motion
//! collision-free from its two ends (conservative advancement, as in Schwarzer, Saha and
//! Latombe's adaptive dynamic collision checking, 2005): a pair whose distance at each end
//! exceeds half its bound cannot touch in between.
//!
//! The bound of a point p of a geometry on link L: its speed is at most
//! `|v_base| + |w_base| rho_base + sum_j |dq_j| rho_j`, with `dq = q1 (-) q0` (constant along
//! the motion), `rho_j` the distance from joint j's origin to any point of the geometry (for a
//! revolute or continuous joint; 1 for a prismatic one) and `rho_base` that from the root frame
//! (free-flyer base), each bounded without the configuration by the lengths of the chain's
//! fixed offsets, the travel of its prismatic joints and the geometry's bounding sphere
//! (triangle inequality). A joint above both members of a self pair moves them together: it is
//! left out of that pair's bound, as the base is.

use nalgebra::{Unit, Vector3};

use super::{CollisionWorld, Scratch};
use crate::kinematics::{KinematicModel, Motion};

/// One active joint above a geometry.
#[derive(Debug, Clone)]
struct Term {
    /// Its tangent index (a mimic joint's: its master's).
    v: usize,
    /// |dq_v| times this is the joint's own motion (a mimic joint's |multiplier|, else 1).
    scale: f64,
    /// Lever arm bound without the configuration (1 for a prismatic joint).
    rho: f64,
    /// Its joint (index into the model's joints) and axis in the joint frame; None: prismatic.
    joint: usize,
    axis: Option<Unit<Vector3<f64>>>,
}

/// How far each robot geometry, and each self pair relative to each other, can move along a
/// straight motion: per geometry the active joints above it (root first) with their lever arms.
/// Built once per world ([`MotionBounds::new`]); None when a prismatic joint above a geometry
/// has no finite limits (its lever arms are unbounded).
#[derive(Debug, Clone)]
pub struct MotionBounds {
    /// Per geometry: the active joints above it, root first.
    terms: Vec<Vec<Term>>,
    /// Per geometry: the largest distance of its points from the root frame's origin.
    base_rho: Vec<f64>,
    /// Per self pair (the world's `self_pairs` order): its two geometries and how many leading
    /// terms they share (the joints above both, which move them together).
    pairs: Vec<(usize, usize, usize)>,
    floating_base: bool,
    nv: usize,
}

/// Lever arms at one configuration ([`MotionBounds::levers`]): per geometry, the distance of
/// its bounding sphere from each revolute joint's axis (and from the root frame's origin),
/// tighter than the configuration-free bounds, with what they may grow by along a motion.
#[derive(Debug, Clone, Default)]
pub struct Levers {
    /// Per geometry, per term: the lever arm at the configuration, plus its growth so far.
    arm: Vec<Vec<f64>>,
    /// Per geometry: distance from the root frame's origin, plus its growth so far.
    base: Vec<f64>,
}

/// The displacement bounds of a motion ([`MotionBounds::sweep`]): per geometry against the
/// world, per self pair between its members. Reused between calls.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    /// Per geometry.
    pub geometry: Vec<f64>,
    /// Per self pair.
    pub pairs: Vec<f64>,
    /// Per geometry, per term: the term's contribution (scratch).
    contrib: Vec<Vec<f64>>,
}

impl MotionBounds {
    /// The bounds of `world`'s robot geometries and self pairs; None when a prismatic joint
    /// above a geometry has an infinite limit.
    pub fn new(world: &CollisionWorld) -> Option<MotionBounds> {
        let m: &KinematicModel = &world.model;
        let n_links = m.link_names.len();
        // the joint (index into m.joints) whose child each link is
        let mut parent_joint = vec![None; n_links];
        for (k, j) in m.joints.iter().enumerate() {
            parent_joint[j.child] = Some(k);
        }
        let mut terms = Vec::with_capacity(world.geometries.len());
        let mut base_rho = Vec::with_capacity(world.geometries.len());
        for g in &world.geometries {
            // the joints from the geometry's link up to the root, leaf first
            let mut chain = Vec::new();
            let mut link = g.link;
            while let Some(k) = parent_joint[link] {
                chain.push(k);
                link = m.joints[k].parent;
            }
            // lever arm below each joint: the geometry's extent in its link frame, plus, going up,
            // each joint's fixed offset and prismatic travel
            let mut rho = (g.offset * g.center).coords.norm() + g.radius;
            let mut mine = Vec::new();
            for &k in &chain {
                let j = &m.joints[k];
                let (v, scale) = j.velocity_column().map_or((0, 0.0), |(v, s)| (v, s.abs()));
                match j.motion {
                    Motion::Revolute { axis } | Motion::Continuous { axis } => mine.push(Term { v, scale, rho, joint: k, axis: Some(axis) }),
                    Motion::Prismatic { .. } => {
                        mine.push(Term { v, scale, rho: 1.0, joint: k, axis: None });
                        let (q, _, mul, off) = j.driver().unwrap_or((j.q_index, v, 1.0, 0.0));
                        let travel = mul.abs() * m.lower[q].abs().max(m.upper[q].abs()) + off.abs();
                        if !travel.is_finite() {
                            return None;
                        }
                        rho += travel;
                    }
                    Motion::Fixed => {}
                }
                rho += j.origin.translation.vector.norm();
            }
            mine.reverse();
            terms.push(mine);
            base_rho.push(rho);
        }
        let pairs = world
            .self_pairs
            .iter()
            .map(|&(a, b)| (a, b, terms[a].iter().zip(&terms[b]).take_while(|(x, y)| x.joint == y.joint).count()))
            .collect();
        Some(MotionBounds { terms, base_rho, pairs, floating_base: m.floating_base, nv: m.nv })
    }

    /// The lever arms at the configuration `world` last posed into `s`
    /// ([`CollisionWorld::pose`]), into `out`: for each geometry, the distance of its bounding
    /// sphere from each revolute joint's axis line (plus its radius), and from the root frame's
    /// origin.
    pub fn levers(&self, world: &CollisionWorld, s: &Scratch, out: &mut Levers) {
        out.arm.resize_with(self.terms.len(), Vec::new);
        out.base.clear();
        let root = s.links.get(world.model.root).map(|p| p.translation.vector).unwrap_or_default();
        for (g, terms) in self.terms.iter().enumerate() {
            let geo = &world.geometries[g];
            let c = (s.poses[g] * geo.center).coords;
            let arm = &mut out.arm[g];
            arm.clear();
            for t in terms {
                arm.push(match t.axis {
                    Some(axis) => {
                        let frame = &s.links[world.model.joints[t.joint].child];
                        let a = frame.rotation * axis.into_inner();
                        let r = c - frame.translation.vector;
                        (r - a * r.dot(&a)).norm() + geo.radius
                    }
                    None => 1.0,
                });
            }
            out.base.push((c - root).norm() + geo.radius);
        }
    }

    /// The displacement bounds of the motion `dq` (= q1 (-) q0, length nv) over the fraction
    /// `f` of it (from its start), added to `out` (which `clear` empties): with `levers` (taken
    /// at the motion's start, or at the run's first state), each lever arm is the one there plus
    /// what the joints below may move the geometry by (and `levers` grows by this motion, for the
    /// next motion of a run), capped by the configuration-free bound; without, the
    /// configuration-free bounds.
    pub fn sweep(&self, dq: &[f64], f: f64, levers: Option<&mut Levers>, out: &mut Sweep) {
        debug_assert_eq!(dq.len(), self.nv);
        let n = self.terms.len();
        out.geometry.resize(n, 0.0);
        out.contrib.resize_with(n, Vec::new);
        let (lin, ang) = if self.floating_base {
            ((dq[0] * dq[0] + dq[1] * dq[1] + dq[2] * dq[2]).sqrt(), (dq[3] * dq[3] + dq[4] * dq[4] + dq[5] * dq[5]).sqrt())
        } else {
            (0.0, 0.0)
        };
        let mut levers = levers;
        for (g, terms) in self.terms.iter().enumerate() {
            // static contributions |dq_j| rho_j, and below[j]: their sum over the joints below j
            let contrib = &mut out.contrib[g];
            contrib.clear();
            contrib.extend(terms.iter().map(|t| dq[t.v].abs() * t.scale * t.rho));
            let mut below = contrib.iter().sum::<f64>();
            let all = below;
            for (k, t) in terms.iter().enumerate() {
                below -= contrib[k];
                let speed = dq[t.v].abs() * t.scale;
                if let Some(l) = levers.as_deref_mut() {
                    let arm = &mut l.arm[g][k];
                    // the average lever over [0, f]: the arm now plus half of its growth
                    let lever = (*arm + 0.5 * below.max(0.0) * f).min(t.rho);
                    contrib[k] = speed * lever * f;
                    *arm += below.max(0.0) * f;
                } else {
                    contrib[k] *= f;
                }
            }
            let mut base = 0.0;
            if self.floating_base {
                let lever = match levers.as_deref_mut() {
                    Some(l) => {
                        let lever = (l.base[g] + 0.5 * all * f).min(self.base_rho[g]);
                        l.base[g] += all * f;
                        lever
                    }
                    None => self.base_rho[g],
                };
                base = (lin + ang * lever) * f;
            }
            // suffix sums: contrib[k] becomes the bound of the joints from k down
            for k in (0..contrib.len().saturating_sub(1)).rev() {
                contrib[k] += contrib[k + 1];
            }
            out.geometry[g] += contrib.first().copied().unwrap_or(0.0) + base;
        }
        out.pairs.resize(self.pairs.len(), 0.0);
        for (p, &(a, b, k)) in self.pairs.iter().enumerate() {
            let from = |g: usize| out.contrib[g].get(k).copied().unwrap_or(0.0);
            out.pairs[p] += from(a) + from(b);
        }
    }
}

impl Sweep {
    /// Zero the bounds (before [`MotionBounds::sweep`] adds a run's motions).
    pub fn clear(&mut self) {
        self.geometry.iter_mut().for_each(|x| *x = 0.0);
        self.pairs.iter_mut().for_each(|x| *x = 0.0);
    }

    /// Multiply the bounds by `k`.
    pub fn scale(&mut self, k: f64) {
        self.geometry.iter_mut().chain(self.pairs.iter_mut()).for_each(|x| *x *= k);
    }
}

#[cfg(test)]
mod tests {
    use super::super::Scratch;
    use super::*;
    use crate::planning::{CollisionChecker, Space, ValidityChecker};
    use crate::robot::preset;
    use nalgebra::{Isometry3, Point3, Vector3};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn random_q(model: &KinematicModel, rng: &mut StdRng) -> Vec<f64> {
        let mut q: Vec<f64> = model
            .lower
            .iter()
            .zip(&model.upper)
            .map(|(&l, &u)| if l.is_finite() && u.is_finite() { rng.random_range(l..=u) } else { rng.random_range(-1.0..1.0) })
            .collect();
        if model.floating_base {
            let n = q[3..7].iter().map(|x| x * x).sum::<f64>().sqrt();
            q[3..7].iter_mut().for_each(|x| *x /= n);
        }
        q
    }

    /// Points on each geometry's bounding sphere (centre and six poles) in the world at q.
    fn sphere_points(w: &CollisionWorld, q: &[f64]) -> Vec<Vec<Point3<f64>>> {
        let mut links = Vec::new();
        w.model.forward_kinematics_unchecked(q, &mut links);
        w.geometries
            .iter()
            .map(|g| {
                let pose: Isometry3<f64> = links[g.link] * g.offset;
                let mut pts = vec![pose * g.center];
                for a in 0..3 {
                    for s in [-1.0, 1.0] {
                        let mut e = Vector3::zeros();
                        e[a] = s * g.radius;
                        pts.push(pose * (g.center + e));
                    }
                }
                pts
            })
            .collect()
    }

    /// Along straight motions of the Panda, of Talos (free-flyer base) and of the Panda with its
    /// fingers free (one mimicking the other), no point of a geometry's bounding sphere moves
    /// farther over [0, t] than its bound over that fraction,
    /// and no pair's points change their distance by more than the pair's bound: with the
    /// configuration-free lever arms and with those at the motion's start; and over a run of
    /// two motions, with the arms at the run's start. The arms at the start are tighter.
    #[test]
    fn the_bounds_hold_along_motions() {
        let mut rng = StdRng::seed_from_u64(7);
        let fingers = crate::robot::RobotDescription {
            locked_joints: crate::robot::LockedJoints::FromReference(Vec::new()),
            ..preset("panda").unwrap()
        };
        for (name, robot) in [("panda", preset("panda").unwrap()), ("talos", preset("talos").unwrap()), ("panda, mimic fingers", fingers)] {
            let (model, world) = robot.load().unwrap();
            let bounds = MotionBounds::new(&world).unwrap();
            let mut s = Scratch::default();
            let (mut tight, mut gain): (f64, f64) = (0.0, 0.0);
            for trial in 0..20 {
                let q0 = random_q(&model, &mut rng);
                let far = random_q(&model, &mut rng);
                let mut q1 = vec![0.0; model.nq];
                // short and long motions
                let scale = [0.02, 0.3, 1.0][trial % 3];
                model.interpolate(&q0, &far, scale, &mut q1);
                let mut q2 = vec![0.0; model.nq];
                model.interpolate(&q1, &random_q(&model, &mut rng), scale, &mut q2);
                let (mut dq, mut dq2) = (vec![0.0; model.nv], vec![0.0; model.nv]);
                model.difference(&q0, &q1, &mut dq);
                model.difference(&q1, &q2, &mut dq2);
                world.pose(&q0, &mut s);
                let mut at_start = Levers::default();
                bounds.levers(&world, &s, &mut at_start);
                let p0 = sphere_points(&world, &q0);
                let mut qt = vec![0.0; model.nq];
                // the run q0 -> q1 -> q2 at 32 points; t in (0, 2]
                for k in 1..=32 {
                    let t = k as f64 / 16.0;
                    let (mut fixed, mut lever) = (Sweep::default(), Sweep::default());
                    let mut l = at_start.clone();
                    if t <= 1.0 {
                        model.interpolate(&q0, &q1, t, &mut qt);
                        bounds.sweep(&dq, t, None, &mut fixed);
                        bounds.sweep(&dq, t, Some(&mut l), &mut lever);
                    } else {
                        model.interpolate(&q1, &q2, t - 1.0, &mut qt);
                        bounds.sweep(&dq, 1.0, None, &mut fixed);
                        bounds.sweep(&dq2, t - 1.0, None, &mut fixed);
                        bounds.sweep(&dq, 1.0, Some(&mut l), &mut lever);
                        bounds.sweep(&dq2, t - 1.0, Some(&mut l), &mut lever);
                    }
                    let pt = sphere_points(&world, &qt);
                    for sweep in [&fixed, &lever] {
                        for (g, (a, b)) in p0.iter().zip(&pt).enumerate() {
                            for (x, y) in a.iter().zip(b) {
                                let moved = (y - x).norm();
                                let bound = sweep.geometry[g];
                                assert!(moved <= bound * (1.0 + 1e-9) + 1e-12, "{name}: geometry {g} moved {moved} > {bound} at t {t}");
                                tight = tight.max(moved / bound);
                            }
                        }
                        for (p, &(i, j)) in world.self_pairs.iter().enumerate() {
                            for (xi, yi) in p0[i].iter().zip(&pt[i]) {
                                let (xj, yj) = (p0[j][0], pt[j][0]);
                                // what the bound serves: the distance between two points of the pair
                                let rel = ((yi - yj).norm() - (xi - xj).norm()).abs();
                                assert!(rel <= sweep.pairs[p] * (1.0 + 1e-9) + 1e-12, "{name}: pair {p} moved {rel} > {} at t {t}", sweep.pairs[p]);
                            }
                        }
                    }
                    for (a, b) in lever.geometry.iter().zip(&fixed.geometry) {
                        assert!(a <= &(b * (1.0 + 1e-12)), "{name}: the arms at the start are never looser");
                        gain = gain.max(b / a);
                    }
                }
            }
            // the bounds are not vacuous: some point moves by a sizeable share of its bound; the
            // arms at the start tighten some bound by a good factor
            assert!(tight > 0.2, "{name}: loosest ratio {tight}");
            assert!(gain > 1.5, "{name}: best tightening {gain}");
        }
    }

    /// clear_by with one margin for every pair says what close_pairs says; a motion the checker
    /// certifies collides nowhere along it (dense samples), with obstacles near the Panda.
    #[test]
    fn clearance_matches_close_pairs_and_certified_motions_are_free() {
        let (model, mut world) = preset("panda").unwrap().load().unwrap();
        world.add_box("table", [0.4, 0.6, 0.02], Isometry3::translation(0.5, 0.0, 0.2)).unwrap();
        world.add_sphere("ball", 0.1, [0.3, 0.3, 0.6]).unwrap();
        world.add_halfspace("floor", [0.0, 0.0, 1.0], -0.3).unwrap();
        let bounds = MotionBounds::new(&world).unwrap();
        let mut rng = StdRng::seed_from_u64(11);
        let mut s = Scratch::default();
        let (ng, np) = (world.geometries.len(), world.self_pairs.len());
        let (mut certified, mut clear_seen, mut close_seen, mut certified_by_levers) = (0, 0, 0, 0);
        let mut checker = CollisionChecker::new(std::sync::Arc::new(world.clone()), false);
        for _ in 0..60 {
            let q0 = random_q(&model, &mut rng);
            let margin = rng.random_range(0.0..0.02);
            let clear = world.clear_by(&q0, &vec![margin; ng], &vec![margin; np], &mut s);
            assert_eq!(clear, world.close_pairs(&q0, margin).unwrap().is_empty(), "margin {margin} at {q0:?}");
            clear_seen += clear as usize;
            close_seen += !clear as usize;
            // a short motion, certified from both ends as the planner's checker does
            let far = random_q(&model, &mut rng);
            let mut q1 = vec![0.0; model.nq];
            model.interpolate(&q0, &far, 0.05, &mut q1);
            let mut dq = vec![0.0; model.nv];
            model.difference(&q0, &q1, &mut dq);
            let mut sw = Sweep::default();
            bounds.sweep(&dq, 0.5, None, &mut sw);
            let (g, p) = (&sw.geometry, &sw.pairs);
            // the checker's certificate, with the lever arms at each end, is free along the motion too
            if checker.certify_motion(&q0, &q1).unwrap() {
                certified_by_levers += 1;
                let mut qt = vec![0.0; model.nq];
                for k in 0..=64 {
                    model.interpolate(&q0, &q1, k as f64 / 64.0, &mut qt);
                    assert!(!world.in_collision_unchecked(&qt, &mut s), "certified motion collides at t = {}", k as f64 / 64.0);
                }
            }
            if world.clear_by(&q0, g, p, &mut s) && world.clear_by(&q1, g, p, &mut s) {
                certified += 1;
                let mut qt = vec![0.0; model.nq];
                for k in 0..=64 {
                    model.interpolate(&q0, &q1, k as f64 / 64.0, &mut qt);
                    assert!(!world.in_collision_unchecked(&qt, &mut s), "certified motion collides at t = {}", k as f64 / 64.0);
                }
            }
        }
        assert!(clear_seen >= 3 && close_seen > 5 && certified > 5, "{clear_seen} clear, {close_seen} close, {certified} certified");
        assert!(certified_by_levers >= certified, "the arms at the ends certify at least as much: {certified_by_levers} < {certified}");
    }
}

//! Validity checkers: the [`ValidityChecker`] trait and the native ones, joint limits plus the
//! parry collision world ([`CollisionChecker`]) and no check at all ([`AlwaysValid`]). A checker
//! may also certify whole motions ([`ValidityChecker::certify_motion`]): the collision checker
//! does it with the swept-motion bounds of `collision/motion.rs`. [`SphereChecker`] checks the
//! robot's covering spheres instead of its exact geometry (`collision/spheres.rs`): faster and
//! conservative (free by the spheres is free by the exact geometry).

use std::sync::{Arc, OnceLock};

use rayon::prelude::*;

use super::PlanResult;
use crate::collision::spheres::{SphereScratch, SphereWorld, LANES};
use crate::collision::{CollisionWorld, Levers, MotionBounds, Scratch, Sweep};
use crate::kinematics::KinematicModel;

/// Says which configurations are valid (collision-free, within limits, ...).
pub trait ValidityChecker: Send {
    /// `valid[i]` for row i of `qs` (n x nq).
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()>;

    /// True when each of the `n` rows of `qs` (n x nq) is valid, and how many rows were checked
    /// to say so (`n` when they all are). A checker may stop at the first invalid row it meets
    /// (the rows in order: a caller puts those most likely to fail first); the answer is the
    /// same as [`check`](Self::check)'s. Default: [`check`](Self::check) on every row.
    fn all_valid(&mut self, qs: &[f64], n: usize) -> PlanResult<(bool, usize)> {
        let mut valid = vec![false; n];
        self.check(qs, &mut valid)?;
        Ok((valid.iter().all(|&v| v), n))
    }

    /// Can [`certify_motion`](Self::certify_motion) answer (default: no)?
    fn certifies_motions(&self) -> bool {
        false
    }

    /// How many states one call checks for about the price of one (a vector checker's lanes):
    /// callers that may check states beyond the first invalid one batch this many. Default 1.
    fn lanes(&self) -> usize {
        1
    }

    /// For two valid configurations `a` and `b`: true when every configuration of the straight
    /// motion between them (`a (+) t (b (-) a)`, t in [0, 1]) is certainly valid; false when
    /// that cannot be shown (the motion may still be valid). Only called when
    /// [`certifies_motions`](Self::certifies_motions).
    fn certify_motion(&mut self, _a: &[f64], _b: &[f64]) -> PlanResult<bool> {
        Ok(false)
    }

    /// For the rows of `path` (n + 1 states, the first one known valid): `valid[i]` for each
    /// state, and `certified[k]` when the motion from state k to k + 1 is certainly valid (both
    /// ends valid). Returns how many certificates it computed. Default: [`check`](Self::check)
    /// and [`certify_motion`](Self::certify_motion) for each chord with valid ends.
    fn certify_path(&mut self, path: &[f64], valid: &mut [bool], certified: &mut [bool]) -> PlanResult<usize> {
        self.check(path, valid)?;
        let nq = path.len() / valid.len();
        let mut n = 0;
        for k in 0..certified.len() {
            certified[k] = false;
            if valid[k] && valid[k + 1] {
                n += 1;
                certified[k] = self.certify_motion(&path[k * nq..(k + 1) * nq], &path[(k + 1) * nq..(k + 2) * nq])?;
            }
        }
        Ok(n)
    }
}

/// Valid = within the joint limits and not in collision (parry world, self-collision included
/// when the world checks it).
pub struct CollisionChecker {
    /// The robot and its obstacles.
    pub world: Arc<CollisionWorld>,
    /// Check the configurations of a batch on rayon's threads.
    pub parallel: bool,
    scratch: Scratch,
    /// The world's swept-motion bounds (None: it cannot certify motions), built when first
    /// asked for: only certified edges need them, and a plan builds its checker per call.
    bounds: OnceLock<Option<MotionBounds>>,
    dq: Vec<f64>,
    levers: Levers,
    sweep: Sweep,
}

impl CollisionChecker {
    /// A checker of the configurations against `world`.
    pub fn new(world: Arc<CollisionWorld>, parallel: bool) -> CollisionChecker {
        CollisionChecker {
            world,
            parallel,
            scratch: Scratch::default(),
            bounds: OnceLock::new(),
            dq: Vec::new(),
            levers: Levers::default(),
            sweep: Sweep::default(),
        }
    }

    /// Within the joint limits (1e-9 of slack).
    fn in_limits(m: &KinematicModel, q: &[f64]) -> bool {
        (0..m.nq).all(|i| q[i] >= m.lower[i] - 1e-9 && q[i] <= m.upper[i] + 1e-9)
    }

    fn valid_one(world: &CollisionWorld, q: &[f64], s: &mut Scratch) -> bool {
        Self::in_limits(&world.model, q) && !world.in_collision_unchecked(q, s)
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

    /// Yes, unless a prismatic joint without finite limits leaves the swept bounds unbounded.
    fn certifies_motions(&self) -> bool {
        self.bounds.get_or_init(|| MotionBounds::new(&self.world)).is_some()
    }

    /// Conservative advancement: from each end, the bound on how far the geometry moves over its
    /// half of the motion (`collision/motion.rs`, with the lever arms at that end) as the
    /// clearance margin there ([`CollisionWorld::clear_by_posed`]). Joint limits hold along the
    /// motion when they hold at its ends (each coordinate moves linearly).
    fn certify_motion(&mut self, a: &[f64], b: &[f64]) -> PlanResult<bool> {
        let Some(bounds) = self.bounds.get_or_init(|| MotionBounds::new(&self.world)) else {
            return Ok(false);
        };
        let m: &KinematicModel = &self.world.model;
        self.dq.resize(m.nv, 0.0);
        m.difference(a, b, &mut self.dq);
        for q in [a, b] {
            let w = &self.world;
            w.pose(q, &mut self.scratch);
            bounds.levers(w, &self.scratch, &mut self.levers);
            self.sweep.clear();
            bounds.sweep(&self.dq, 0.5, Some(&mut self.levers), &mut self.sweep);
            if !w.clear_by_posed(&self.sweep.geometry, &self.sweep.pairs, &mut self.scratch) {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// Conservative advancement along the polyline: from a state, the motion through the next L
    /// chords is certified when the state is clear by the bound on how far the geometry moves
    /// along them (with the lever arms at that state); L doubles while that holds (starting from
    /// the last run's length), so one query covers many chords far from obstacles. A chord no
    /// run covers is tried from both ends ([`certify_motion`](ValidityChecker::certify_motion)).
    /// States are checked for the joint limits; a state a run covers is collision-free; any other
    /// is checked.
    fn certify_path(&mut self, path: &[f64], valid: &mut [bool], certified: &mut [bool]) -> PlanResult<usize> {
        let Some(bounds) = self.bounds.get_or_init(|| MotionBounds::new(&self.world)) else {
            certified.fill(false);
            return self.check(path, valid).map(|_| 0);
        };
        let m = self.world.model.clone();
        let (nq, nv) = (m.nq, m.nv);
        let n_seg = certified.len();
        for (q, v) in path.chunks(nq).zip(valid.iter_mut()) {
            *v = Self::in_limits(&m, q);
        }
        certified.fill(false);
        if !valid.iter().all(|&v| v) {
            return Ok(0);
        }
        // every chord's motion
        let mut dqs = vec![0.0; n_seg * nv];
        for k in 0..n_seg {
            m.difference(&path[k * nq..(k + 1) * nq], &path[(k + 1) * nq..(k + 2) * nq], &mut dqs[k * nv..(k + 1) * nv]);
        }
        let mut queries = 0;
        let mut covered = vec![false; n_seg + 1];
        covered[0] = true;
        let (mut k, mut run) = (0, 1);
        let mut start_levers = Levers::default();
        while k < n_seg {
            let w = &self.world;
            w.pose(&path[k * nq..(k + 1) * nq], &mut self.scratch);
            bounds.levers(w, &self.scratch, &mut start_levers);
            let mut best = 0;
            let mut len = run.min(n_seg - k);
            loop {
                // the run's bound: its chords one after the other, the lever arms growing
                self.levers.clone_from(&start_levers);
                self.sweep.clear();
                for i in k..k + len {
                    bounds.sweep(&dqs[i * nv..(i + 1) * nv], 1.0, Some(&mut self.levers), &mut self.sweep);
                }
                queries += 1;
                if !w.clear_by_posed(&self.sweep.geometry, &self.sweep.pairs, &mut self.scratch) {
                    break;
                }
                best = len;
                if k + len == n_seg {
                    break;
                }
                len = (2 * len).min(n_seg - k);
            }
            if best == 0 {
                run = 1;
                k += 1;
            } else {
                certified[k..k + best].fill(true);
                covered[k..=k + best].fill(true);
                run = best;
                k += best;
            }
        }
        // states no run covered: checked; chords between valid ones: tried from both ends
        for k in 0..=n_seg {
            if !covered[k] {
                valid[k] = !self.world.in_collision_unchecked(&path[k * nq..(k + 1) * nq], &mut self.scratch);
            }
        }
        for k in 0..n_seg {
            if !certified[k] && valid[k] && valid[k + 1] {
                queries += 1;
                certified[k] = self.certify_motion(&path[k * nq..(k + 1) * nq], &path[(k + 1) * nq..(k + 2) * nq])?;
            }
        }
        Ok(queries)
    }
}

/// Valid = within the joint limits and free by the robot's spheres
/// ([`SphereWorld`]: a conservative check, so a valid state is free by the exact geometry too).
/// With `confirm`, a state the spheres find in collision is checked again by the exact geometry
/// of the spheres' world ([`CollisionWorld::in_collision_unchecked`](crate::collision::CollisionWorld::in_collision_unchecked)),
/// whose answer stands: the exact check's answers, at the spheres' cost where the robot is
/// free (the spheres' false positives, near contact or between the covers of close links,
/// refuse nothing). A batch is checked [`LANES`] configurations at a time; with `parallel`,
/// blocks of them on rayon's threads. Motions are not certified (the planner checks their states).
pub struct SphereChecker {
    /// The spheres and the world.
    pub spheres: Arc<SphereWorld>,
    /// Check the blocks of a batch on rayon's threads.
    pub parallel: bool,
    /// Confirm each collision the spheres find with the exact geometry.
    pub confirm: bool,
    scratch: SphereScratch<LANES>,
    exact: crate::collision::Scratch,
}

impl SphereChecker {
    /// A checker of the configurations against `spheres` (`confirm`: see the type).
    pub fn new(spheres: Arc<SphereWorld>, parallel: bool, confirm: bool) -> SphereChecker {
        SphereChecker { spheres, parallel, confirm, scratch: SphereScratch::default(), exact: Default::default() }
    }
}

impl ValidityChecker for SphereChecker {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        let m = &self.spheres.world.model;
        let nq = m.nq;
        // rows outside the limits are answered without the spheres
        let block = nq * LANES;
        let sw = &self.spheres;
        let confirm = self.confirm;
        let run = |rows: &[f64], out: &mut [bool], s: &mut SphereScratch<LANES>, exact: &mut crate::collision::Scratch| {
            sw.in_collision_batch(rows, out, s);
            for (q, v) in rows.chunks(nq).zip(out.iter_mut()) {
                let within = CollisionChecker::in_limits(m, q);
                *v = within && (!*v || (confirm && !sw.world.in_collision_unchecked(q, exact)));
            }
        };
        if self.parallel && valid.len() > 2 * LANES {
            valid
                .par_chunks_mut(4 * LANES)
                .zip(qs.par_chunks(4 * block))
                .for_each_init(<(SphereScratch<LANES>, crate::collision::Scratch)>::default, |(s, e), (out, rows)| run(rows, out, s, e));
        } else {
            run(qs, valid, &mut self.scratch, &mut self.exact);
        }
        Ok(())
    }

    /// [`LANES`]: the spheres of 8 states are tested in one pass.
    fn lanes(&self) -> usize {
        LANES
    }

    /// The joint limits of every row first (no kinematics), then the spheres in blocks of
    /// [`LANES`] rows, stopping at the first lane in collision
    /// ([`SphereWorld::any_in_collision`]); with `confirm`, the rows of that block the spheres
    /// find in collision are checked by the exact geometry in order, and the rows after it
    /// go on when none is.
    fn all_valid(&mut self, qs: &[f64], n: usize) -> PlanResult<(bool, usize)> {
        let m = &self.spheres.world.model;
        let nq = m.nq;
        debug_assert_eq!(qs.len(), n * nq);
        if let Some(i) = qs.chunks(nq).position(|q| !CollisionChecker::in_limits(m, q)) {
            return Ok((false, i + 1));
        }
        let mut start = 0;
        while start < n {
            let (hit, checked) = self.spheres.any_in_collision(&qs[start * nq..], &mut self.scratch);
            if !hit {
                return Ok((true, n));
            }
            if !self.confirm {
                return Ok((false, start + checked));
            }
            // the block that hit: the blocks start every LANES rows from `start`, and the
            // hitting one ends the rows checked
            let first = start + (checked - 1) / LANES * LANES;
            let end = start + checked;
            let mut flags = [false; LANES];
            let rows = &qs[first * nq..end * nq];
            self.spheres.in_collision_batch(rows, &mut flags[..end - first], &mut self.scratch);
            for (k, q) in rows.chunks(nq).enumerate() {
                if flags[k] && self.spheres.world.in_collision_unchecked(q, &mut self.exact) {
                    return Ok((false, first + k + 1));
                }
            }
            start = end;
        }
        Ok((true, n))
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

    fn certifies_motions(&self) -> bool {
        true
    }

    fn certify_motion(&mut self, _a: &[f64], _b: &[f64]) -> PlanResult<bool> {
        Ok(true)
    }
}

//! Validity checkers: the [`ValidityChecker`] trait and the native ones, joint limits plus the
//! parry collision world ([`CollisionChecker`]) and no check at all ([`AlwaysValid`]).

use std::sync::Arc;

use rayon::prelude::*;

use super::PlanResult;
use crate::collision::{CollisionWorld, Scratch};

/// Says which configurations are valid (collision-free, within limits, ...).
pub trait ValidityChecker: Send {
    /// `valid[i]` for row i of `qs` (n x nq).
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()>;
}

/// Valid = within the joint limits and not in collision (parry world, self-collision included
/// when the world checks it).
pub struct CollisionChecker {
    /// The robot and its obstacles.
    pub world: Arc<CollisionWorld>,
    /// Check the configurations of a batch on rayon's threads.
    pub parallel: bool,
    scratch: Scratch,
}

impl CollisionChecker {
    /// A checker of the configurations against `world`.
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

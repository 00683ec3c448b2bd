//! Constrained RRT: the GAN paper's Algorithm 1 (Section III-C), with projected extensions.
//!
//! The planner grows a tree from a start configuration towards K goal configurations (found by
//! IK beforehand). Each iteration samples a configuration, extends the tree from its nearest
//! node towards it ([`Planner`]'s *ConstrainedExtend*: steps of `step` radians, each projected
//! onto the constraint manifold with a posture task around the interpolated configuration), then
//! extends greedily from the reached node towards the nearest goal. It succeeds when a goal is
//! reached within `goal_tolerance`. The start and goals are checked first (on the manifold, by
//! the projector; valid, by the checker), and a bad one is refused with its name and the reason
//! ([`Planner::plan`]): a success never rests on an input that fails the planner's own checks.
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
//! The projected intermediate states are kept and make up the returned dense path. With
//! [`EdgeCheck::Certified`] the motions between them are certified collision-free too
//! ([`ValidityChecker::certify_path`]; the collision checker by conservative advancement with the
//! swept-motion bounds of `collision/motion.rs`), states being added where a chord cannot be.
//!
//! The search runs on a [`ConstrainedSpace`] (OMPL's `ProjectedStateSpace` with its
//! `ConstrainedMotionValidator`): the ambient space, the projector and the checker behind one
//! type whose constrained steps and geodesics (the projected, checked edges) every planner uses;
//! the planners keep the tree logic only. [`Settings::algorithm`] picks the search: the paper's
//! cRRT ([`Algorithm::Crrt`], the default) or a bidirectional constrained RRT-Connect
//! ([`Algorithm::RrtConnect`]: a tree from the start, one rooted at every goal).
//!
//! The files, one concept each: `error` (PlanError), `space` (configuration spaces), `sampler`,
//! `projector`, `checker` (the components and their native implementations), `nearest` (the
//! nearest-neighbour indices), `constrained` (the constrained space), `tree` (the search tree),
//! `rrt` (settings, the planner and the cRRT), `rrt_connect` (RRT-Connect's attempt), `simplify`
//! (free-space path simplification).
//! Everything is re-exported here: the paths are `genplan_core::planning::X`.

mod checker;
mod constrained;
mod error;
mod nearest;
mod projector;
mod rrt;
mod rrt_connect;
mod sampler;
mod simplify;
mod space;
mod tree;

pub use checker::{AlwaysValid, CollisionChecker, SphereChecker, ValidityChecker};
pub use error::{ComponentError, PlanError, PlanResult};
pub use nearest::{KdForest, LinearNearest, NearestNeighbors, NeighborIndex, KD_BRUTE, KD_MAX_DIM};
pub use projector::{GaussNewtonProjector, Projection, Projector};
pub use constrained::{ConstrainedSpace, Step};
pub use rrt::{Algorithm, Components, EdgeCheck, Named, Planner, Settings, Solution, Stats, MAX_SPACING};
pub use sampler::{standard_normal, uniform_in_box, valid_box, DataSampler, Halton, MixtureSampler, Sampler, Sampling, UniformSampler};
pub use space::{EuclideanSpace, Space};

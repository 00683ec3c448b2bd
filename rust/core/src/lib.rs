//! genplan-core: the pure-Rust part of genplan.
//!
//! * [`urdf`] / [`srdf`]: strict readers for the robot description files.
//! * [`kinematics`]: forward kinematics of every link, q in Pinocchio's convention.
//! * [`lie`]: SO(3) / SE(3) maps (log, exp) and their Jacobians, in Pinocchio's conventions.
//! * [`collision`]: parry collision world (self-collision with SRDF filtering, obstacles),
//!   answering "in collision?" and signed minimum distance; one file each for the geometry,
//!   the broad phase and the world.
//! * [`robot`]: robot descriptions as data (robot files: URDF + SRDF + options), loaded into both.
//! * [`projection`]: damped Gauss-Newton projection / IK with a null-space posture task, one file
//!   per concept (the terms, their checks, custom terms, the solver, residuals, errors).
//! * [`gan`]: native inference of a trained GAN generator, as a planner sampler.
//! * [`planning`]: the constrained RRT, one file per concept (errors, space, samplers,
//!   projectors, validity checkers, nearest neighbours, the RRT itself).
//! * [`jerk`]: jerk-limited, phase-synchronised rest-to-rest timing of straight joint-space
//!   segments (7-segment S-curves), stopping at each state of a path.
//! * [`dynamics`] / [`control`]: rigid-body dynamics of a fixed-base robot and its 1 kHz P-D +
//!   disturbance-observer loop (the seq2seq paper's spatula experiment one configuration of it).
//! * [`error`]: the crate's [`Error`] (the planner has its own, [`planning::PlanError`]).
//!
//! Nothing here depends on Python: `cargo test` and `cargo bench` run without it.

#![warn(missing_docs)]

pub mod collision;
pub mod codec;
pub mod control;
mod cpu;
pub mod dynamics;
pub mod flow;
pub mod error;
pub mod gan;
pub mod jerk;
pub mod kinematics;
pub mod lie;
pub mod mesh;
pub mod planning;
pub mod projection;
pub mod robot;
pub mod srdf;
pub mod timing;
pub mod urdf;

pub use collision::{CollisionWorld, Scratch};
pub use error::{Error, Result};
pub use kinematics::{KinematicModel, ModelOptions};
pub use robot::RobotDescription;

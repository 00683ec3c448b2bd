//! The 1 kHz loop of the seq2seq paper (Kutsuzawa et al. 2019, Section 5, Fig. 10) for every
//! fixed-base robot: a P-D controller with a disturbance observer on the robot's simulated
//! dynamics, with model errors, payloads and joint limits.
//!
//! * [`settings`]: the controller, the disturbances and the joint limits, defined once;
//! * [`controllers`]: the P-D law in the task space of any frame (free axes; a damped inverse,
//!   or for a redundant arm a damped pseudo-inverse with a null-space posture term) or in joint
//!   space, through the nominal model;
//! * [`observer`]: the disturbance observer;
//! * [`plant`]: the true robot (its URDF dynamics, friction, torque offsets, unknown payloads;
//!   RK4, continuous joints on their circle);
//! * [`payloads`]: what the robot holds: rigid payloads, and payloads with dynamics of their own
//!   such as the paper's pancake;
//! * [`limits`]: torque and speed limits every tick, with a policy (log, saturate, stop);
//! * [`reference`](mod@reference): what a run follows, and the checks of a joint trajectory before it runs;
//! * [`run`]: the loop (allocation-free per tick, the log allocated up front, Ctrl-C polled,
//!   paced or as fast as it goes);
//! * [`spatula`]: the paper's experiment as one configuration of the loop (eq. 23 on the UR5's
//!   spatula frame, the spatula and the pancake as payloads).
//!
//! Every tick (period `dt`, 1 ms by default): the controller measures the plant's state and
//! computes `tau = M_n(q) qdd_ref + h_n(q, v) + tau_dis_hat` on its nominal model (the robot and
//! the payloads it knows); the torque is checked against the limits (and clipped by the
//! `saturate` policy); the plant (the robot, the payloads, the disturbances) runs `dt` under
//! it; a payload with dynamics steps with the achieved motion of the controller's frame.

pub mod controllers;
pub mod limits;
pub mod observer;
pub mod payloads;
pub mod plant;
pub mod reference;
pub mod run;
pub mod settings;
pub mod spatula;

pub use controllers::{Controller, JointCommand, TaskCommand};
pub use limits::{LimitKind, LimitViolation, Limits};
pub use observer::DisturbanceObserver;
pub use payloads::{phi, wrap_angle, FrameMotion, Pancake, PancakeMode, PancakeOnSpatula, PancakeSettings, Payload, PayloadDynamics, PlanarMotion};
pub use plant::Plant;
pub use reference::{JointReference, Reference, ReferenceCheck, ReferenceError};
pub use run::{percentile, Log, Run, SimConfig, Simulation, Summary, TickOutput, MAX_TICKS, STOP_CHECK_TICKS};
pub use settings::{ControlSpace, ControllerSettings, Disturbances, JointLimits, LimitPolicy, MAX_MASS, MAX_OFFSET};
pub use spatula::{attitude_matrix, reference_disturbances, PancakeSummary, Spatula, SpatulaConfig, SpatulaRun, SpatulaSetup};

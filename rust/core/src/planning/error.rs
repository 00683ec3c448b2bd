//! The planner's errors: [`PlanError`], one variant per kind of failure, and the boxed error
//! of a component ([`ComponentError`]) that a failing sampler, projector or checker returns.

/// An error from a component the planner calls (e.g. a Python exception), kept intact so the
/// caller gets it back as it was raised.
pub type ComponentError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a plan (or a planner part's construction) stopped without a result. Every variant but
/// [`PlanError::Component`] and [`PlanError::Internal`] is the caller's error; its text names
/// what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// A planner setting has a bad value ([`Settings::validate`](super::Settings::validate)).
    #[error("settings: {msg}")]
    Settings {
        /// The setting at fault (the first one, when the message names several).
        field: &'static str,
        /// What is wrong with it (the text after "settings: ").
        msg: String,
    },
    /// The start configuration is malformed (length, NaN), not on the constraint manifold, or
    /// not valid (in collision or outside the joint limits).
    #[error("{0}")]
    InvalidStart(String),
    /// The goal rows are malformed, one of them is not on the constraint manifold, or none of
    /// them is valid.
    #[error("{0}")]
    InvalidGoal(String),
    /// Another input is malformed: a configuration given to [`Planner::extend`](super::Planner::extend),
    /// or an argument of a native sampler's constructor.
    #[error("{0}")]
    Input(String),
    /// The sampler gave no usable batch: a malformed configuration, or (in the bindings) its
    /// lock was poisoned.
    #[error("{0}")]
    Sampler(String),
    /// No sample could be projected onto the manifold in `max_empty_batches` batches in a row.
    #[error("{0}")]
    NoProjectableSample(String),
    /// A component (sampler, projector, validity checker, interrupt check) failed.
    #[error("{0}")]
    Component(ComponentError),
    /// The search ran out of [`Settings::time_limit`](super::Settings::time_limit):
    /// [`Planner::plan`](super::Planner::plan) returns an unsuccessful plan
    /// ([`Stats::timed_out`](super::Stats::timed_out)), never this error.
    #[error("the search ran out of its time limit")]
    TimeLimit,
    /// A result failed the planner's own final check: a bug in the planner, never returned as
    /// a success.
    #[error("{0}")]
    Internal(String),
}

/// The result of the planner and its parts.
pub type PlanResult<T> = std::result::Result<T, PlanError>;

//! The planner: its [`Settings`], what a plan cost ([`Stats`]) and returns ([`Solution`]), the
//! [`Components`] a plan calls, and the [`Planner`] itself: input checks, attempts, the paper's
//! cRRT (Algorithm 1: ConstrainedExtend towards samples, then greedily towards the nearest
//! goal), lazy pruning, shortcutting. The constrained steps and edges are the
//! [`ConstrainedSpace`]'s; [`Algorithm::RrtConnect`]'s attempt is in `rrt_connect.rs`.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::constrained::ConstrainedSpace;
use super::tree::{extract, flatten, Tree};
use super::{NeighborIndex, PlanError, PlanResult, Projection, Projector, Sampler, Sampling, Space, ValidityChecker};

/// Consecutive states of a validated edge are at most this many edge resolutions apart.
pub const MAX_SPACING: f64 = 1.25;

/// The search algorithm on the constrained space ([`Settings::algorithm`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Algorithm {
    /// The GAN paper's constrained RRT (Algorithm 1): one tree from the start, each iteration
    /// extended towards a sample, then greedily towards the nearest goal.
    #[default]
    Crrt,
    /// A bidirectional constrained RRT-Connect: a tree from the start and one rooted at every
    /// goal; each iteration extends one tree towards a sample and connects the other to the
    /// state reached, then the trees swap roles.
    RrtConnect,
}

/// A setting chosen by name ([`Algorithm`], [`EdgeCheck`]): its values with their names.
pub trait Named: Copy + PartialEq + Sized + 'static {
    /// Every value with its name, the default first.
    const NAMES: &'static [(&'static str, Self)];
    /// What the setting is called in messages (`"algorithm"`, `"edge check"`).
    const WHAT: &'static str;

    /// Its name.
    fn name(self) -> &'static str {
        Self::NAMES.iter().find(|(_, a)| *a == self).map_or(Self::NAMES[0].0, |(n, _)| *n)
    }

    /// The value of this name, or None.
    fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, a)| *a)
    }
}

impl Named for Algorithm {
    const NAMES: &'static [(&'static str, Algorithm)] = &[("crrt", Algorithm::Crrt), ("rrt_connect", Algorithm::RrtConnect)];
    const WHAT: &'static str = "algorithm";
}

/// How the motion between consecutive states of an edge is validated ([`Settings::edge_check`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EdgeCheck {
    /// States at `edge_resolution` along the edge, each projected and checked; the motion
    /// between two states is not checked (as OMPL's discrete motion validator).
    #[default]
    Sampled,
    /// The states at `edge_resolution` as [`Sampled`](EdgeCheck::Sampled), and every chord
    /// between consecutive states certified valid by the checker
    /// ([`ValidityChecker::certify_path`](super::ValidityChecker::certify_path) /
    /// [`certify_motion`](super::ValidityChecker::certify_motion): the collision checker by
    /// conservative advancement). A chord that fails is split at its projected midpoint, down to
    /// `edge_resolution /` [`CERTIFY_REFINEMENT`](Settings::CERTIFY_REFINEMENT); one still
    /// uncertified there refuses the edge.
    Certified,
}

impl Named for EdgeCheck {
    const NAMES: &'static [(&'static str, EdgeCheck)] = &[("sampled", EdgeCheck::Sampled), ("certified", EdgeCheck::Certified)];
    const WHAT: &'static str = "edge check";
}

/// Planner settings. Defaults: the GAN paper's public code (the values marked "Paper" below),
/// plus edge validation at 0.025 rad.
///
/// The ranges [`validate`](Settings::validate) accepts are closed: every length is at most
/// [`MAX_LENGTH`](Settings::MAX_LENGTH), a sample batch at most
/// [`MAX_SAMPLE_BATCH`](Settings::MAX_SAMPLE_BATCH) configurations, and the edge resolution is
/// 0 or at least [`MIN_EDGE_RESOLUTION`](Settings::MIN_EDGE_RESOLUTION) and fine enough for at
/// most [`MAX_EDGE_STATES`](Settings::MAX_EDGE_STATES) states on a tree edge: no buffer the
/// planner allocates and no count it computes can overflow or exhaust memory at once.
/// (`max_increments`, `max_extensions`, `max_empty_batches` and `retries` are budgets of loops
/// that allocate nothing up front, and a plan checks for an interrupt at every iteration: any
/// count >= 1, or >= 0 for `retries`, is accepted.)
#[derive(Debug, Clone)]
pub struct Settings {
    /// Length of one extension step (tangent norm, rad for joint spaces), in (0, 1e6].
    /// Paper: 0.3.
    pub step: f64,
    /// Steps per extension (ConstrainedExtend) at most. Paper: 10.
    pub max_increments: usize,
    /// An extension stops when a projected state lands farther than this many steps from the
    /// previous one (the projection jumped to another branch of the manifold), in (0, 1e6].
    /// Paper: 3.
    pub max_jump: f64,
    /// A goal is reached when the tree gets within this distance of it, in (0, 1e6].
    /// Paper: 1e-3.
    pub goal_tolerance: f64,
    /// Iterations (sample + extension + extension to the goal; RRT-Connect: sample + extension
    /// + connection of the other tree) per attempt. Paper: 500.
    pub max_extensions: usize,
    /// Attempts after a failed one, each from a fresh tree. Paper: 2.
    pub retries: usize,
    /// Project each sample onto the manifold before extending towards it (as the authors' code).
    pub project_samples: bool,
    /// Samples requested from the sampler per call, from 1 to 65536
    /// ([`MAX_SAMPLE_BATCH`](Settings::MAX_SAMPLE_BATCH)).
    pub sample_batch: usize,
    /// Spacing of the projected, checked states along each tree edge; 0 disables edge
    /// validation (then only the tree nodes are checked, as in the paper). Otherwise between
    /// 1e-6 and 1e6 inclusive, and at least `step * max_jump / 2^20` (a tree edge, at most
    /// `max_jump * step` long, then holds at most
    /// [`MAX_EDGE_STATES`](Settings::MAX_EDGE_STATES) states).
    pub edge_resolution: f64,
    /// Validate edges lazily: only those of a path that reaches a goal (a failing edge prunes its
    /// subtree and the search goes on). Otherwise every edge is validated as it is added.
    pub lazy_edges: bool,
    /// Simplify the solution. On a manifold: greedy shortcuts, each a projected, validated
    /// straight edge. In free space: reduce, partial shortcuts and smoothing, repeated while they
    /// shorten the path (`simplify.rs`). Off by default: the paper's timings have none.
    pub simplify: bool,
    /// The nearest-neighbour index.
    pub neighbors: NeighborIndex,
    /// Give up after this many consecutive sample batches without one projectable sample.
    pub max_empty_batches: usize,
    /// The search: the paper's cRRT (default) or RRT-Connect (same components, same edges).
    pub algorithm: Algorithm,
    /// How edges are validated: states at `edge_resolution` (default) or certified chords
    /// (needs `edge_resolution` > 0 and a checker that certifies motions).
    pub edge_check: EdgeCheck,
    /// How the uniform samples are drawn: random (default) or a seeded Halton sequence
    /// ([`Sampling`]). The planner draws from whatever [`Sampler`] its [`Components`] hold; this
    /// says how the front end (genplan.planning.Planner) makes its [`UniformSampler`](super::UniformSampler)
    /// (`with_sampling`), alone or inside a mixture.
    pub sampling: Sampling,
    /// Seconds the search may take (its attempts together, from the start of the plan call;
    /// simplifying a path found within it is not cut short); 0 (the default): no limit, only the
    /// iteration budgets. A plan out of time is unsuccessful with `Stats::timed_out` set. At
    /// most [`MAX_TIME_LIMIT`](Self::MAX_TIME_LIMIT).
    pub time_limit: f64,
    /// RRT-Connect only: each iteration extends the smaller tree towards the sample (the start
    /// tree on a tie) and connects the other one to it, as VAMP's RRT-Connect does, instead of
    /// alternating the trees. Off by default (the paper's planner alternates); on in free space
    /// (genplan.planning.FREE_SPACE_SETTINGS), where it planned the motion bench's tuning
    /// problems faster on every robot (benches/free_space_settings.py). A tree
    /// that cannot grow (its extensions all blocked) is tried every iteration while it is the
    /// smaller one.
    pub balance: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            step: 0.3,
            max_increments: 10,
            max_jump: 3.0,
            goal_tolerance: 1e-3,
            max_extensions: 500,
            retries: 2,
            project_samples: true,
            sample_batch: 16,
            edge_resolution: 0.025,
            lazy_edges: true,
            simplify: false,
            neighbors: NeighborIndex::Auto,
            max_empty_batches: 100,
            algorithm: Algorithm::Crrt,
            edge_check: EdgeCheck::Sampled,
            sampling: Sampling::Random,
            time_limit: 0.0,
            balance: false,
        }
    }
}

impl Settings {
    /// The largest `step`, `goal_tolerance` and `edge_resolution` (tangent norms: rad for joint
    /// spaces), and the largest `max_jump` (in steps): 1e6. Products of two of them stay finite.
    pub const MAX_LENGTH: f64 = 1e6;
    /// The smallest non-zero `edge_resolution`: 1e-6 (rad for joint spaces).
    pub const MIN_EDGE_RESOLUTION: f64 = 1e-6;
    /// The most states validated on one edge: 2^20 (= 1048576). A tree edge is at most
    /// `max_jump * step` long, so `edge_resolution` must be at least `step * max_jump / 2^20`;
    /// a longer edge (a shortcut) that would need more states is not taken.
    pub const MAX_EDGE_STATES: usize = 1 << 20;
    /// The largest `sample_batch`: 65536 configurations per sampler call (the planner holds
    /// two buffers of `sample_batch x nq` numbers).
    pub const MAX_SAMPLE_BATCH: usize = 1 << 16;
    /// With [`EdgeCheck::Certified`], chords are split down to `edge_resolution / 8` at most.
    pub const CERTIFY_REFINEMENT: f64 = 8.0;
    /// The largest `time_limit`: 1e6 s (11.6 days).
    pub const MAX_TIME_LIMIT: f64 = 1e6;

    /// Check every value ([`PlanError::Settings`] names the first bad one, its value and the
    /// bound it breaks):
    ///
    /// * `step`, `max_jump`, `goal_tolerance`: positive, finite, at most
    ///   [`MAX_LENGTH`](Self::MAX_LENGTH);
    /// * `edge_resolution`: 0, or between [`MIN_EDGE_RESOLUTION`](Self::MIN_EDGE_RESOLUTION)
    ///   and [`MAX_LENGTH`](Self::MAX_LENGTH) inclusive and at least `step * max_jump /`
    ///   [`MAX_EDGE_STATES`](Self::MAX_EDGE_STATES);
    /// * `max_increments`, `max_extensions`, `sample_batch`, `max_empty_batches`: at least 1;
    ///   `sample_batch` at most [`MAX_SAMPLE_BATCH`](Self::MAX_SAMPLE_BATCH);
    /// * `edge_check`: certified needs `edge_resolution` > 0 (its finest spacing, times
    ///   [`CERTIFY_REFINEMENT`](Self::CERTIFY_REFINEMENT));
    /// * `time_limit`: 0 (none) or positive, finite, at most [`MAX_TIME_LIMIT`](Self::MAX_TIME_LIMIT);
    /// * `retries`, the flags, `neighbors`, `algorithm` and `sampling`: any value.
    pub fn validate(&self) -> PlanResult<()> {
        let bad = |field: &'static str, msg: String| Err(PlanError::Settings { field, msg });
        let max = Self::MAX_LENGTH;
        let length = |field: &'static str, v: f64| {
            if !(v.is_finite() && v > 0.0) {
                bad(field, format!("{field} must be positive and finite, got {v}"))
            } else if v > max {
                bad(field, format!("{field} must be at most {max:e}, got {v:?}"))
            } else {
                Ok(())
            }
        };
        length("step", self.step)?;
        length("max_jump", self.max_jump)?;
        length("goal_tolerance", self.goal_tolerance)?;
        let (er, min_er) = (self.edge_resolution, Self::MIN_EDGE_RESOLUTION);
        if !(er.is_finite() && er >= 0.0) {
            return bad("edge_resolution", format!("edge_resolution must be >= 0, got {er}"));
        }
        if er > 0.0 && er < min_er {
            return bad(
                "edge_resolution",
                format!("edge_resolution must be 0 (no edge validation) or at least {min_er:e}, got {er:?}"),
            );
        }
        if er > max {
            return bad("edge_resolution", format!("edge_resolution must be at most {max:e}, got {er:?}"));
        }
        if self.edge_check == EdgeCheck::Certified && er == 0.0 {
            return bad("edge_check", "edge_check 'certified' needs edge_resolution > 0 (edges are validated), got 0".into());
        }
        // a tree edge is at most max_jump * step long (Run::extend): its state count is bounded
        let longest = self.step * self.max_jump;
        // certified edges split chords down to er / CERTIFY_REFINEMENT
        let refine = if self.edge_check == EdgeCheck::Certified { Self::CERTIFY_REFINEMENT } else { 1.0 };
        if er > 0.0 && longest * refine / er > Self::MAX_EDGE_STATES as f64 {
            return bad(
                "edge_resolution",
                format!(
                    "edge_resolution must be at least step * max_jump{} / {} = {:e} (at most {} states on a tree edge of up to step * max_jump = {:?} long), got {er:?}",
                    if refine > 1.0 { format!(" * {refine} (certified edges)") } else { String::new() },
                    Self::MAX_EDGE_STATES,
                    longest * refine / Self::MAX_EDGE_STATES as f64,
                    Self::MAX_EDGE_STATES,
                    longest
                ),
            );
        }
        let counts = [("max_increments", self.max_increments), ("max_extensions", self.max_extensions), ("sample_batch", self.sample_batch), ("max_empty_batches", self.max_empty_batches)];
        if let Some(&(field, _)) = counts.iter().find(|&&(_, n)| n == 0) {
            return bad(field, "max_increments, max_extensions, sample_batch and max_empty_batches must be >= 1".into());
        }
        if self.sample_batch > Self::MAX_SAMPLE_BATCH {
            return bad(
                "sample_batch",
                format!("sample_batch must be in [1, {}], got {}", Self::MAX_SAMPLE_BATCH, self.sample_batch),
            );
        }
        let tl = self.time_limit;
        if !(tl.is_finite() && (0.0..=Self::MAX_TIME_LIMIT).contains(&tl)) {
            return bad(
                "time_limit",
                format!("time_limit must be 0 (no limit) or in (0, {:e}] seconds, got {tl}", Self::MAX_TIME_LIMIT),
            );
        }
        Ok(())
    }
}

/// What a plan cost.
#[derive(Debug, Clone, Default)]
pub struct Stats {
    /// A goal was reached.
    pub success: bool,
    /// Attempts made after the first (0 when the first attempt succeeded).
    pub retries: usize,
    /// Iterations (the paper's extension steps E), over all attempts.
    pub extensions: usize,
    /// Optimisation steps of the projections of samples and extension steps (the paper's
    /// "Opt. Steps"), over all attempts.
    pub projections: usize,
    /// Projector calls for samples and extension steps (configurations projected).
    pub projection_calls: usize,
    /// Optimisation steps spent validating edges (states between tree nodes).
    pub edge_projections: usize,
    /// Configurations drawn from the sampler.
    pub samples: usize,
    /// Samples whose projection failed.
    pub samples_rejected: usize,
    /// Configurations given to the validity checker.
    pub validity_checks: usize,
    /// Motions the checker was asked to certify (edge chords, with certified edges).
    pub motion_certificates: usize,
    /// Chord midpoints checked against the projector's chord tolerance (with a projector that
    /// holds the chords to one: [`Projector::check_chords`]).
    pub chord_checks: usize,
    /// Tree nodes at the end of the last attempt.
    pub nodes: usize,
    /// Nodes pruned because an edge above them failed (lazy) validation.
    pub pruned: usize,
    /// Shortcuts taken when simplifying the solution.
    pub shortcuts: usize,
    /// The search ran out of `time_limit` (the plan is then unsuccessful).
    pub timed_out: bool,
    /// Wall time of the whole plan, in seconds.
    pub time_s: f64,
    /// Seconds spent in the sampler (the rest of `time_s`, beyond the sampler, projector and
    /// checker, is the tree, nearest neighbours and bookkeeping).
    pub sampler_s: f64,
    /// Seconds spent in the projector (samples, extension steps and edges).
    pub projector_s: f64,
    /// Seconds spent in the validity checker.
    pub checker_s: f64,
    /// Seconds spent simplifying the solution (included in `time_s`; its checks in `checker_s`).
    pub simplify_s: f64,
}

/// A plan's outcome.
#[derive(Debug, Clone)]
pub struct Solution {
    /// A goal was reached (else the path is empty).
    pub success: bool,
    /// The tree nodes from start to goal (rows of nq).
    pub waypoints: Vec<f64>,
    /// The dense path: waypoints and the validated states between them (rows of nq).
    pub path: Vec<f64>,
    /// Which goal was reached.
    pub goal_index: Option<usize>,
    /// What the plan cost.
    pub stats: Stats,
}

/// The components of one plan.
pub struct Components<'a> {
    /// Draws the configurations the tree grows towards.
    pub sampler: &'a mut dyn Sampler,
    /// Projects samples, extension steps and edge states onto the manifold; None plans in free
    /// space (no constraint but the checker's: the joint limits and collisions), where nothing
    /// is projected and the ambient space is the manifold.
    pub projector: Option<&'a mut dyn Projector>,
    /// Says which states are valid.
    pub checker: &'a mut dyn ValidityChecker,
    /// Called once per iteration; an error (e.g. a KeyboardInterrupt) ends the plan.
    pub interrupt: &'a mut dyn FnMut() -> PlanResult<()>,
}

/// The constrained RRT of the GAN paper (Algorithm 1).
pub struct Planner {
    /// The configuration space.
    pub space: Arc<dyn Space>,
    /// Its settings, validated.
    pub settings: Settings,
}

/// State of one plan call (the planner itself stays immutable and shareable): the constrained
/// space (which keeps the stats), the sampler, the interrupt check and the sample buffer.
pub(super) struct Run<'a> {
    pub(super) space: ConstrainedSpace<'a>,
    pub(super) st: &'a Settings,
    sampler: &'a mut dyn Sampler,
    pub(super) interrupt: &'a mut dyn FnMut() -> PlanResult<()>,
    /// When the search must stop (`time_limit`; None: no limit, or the search is over).
    deadline: Option<Instant>,
    /// The clock is read for the deadline every `clock_stride` polls (`polls_left` to go), as
    /// many as took about [`CLOCK_PERIOD`] at the pace of the last ones, at most
    /// [`MAX_CLOCK_STRIDE`]; `last_clock`: when it was read last.
    clock_stride: u32,
    polls_left: u32,
    last_clock: Instant,
    /// The buffered samples (rows of nq, projected when `project_samples`), the next one at
    /// `next` (an offset into it); refilled a batch at a time into the same memory.
    samples: Vec<f64>,
    next: usize,
    /// The sampler's raw batch (rows of nq).
    raw: Vec<f64>,
    /// A free-space extension's steps (rows of nq) and their validity ([`Run::extend_free`]).
    line: Vec<f64>,
    line_ok: Vec<bool>,
    /// A validated edge's states and a chain of nodes ([`Run::validate_path`]), in memory kept
    /// from call to call.
    edge: Vec<f64>,
    chain: Vec<usize>,
}

/// The time limit is checked about this often (the clock read every few polls, as many as took
/// about this long at the pace of the last ones): a search stops within about this much of its
/// deadline, past the poll that finds it out of time; where polls turn slow all at once, within
/// [`MAX_CLOCK_STRIDE`] of the slow polls at most.
const CLOCK_PERIOD: Duration = Duration::from_micros(500);

/// Polls between two reads of the clock, at most.
const MAX_CLOCK_STRIDE: u32 = 32;

impl<'a> Run<'a> {
    fn new(space: &'a dyn Space, st: &'a Settings, c: &'a mut Components<'_>) -> Run<'a> {
        let Components { sampler, projector, checker, interrupt } = c;
        Run {
            space: ConstrainedSpace::new(space, projector.as_mut().map(|p| &mut **p as &mut dyn Projector), &mut **checker, st),
            st,
            sampler: &mut **sampler,
            interrupt: &mut **interrupt,
            deadline: None,
            clock_stride: 1,
            polls_left: 1,
            last_clock: Instant::now(),
            samples: Vec::new(),
            next: 0,
            raw: Vec::new(),
            line: Vec::new(),
            line_ok: Vec::new(),
            edge: Vec::new(),
            chain: Vec::new(),
        }
    }

    /// Asked at every iteration of a loop: the caller's interrupt check (Ctrl-C), then the time
    /// limit while one is set ([`PlanError::TimeLimit`], which [`Planner::plan`] turns into an
    /// unsuccessful plan). The clock is read every `clock_stride` polls, adapted so that reads
    /// are about [`CLOCK_PERIOD`] apart (a poll costs no clock read but every few): the stride
    /// doubles while reads come less than half a period apart, falls to 1 when a read comes more
    /// than two periods after the last one or the deadline is less than two periods away, and
    /// halves otherwise beyond a period.
    pub(super) fn poll(&mut self) -> PlanResult<()> {
        (self.interrupt)()?;
        let Some(deadline) = self.deadline else {
            return Ok(());
        };
        if self.polls_left > 1 {
            self.polls_left -= 1;
            return Ok(());
        }
        let now = Instant::now();
        if now >= deadline {
            return Err(PlanError::TimeLimit);
        }
        let since = now - self.last_clock;
        self.last_clock = now;
        if since > 2 * CLOCK_PERIOD || deadline - now < 2 * CLOCK_PERIOD {
            self.clock_stride = 1;
        } else if since < CLOCK_PERIOD / 2 {
            self.clock_stride = (self.clock_stride * 2).min(MAX_CLOCK_STRIDE);
        } else if since > CLOCK_PERIOD {
            self.clock_stride = (self.clock_stride / 2).max(1);
        }
        self.polls_left = self.clock_stride;
        Ok(())
    }

    pub(super) fn ambient(&self) -> &'a dyn Space {
        self.space.ambient
    }
}

impl Planner {
    /// A planner in `space`; the settings are validated.
    pub fn new(space: Arc<dyn Space>, settings: Settings) -> PlanResult<Planner> {
        settings.validate()?;
        Ok(Planner { space, settings })
    }

    /// Plan from `start` to any of `goals` (rows of nq, on the manifold, e.g. from IK).
    ///
    /// Before the search, every input the result's guarantee rests on is checked, and refused
    /// with a message naming it and saying why:
    ///
    /// * shape and finite values ([`Space::check`]);
    /// * on the manifold: the start and every goal are projected (posture around themselves);
    ///   one the projector cannot project, or moves by more than `goal_tolerance`, is refused
    ///   ([`PlanError::InvalidStart`], or [`PlanError::InvalidGoal`] naming every such goal,
    ///   even when others are fine: such a goal was not made for this constraint). One it moves
    ///   by less is replaced by its projection, so that every state of the path satisfies the
    ///   projector (a configuration already on the manifold is not moved at all);
    /// * valid (the checker): an invalid start is refused; invalid goals are dropped, and
    ///   refused only when none is left ([`Solution::goal_index`] says which goal was reached).
    ///
    /// A start within `goal_tolerance` of a valid goal has reached it: the solution is the start
    /// alone (one state, one waypoint, the nearest such goal), with no search.
    ///
    /// A solution is checked once more before it is returned: its path starts at the start and
    /// ends at the goal reached (its edges were validated as they were built).
    pub fn plan(&self, start: &[f64], goals: &[f64], c: &mut Components<'_>) -> PlanResult<Solution> {
        let t0 = Instant::now();
        let space = &*self.space;
        let nq = space.nq();
        space.check(start, "start").map_err(PlanError::InvalidStart)?;
        if goals.is_empty() || goals.len() % nq != 0 {
            return Err(PlanError::InvalidGoal(format!("goals: expected rows of {nq} numbers, got {} numbers", goals.len())));
        }
        for (i, g) in goals.chunks(nq).enumerate() {
            // named only when it fails (a message per goal would allocate per plan and goal)
            if space.check(g, "goals").is_err() {
                space.check(g, &format!("goals[{i}]")).map_err(PlanError::InvalidGoal)?;
            }
        }
        if self.settings.edge_check == EdgeCheck::Certified && !c.checker.certifies_motions() {
            return Err(PlanError::Settings {
                field: "edge_check",
                msg: "edge_check 'certified' needs a checker that certifies motions (the native collision world); this checker cannot: use edge_check 'sampled'".into(),
            });
        }
        let mut run = Run::new(space, &self.settings, c);
        if self.settings.time_limit > 0.0 {
            run.deadline = Some(t0 + Duration::from_secs_f64(self.settings.time_limit));
            run.last_clock = t0;
        }
        let (start, goals) = run.space.onto_manifold(start, goals)?;
        let (start, goals) = (&start[..], &goals[..]);
        let mut start_ok = [false];
        run.space.check(start, &mut start_ok)?;
        if !start_ok[0] {
            return Err(PlanError::InvalidStart("start: the configuration is not valid (in collision or outside the joint limits)".into()));
        }
        let mut goal_ok = vec![false; goals.len() / nq];
        run.space.check(goals, &mut goal_ok)?;
        let valid_goals: Vec<usize> = (0..goal_ok.len()).filter(|&i| goal_ok[i]).collect();
        if valid_goals.is_empty() {
            return Err(PlanError::InvalidGoal("goals: none of the goal configurations is valid (in collision or outside the joint limits)".into()));
        }
        // the start within goal_tolerance of a valid goal (the nearest such one) has reached it:
        // a path of one state, without a search (which would grow a tree away and back)
        // the nearest valid goal (total_cmp puts NaN distances last)
        let nearest = valid_goals
            .iter()
            .map(|&g| (g, space.distance(start, &goals[g * nq..(g + 1) * nq])))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        let at_goal = nearest.filter(|&(_, d)| d <= self.settings.goal_tolerance);
        if let Some((g, _)) = at_goal {
            let mut stats = run.space.stats;
            stats.success = true;
            stats.nodes = 1;
            stats.time_s = t0.elapsed().as_secs_f64();
            let path = start.to_vec();
            self.check_solution(&path, start, &goals[g * nq..(g + 1) * nq])?;
            return Ok(Solution { success: true, waypoints: path.clone(), path, goal_index: Some(g), stats });
        }

        let mut solution = None;
        // a goal within one step: the direct edge first (a tree grown from the start would wander
        // away and back before it connects)
        let (mut direct, mut timed_out) = match out_of_time(run.direct_attempt(start, goals, nearest))? {
            Some(direct) => (direct, false),
            None => (None, true),
        };
        for attempt in 0..=self.settings.retries {
            if timed_out {
                break;
            }
            run.space.stats.retries = attempt;
            let found = match direct.take() {
                Some(found) => Some(Some(found)),
                None => out_of_time(match self.settings.algorithm {
                    Algorithm::Crrt => run.crrt_attempt(start, goals, &valid_goals),
                    Algorithm::RrtConnect => run.connect_attempt(start, goals, &valid_goals),
                })?,
            };
            let found = match found {
                Some(Some(found)) => Some(found),
                Some(None) => None,
                None => {
                    timed_out = true;
                    None
                }
            };
            if let Some(Found { mut waypoints, mut edges, goal }) = found {
                // a path found in time is simplified whatever the clock says
                run.deadline = None;
                if self.settings.simplify {
                    let t = Instant::now();
                    (waypoints, edges) = if run.space.constrained() {
                        run.shortcut(waypoints, edges)?
                    } else {
                        run.simplify_free(waypoints, edges)?
                    };
                    run.space.stats.simplify_s += t.elapsed().as_secs_f64();
                }
                let (w, path) = flatten(&waypoints, &edges);
                solution = Some((w, path, goal));
                break;
            }
        }
        let mut stats = run.space.stats;
        stats.success = solution.is_some();
        stats.timed_out = solution.is_none() && timed_out;
        stats.time_s = t0.elapsed().as_secs_f64();
        Ok(match solution {
            Some((waypoints, path, g)) => {
                self.check_solution(&path, start, &goals[g * nq..(g + 1) * nq])?;
                Solution { success: true, waypoints, path, goal_index: Some(g), stats }
            }
            None => Solution { success: false, waypoints: Vec::new(), path: Vec::new(), goal_index: None, stats },
        })
    }

    /// The last word before a success: the path is whole rows of finite numbers from `start` to
    /// within `goal_tolerance` of `goal`. (Every state on the way was projected and checked when
    /// its edge was validated; this catches a broken invariant, not a bad input.)
    fn check_solution(&self, path: &[f64], start: &[f64], goal: &[f64]) -> PlanResult<()> {
        let nq = self.space.nq();
        let fail = |why: &str| Err(PlanError::Internal(format!("the planner found a path that fails its own check: {why}")));
        // a fold without early exit: vectorised, and a path is finite but for a broken invariant
        if path.len() < nq || path.len() % nq != 0 || !path.iter().fold(true, |ok, x| ok & x.is_finite()) {
            return fail("not whole rows of finite numbers");
        }
        if path[..nq] != *start {
            return fail("it does not begin at the start");
        }
        let d = self.space.distance(&path[path.len() - nq..], goal);
        if d.is_nan() || d > self.settings.goal_tolerance {
            return fail(&format!("it ends {} from the goal (goal_tolerance {})", short(d), self.settings.goal_tolerance));
        }
        Ok(())
    }
}

/// An attempt's outcome with the time limit read: `Some(found)` when it ended on its own,
/// `None` when it ran out of time; any other error as it is.
fn out_of_time<T>(r: PlanResult<T>) -> PlanResult<Option<T>> {
    match r {
        Ok(v) => Ok(Some(v)),
        Err(PlanError::TimeLimit) => Ok(None),
        Err(e) => Err(e),
    }
}

/// A distance for a message: three significant digits, scientific notation when tiny or huge.
pub(super) fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let sci = format!("{x:.2e}");
    let e: i32 = sci.rsplit('e').next().and_then(|e| e.parse().ok()).unwrap_or(0);
    if (-3..6).contains(&e) {
        format!("{:.*}", (2 - e).max(0) as usize, x)
    } else {
        sci
    }
}

impl Planner {
    /// One ConstrainedExtend from `from` towards `target` (on the manifold when
    /// `target_on_manifold`: the last step lands on it unprojected), outside a plan. Returns the
    /// states added (rows of nq, `from` excluded) and whether `target` was reached. With lazy
    /// edges only the states are checked; otherwise each edge too.
    pub fn extend(&self, from: &[f64], target: &[f64], target_on_manifold: bool, c: &mut Components<'_>) -> PlanResult<(Vec<f64>, bool)> {
        let space = &*self.space;
        space.check(from, "from").map_err(PlanError::Input)?;
        space.check(target, "target").map_err(PlanError::Input)?;
        let mut run = Run::new(space, &self.settings, c);
        let mut tree = Tree::new(space.nq(), space.nv(), self.settings.neighbors);
        tree.add(space, from, usize::MAX, Some(&[]));
        let reach = run.extend(&mut tree, 0, target, target_on_manifold)?;
        Ok((tree.q[space.nq()..].to_vec(), reach.reached))
    }
}

/// A path found by an attempt: its waypoints (tree nodes from the start to the goal), per
/// waypoint the validated states of the edge that leads to it (none for the first), and the
/// goal reached (its row in the goals).
pub(super) struct Found {
    pub(super) waypoints: Vec<Vec<f64>>,
    pub(super) edges: Vec<Vec<f64>>,
    pub(super) goal: usize,
}

/// Where an extension ended.
pub(super) struct Reach {
    pub(super) node: usize,
    /// The target itself was added.
    pub(super) reached: bool,
    pub(super) added: usize,
}

impl Run<'_> {
    /// One attempt of the paper's cRRT (Algorithm 1) from a fresh tree rooted at `start`: each
    /// iteration extends the tree from its nearest node towards a sample, then from the state
    /// reached towards the nearest valid goal; a path that reaches a goal is validated (lazy
    /// edges), else pruned below its first failing edge.
    fn crrt_attempt(&mut self, start: &[f64], goals: &[f64], valid_goals: &[usize]) -> PlanResult<Option<Found>> {
        let space = self.ambient();
        let nq = space.nq();
        let mut tree = Tree::new(nq, space.nv(), self.st.neighbors);
        tree.add(space, start, usize::MAX, Some(&[]));
        let mut found = None;
        let mut q_rand = Vec::with_capacity(nq);
        for _ in 0..self.st.max_extensions {
            // kept current: a time-out (poll, next_sample) leaves the attempt by `?`
            self.space.stats.nodes = tree.len();
            self.poll()?;
            self.space.stats.extensions += 1;
            self.next_sample(&mut q_rand)?;
            let near = tree.nearest(space, &q_rand);
            let a = self.extend(&mut tree, near, &q_rand, self.st.project_samples)?;
            if a.added == 0 {
                continue;
            }
            let qa = tree.node(a.node);
            let g = *valid_goals
                .iter()
                .min_by(|&&i, &&j| {
                    let di = space.distance(qa, &goals[i * nq..(i + 1) * nq]);
                    let dj = space.distance(qa, &goals[j * nq..(j + 1) * nq]);
                    di.total_cmp(&dj)
                })
                .expect("at least one valid goal");
            let goal = &goals[g * nq..(g + 1) * nq];
            let b = self.extend(&mut tree, a.node, goal, true)?;
            if b.reached && space.distance(tree.node(b.node), goal) <= self.st.goal_tolerance && self.validate_path(&mut tree, b.node)? {
                let (waypoints, edges) = extract(&tree, b.node);
                found = Some(Found { waypoints, edges, goal: g });
                break;
            }
        }
        self.space.stats.nodes = tree.len();
        Ok(found)
    }

    /// The direct edge from the start to its nearest valid goal (`nearest`: its row in the goals
    /// and its distance), when the edge is valid end to end (projected and checked as every edge
    /// is); None otherwise (then the search decides). On a manifold only a goal within one
    /// `step` is tried. In free space the straight edge is tried whatever its length, as VAMP's
    /// and OMPL's RRT-Connect try it: its states checked in rake order, so that a blocked edge is
    /// refused after a few checks, and a clear one is the path without a tree.
    fn direct_attempt(&mut self, start: &[f64], goals: &[f64], nearest: Option<(usize, f64)>) -> PlanResult<Option<Found>> {
        let space = self.ambient();
        let nq = space.nq();
        let Some((g, d)) = nearest else {
            return Ok(None);
        };
        if d.is_nan() {
            return Ok(None);
        }
        if !self.space.constrained() {
            let goal = &goals[g * nq..(g + 1) * nq];
            // one edge checked, not an iteration of the search: counted as one only when it is
            // the path
            let Some(states) = self.space.geodesic(start, goal, false)? else {
                return Ok(None);
            };
            self.space.stats.extensions += 1;
            self.space.stats.nodes = 2;
            return Ok(Some(Found { waypoints: vec![start.to_vec(), goal.to_vec()], edges: vec![Vec::new(), states], goal: g }));
        }
        if d > self.st.step {
            return Ok(None);
        }
        let goal = &goals[g * nq..(g + 1) * nq];
        let mut tree = Tree::new(nq, space.nv(), self.st.neighbors);
        tree.add(space, start, usize::MAX, Some(&[]));
        self.space.stats.extensions += 1;
        let b = self.extend(&mut tree, 0, goal, true)?;
        if b.reached && space.distance(tree.node(b.node), goal) <= self.st.goal_tolerance && self.validate_path(&mut tree, b.node)? {
            let (waypoints, edges) = extract(&tree, b.node);
            self.space.stats.nodes = tree.len();
            return Ok(Some(Found { waypoints, edges, goal: g }));
        }
        Ok(None)
    }

    /// The next (projected, when `project_samples`) sample into `q`, refilling the buffer in
    /// batches (in the memory of the previous batch: nothing is allocated per sample).
    pub(super) fn next_sample(&mut self, q: &mut Vec<f64>) -> PlanResult<()> {
        let nq = self.ambient().nq();
        let mut empty = 0;
        while self.next >= self.samples.len() {
            self.poll()?;
            let n = self.st.sample_batch;
            self.samples.clear();
            self.next = 0;
            self.raw.resize(n * nq, 0.0);
            let t = Instant::now();
            self.sampler.sample(n, &mut self.raw)?;
            self.space.stats.sampler_s += t.elapsed().as_secs_f64();
            for (i, q) in self.raw.chunks(nq).enumerate() {
                if self.ambient().check(q, "sampler output").is_err() {
                    // named only when it fails (a message per row would allocate per sample)
                    let e = self.ambient().check(q, &format!("sampler output row {i}")).unwrap_err();
                    return Err(PlanError::Sampler(format!("the sampler returned a bad configuration: {e}")));
                }
            }
            self.space.stats.samples += n;
            if self.st.project_samples && self.space.constrained() {
                let mut out = vec![0.0; n * nq];
                let mut reps = vec![Projection::default(); n];
                self.space.project(&self.raw, &self.raw, &mut out, &mut reps)?;
                self.space.stats.projection_calls += n;
                for (q, r) in out.chunks(nq).zip(&reps) {
                    self.space.stats.projections += r.iterations;
                    if r.success && q.iter().all(|x| x.is_finite()) {
                        self.samples.extend_from_slice(q);
                    } else {
                        self.space.stats.samples_rejected += 1;
                    }
                }
            } else {
                std::mem::swap(&mut self.samples, &mut self.raw);
            }
            if self.samples.is_empty() {
                empty += 1;
                if empty >= self.st.max_empty_batches {
                    return Err(PlanError::NoProjectableSample(format!(
                        "no sample could be projected onto the manifold in {} batches of {n}: check the sampler and the projector's task",
                        empty
                    )));
                }
            }
        }
        q.clear();
        q.extend_from_slice(&self.samples[self.next..self.next + nq]);
        self.next += nq;
        Ok(())
    }

    /// ConstrainedExtend from tree node `from` towards `target` (on the manifold when
    /// `target_on_manifold`): up to `max_increments` constrained steps
    /// ([`ConstrainedSpace::step`]), each added to the tree, until the target is reached or a
    /// step fails.
    pub(super) fn extend(&mut self, tree: &mut Tree, from: usize, target: &[f64], target_on_manifold: bool) -> PlanResult<Reach> {
        if !self.space.constrained() && self.st.lazy_edges {
            return self.extend_free(tree, from, target);
        }
        let space = self.ambient();
        let mut cur = from;
        let mut added = 0;
        for _ in 0..self.st.max_increments {
            let Some(step) = self.space.step(tree.node(cur), target, target_on_manifold)? else {
                break;
            };
            cur = tree.add(space, &step.q, cur, step.edge.as_deref());
            added += 1;
            if step.reached {
                return Ok(Reach { node: cur, reached: true, added });
            }
        }
        Ok(Reach { node: cur, reached: false, added })
    }

    /// [`extend`](Self::extend) in free space with lazy edges: the same steps (each
    /// [`ConstrainedSpace::step`]'s candidate: `step` towards the target from the previous one,
    /// the target itself within one step; stopped where a step would jump too far or not move),
    /// all computed first, since nothing is projected, and checked the first alone, then a batch
    /// of the checker's [`lanes`](super::ValidityChecker::lanes) at a time (the sphere checker:
    /// 8 states per pass instead of a pass per state; a checker of one lane: state by state);
    /// the nodes up to the first invalid state are added, as the step-by-step extension adds
    /// them. The states after an invalid one in its batch are checked too (counted in
    /// `validity_checks`): the tree and the search are the same as step by step.
    fn extend_free(&mut self, tree: &mut Tree, from: usize, target: &[f64]) -> PlanResult<Reach> {
        let space = self.ambient();
        let nq = space.nq();
        let st = self.st;
        let mut line = std::mem::take(&mut self.line);
        line.clear();
        let mut reached = false;
        for k in 0..st.max_increments {
            // the candidate's row: the target, moved `step` towards it from the previous state
            // unless within one step
            let at = line.len();
            line.extend_from_slice(target);
            let (done, cand) = line.split_at_mut(at);
            let prev: &[f64] = if k == 0 { tree.node(from) } else { &done[at - nq..] };
            let dist = space.distance(prev, target);
            let last = dist <= st.step;
            if !last {
                space.interpolate(prev, target, st.step / dist, cand);
            }
            let jump = space.distance(prev, cand);
            if jump > st.max_jump * st.step || jump < 1e-12 {
                line.truncate(at);
                break;
            }
            if last {
                reached = true;
                break;
            }
        }
        let n = line.len() / nq.max(1);
        let mut ok = std::mem::take(&mut self.line_ok);
        ok.clear();
        ok.resize(n, false);
        // the first state alone (an extension into an obstacle usually ends there, and a checker
        // stops at a state's first hit), then a batch of the checker's lanes at a time, until a
        // state is invalid
        let lanes = self.space.lanes();
        let (mut cur, mut added) = (from, 0);
        let mut first = 0;
        'batches: while first < n {
            let last = if first == 0 { 1 } else { (first + lanes).min(n) };
            self.space.check(&line[first * nq..last * nq], &mut ok[first..last])?;
            for k in first..last {
                if !ok[k] {
                    break 'batches;
                }
                cur = tree.add(space, &line[k * nq..(k + 1) * nq], cur, None);
                added += 1;
            }
            first = last;
        }
        let reached = reached && added == n;
        self.line = line;
        self.line_ok = ok;
        Ok(Reach { node: cur, reached, added })
    }

    /// Shortcut a solution greedily: from each waypoint, connect to the farthest later waypoint
    /// whose straight (projected, validated) edge holds, halving the span on failure.
    fn shortcut(&mut self, waypoints: Vec<Vec<f64>>, edges: Vec<Vec<f64>>) -> PlanResult<(Vec<Vec<f64>>, Vec<Vec<f64>>)> {
        let n = waypoints.len();
        let mut out_w = vec![waypoints[0].clone()];
        let mut out_e = vec![Vec::new()];
        let mut i = 0;
        while i + 1 < n {
            let mut j = n - 1;
            loop {
                if j == i + 1 {
                    out_w.push(waypoints[j].clone());
                    out_e.push(edges[j].clone());
                    break;
                }
                self.poll()?;
                if let Some(states) = self.space.geodesic(&waypoints[i], &waypoints[j], false)? {
                    self.space.stats.shortcuts += 1;
                    out_w.push(waypoints[j].clone());
                    out_e.push(states);
                    break;
                }
                j = i + (j - i) / 2;
            }
            i = j;
        }
        Ok((out_w, out_e))
    }

    /// Validate the edges from the root to `node` that are not yet; prune below the first that
    /// fails. True when the whole path is valid.
    pub(super) fn validate_path(&mut self, tree: &mut Tree, node: usize) -> PlanResult<bool> {
        let (mut chain, mut edge) = (std::mem::take(&mut self.chain), std::mem::take(&mut self.edge));
        tree.chain_into(node, &mut chain);
        let mut valid = Ok(true);
        for &i in &chain {
            if tree.validated[i] {
                continue;
            }
            match self.space.geodesic_into(tree.node(tree.parent[i]), tree.node(i), false, &mut edge) {
                Ok(true) => tree.set_edge(i, &edge),
                Ok(false) => {
                    self.space.stats.pruned += tree.prune(i);
                    valid = Ok(false);
                    break;
                }
                Err(e) => {
                    valid = Err(e);
                    break;
                }
            }
        }
        (self.chain, self.edge) = (chain, edge);
        valid
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::EuclideanSpace;

    #[test]
    fn a_path_that_fails_the_final_check_is_an_internal_error() {
        let planner = Planner::new(Arc::new(EuclideanSpace(2)), Settings::default()).unwrap();
        let (start, goal) = ([0.0, 0.0], [1.0, 0.0]);
        assert!(planner.check_solution(&[0.0, 0.0, 0.5, 0.0, 1.0, 0.0], &start, &goal).is_ok());
        let internal = |path: &[f64]| match planner.check_solution(path, &start, &goal) {
            Err(PlanError::Internal(m)) => m,
            other => panic!("expected an internal error, got {other:?}"),
        };
        assert!(internal(&[0.1, 0.0, 1.0, 0.0]).ends_with("it does not begin at the start"));
        assert!(internal(&[0.0, 0.0, 0.9, 0.0]).ends_with("it ends 0.100 from the goal (goal_tolerance 0.001)"));
        assert!(internal(&[0.0, 0.0, f64::NAN, 0.0]).ends_with("not whole rows of finite numbers"));
        assert!(internal(&[]).ends_with("not whole rows of finite numbers"));
    }

    #[test]
    fn short_numbers() {
        assert_eq!(short(0.31234), "0.312");
        assert_eq!(short(1.5), "1.50");
        assert_eq!(short(123.456), "123");
        assert_eq!(short(0.0012345), "0.00123");
        assert_eq!(short(2.5e-7), "2.50e-7");
        assert_eq!(short(0.0), "0");
    }
}

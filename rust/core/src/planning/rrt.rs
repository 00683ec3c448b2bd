//! The planner: its [`Settings`], what a plan cost ([`Stats`]) and returns ([`Solution`]), the
//! search tree of one attempt, the [`Components`] a plan calls, and the [`Planner`] itself
//! (attempts, ConstrainedExtend, edge validation, lazy pruning, shortcutting).

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Instant;

use super::{NearestNeighbors, NeighborIndex, PlanError, PlanResult, Projection, Projector, Sampler, Space, ValidityChecker};

/// Consecutive states of a validated edge are at most this many edge resolutions apart.
pub const MAX_SPACING: f64 = 1.25;

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
    /// Iterations (sample + extension + extension to the goal) per attempt. Paper: 500.
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
    /// Shortcut the solution (greedy, each shortcut a projected, validated straight edge). Off
    /// by default: the paper's timings have none.
    pub simplify: bool,
    /// The nearest-neighbour index.
    pub neighbors: NeighborIndex,
    /// Give up after this many consecutive sample batches without one projectable sample.
    pub max_empty_batches: usize,
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
    /// * `retries`, the flags and `neighbors`: any value.
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
        // a tree edge is at most max_jump * step long (Run::extend): its state count is bounded
        let longest = self.step * self.max_jump;
        if er > 0.0 && longest / er > Self::MAX_EDGE_STATES as f64 {
            return bad(
                "edge_resolution",
                format!(
                    "edge_resolution must be at least step * max_jump / {} = {:e} (at most {} states on a tree edge of up to step * max_jump = {:?} long), got {er:?}",
                    Self::MAX_EDGE_STATES,
                    longest / Self::MAX_EDGE_STATES as f64,
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
    /// Tree nodes at the end of the last attempt.
    pub nodes: usize,
    /// Nodes pruned because an edge above them failed (lazy) validation.
    pub pruned: usize,
    /// Shortcuts taken when simplifying the solution.
    pub shortcuts: usize,
    /// Wall time of the whole plan, in seconds.
    pub time_s: f64,
    /// Seconds spent in the sampler (the rest of `time_s`, beyond the sampler, projector and
    /// checker, is the tree, nearest neighbours and bookkeeping).
    pub sampler_s: f64,
    /// Seconds spent in the projector (samples, extension steps and edges).
    pub projector_s: f64,
    /// Seconds spent in the validity checker.
    pub checker_s: f64,
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

/// The tree of one attempt: node configurations and, per node, the states on the edge from its
/// parent (exclusive of both ends).
struct Tree {
    nq: usize,
    q: Vec<f64>,
    parent: Vec<usize>,
    children: Vec<Vec<usize>>,
    /// The edge from the parent has been validated (its states are stored).
    validated: Vec<bool>,
    /// Pruned: an edge above it failed validation; never extended from again.
    dead: Vec<bool>,
    edge_start: Vec<usize>,
    edge_count: Vec<usize>,
    edge_states: Vec<f64>,
    nn: Box<dyn NearestNeighbors>,
    coords: Vec<f64>,
}

impl Tree {
    fn node(&self, i: usize) -> &[f64] {
        &self.q[i * self.nq..(i + 1) * self.nq]
    }
    fn len(&self) -> usize {
        self.parent.len()
    }
    fn new(nq: usize, nv: usize, neighbors: NeighborIndex) -> Tree {
        Tree {
            nq,
            q: Vec::new(),
            parent: Vec::new(),
            children: Vec::new(),
            validated: Vec::new(),
            dead: Vec::new(),
            edge_start: Vec::new(),
            edge_count: Vec::new(),
            edge_states: Vec::new(),
            nn: neighbors.build(nv),
            coords: vec![0.0; nv],
        }
    }
    /// Add a node; `edge`: the validated states from the parent, or None (validated later).
    fn add(&mut self, space: &dyn Space, q: &[f64], parent: usize, edge: Option<&[f64]>) -> usize {
        let id = self.len();
        self.q.extend_from_slice(q);
        self.parent.push(parent);
        self.children.push(Vec::new());
        if parent != usize::MAX {
            self.children[parent].push(id);
        }
        self.dead.push(false);
        self.validated.push(false);
        self.edge_start.push(0);
        self.edge_count.push(0);
        if let Some(e) = edge {
            self.set_edge(id, e);
        }
        space.coordinates(q, &mut self.coords);
        self.nn.add(&self.coords);
        id
    }
    fn set_edge(&mut self, node: usize, states: &[f64]) {
        self.edge_start[node] = self.edge_states.len() / self.nq.max(1);
        self.edge_count[node] = states.len() / self.nq.max(1);
        self.edge_states.extend_from_slice(states);
        self.validated[node] = true;
    }
    /// Mark `node` and everything below it dead; returns how many nodes died.
    fn prune(&mut self, node: usize) -> usize {
        let mut stack = vec![node];
        let mut n = 0;
        while let Some(i) = stack.pop() {
            if !self.dead[i] {
                self.dead[i] = true;
                n += 1;
            }
            stack.extend_from_slice(&self.children[i]);
        }
        n
    }
    fn nearest(&mut self, space: &dyn Space, q: &[f64]) -> usize {
        space.coordinates(q, &mut self.coords);
        let dead = &self.dead;
        self.nn.nearest_where(&self.coords, &|i| !dead[i]).map(|(i, _)| i).unwrap_or(0)
    }
    /// Node indices from the root to `node`.
    fn chain(&self, node: usize) -> Vec<usize> {
        let mut chain = vec![node];
        while let Some(&last) = chain.last() {
            match self.parent[last] {
                usize::MAX => break,
                p => chain.push(p),
            }
        }
        chain.reverse();
        chain
    }
}

/// The components of one plan.
pub struct Components<'a> {
    /// Draws the configurations the tree grows towards.
    pub sampler: &'a mut dyn Sampler,
    /// Projects samples, extension steps and edge states onto the manifold.
    pub projector: &'a mut dyn Projector,
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

/// State of one plan call (the planner itself stays immutable and shareable).
struct Run<'a, 'c> {
    space: &'a dyn Space,
    st: &'a Settings,
    c: &'a mut Components<'c>,
    stats: Stats,
    samples: VecDeque<Vec<f64>>,
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
            space.check(g, &format!("goals[{i}]")).map_err(PlanError::InvalidGoal)?;
        }
        let mut run = Run { space, st: &self.settings, c, stats: Stats::default(), samples: VecDeque::new() };
        let (start, goals) = run.onto_manifold(start, goals)?;
        let (start, goals) = (&start[..], &goals[..]);
        let mut start_ok = [false];
        run.check_valid(start, &mut start_ok)?;
        if !start_ok[0] {
            return Err(PlanError::InvalidStart("start: the configuration is not valid (in collision or outside the joint limits)".into()));
        }
        let mut goal_ok = vec![false; goals.len() / nq];
        run.check_valid(goals, &mut goal_ok)?;
        let valid_goals: Vec<usize> = (0..goal_ok.len()).filter(|&i| goal_ok[i]).collect();
        if valid_goals.is_empty() {
            return Err(PlanError::InvalidGoal("goals: none of the goal configurations is valid (in collision or outside the joint limits)".into()));
        }

        let mut solution = None;
        for attempt in 0..=self.settings.retries {
            run.stats.retries = attempt;
            let mut tree = Tree::new(nq, space.nv(), self.settings.neighbors);
            tree.add(space, start, usize::MAX, Some(&[]));
            if let Some((node, g)) = run.attempt(&mut tree, goals, &valid_goals)? {
                let (mut waypoints, mut edges) = extract(&tree, node);
                if self.settings.simplify {
                    (waypoints, edges) = run.shortcut(waypoints, edges)?;
                }
                let (w, path) = flatten(&waypoints, &edges);
                solution = Some((w, path, g));
            }
            run.stats.nodes = tree.len();
            if solution.is_some() {
                break;
            }
        }
        let mut stats = run.stats;
        stats.success = solution.is_some();
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
        if path.len() < nq || path.len() % nq != 0 || path.iter().any(|x| !x.is_finite()) {
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

/// A distance for a message: three significant digits, scientific notation when tiny or huge.
fn short(x: f64) -> String {
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
        let mut run = Run { space, st: &self.settings, c, stats: Stats::default(), samples: VecDeque::new() };
        let mut tree = Tree::new(space.nq(), space.nv(), self.settings.neighbors);
        tree.add(space, from, usize::MAX, Some(&[]));
        let reach = run.extend(&mut tree, 0, target, target_on_manifold)?;
        Ok((tree.q[space.nq()..].to_vec(), reach.reached))
    }
}

/// The waypoints from the root to `goal_node` and, per waypoint after the first, the validated
/// states of the edge that leads to it.
fn extract(tree: &Tree, goal_node: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let nq = tree.nq;
    let chain = tree.chain(goal_node);
    let waypoints = chain.iter().map(|&i| tree.node(i).to_vec()).collect();
    let edges = chain
        .iter()
        .map(|&i| {
            let (s, n) = (tree.edge_start[i], tree.edge_count[i]);
            tree.edge_states[s * nq..(s + n) * nq].to_vec()
        })
        .collect();
    (waypoints, edges)
}

/// Flatten waypoints and their edges into (waypoints, dense path).
fn flatten(waypoints: &[Vec<f64>], edges: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let mut w = Vec::new();
    let mut path = Vec::new();
    for (q, e) in waypoints.iter().zip(edges) {
        path.extend_from_slice(e);
        path.extend_from_slice(q);
        w.extend_from_slice(q);
    }
    (w, path)
}

/// Where an extension ended.
struct Reach {
    node: usize,
    /// The target itself was added.
    reached: bool,
    added: usize,
}

impl Run<'_, '_> {
    fn check_valid(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        self.stats.validity_checks += valid.len();
        let t = Instant::now();
        let r = self.c.checker.check(qs, valid);
        self.stats.checker_s += t.elapsed().as_secs_f64();
        r
    }

    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let t = Instant::now();
        let r = self.c.projector.project(qs, q_noms, out, reports);
        self.stats.projector_s += t.elapsed().as_secs_f64();
        r
    }

    /// The start and goals checked against the manifold (see [`Planner::plan`]): each projected
    /// around itself in one batch; refused when the projection fails or moves it by more than
    /// `goal_tolerance`, else replaced by its projection. Not counted in the stats (an input
    /// check, not the search).
    fn onto_manifold(&mut self, start: &[f64], goals: &[f64]) -> PlanResult<(Vec<f64>, Vec<f64>)> {
        let nq = self.space.nq();
        let rows = [start, goals].concat();
        let n = rows.len() / nq;
        let mut out = vec![0.0; rows.len()];
        let mut reps = vec![Projection::default(); n];
        self.c.projector.project(&rows, &rows, &mut out, &mut reps)?;
        let tol = self.st.goal_tolerance;
        let why = |i: usize| -> Option<String> {
            let (q, p) = (&rows[i * nq..(i + 1) * nq], &out[i * nq..(i + 1) * nq]);
            if !reps[i].success || p.iter().any(|x| !x.is_finite()) {
                return Some("not on the constraint manifold: the projector could not project it".into());
            }
            let d = self.space.distance(q, p);
            (d.is_nan() || d > tol).then(|| format!("not on the constraint manifold: the projector moved it by {} (goal_tolerance {tol})", short(d)))
        };
        if let Some(w) = why(0) {
            return Err(PlanError::InvalidStart(format!("start: {w}")));
        }
        let bad: Vec<(usize, String)> = (1..n).filter_map(|i| why(i).map(|w| (i - 1, w))).collect();
        if let Some((i, w)) = bad.first() {
            let mut msg = format!("goals[{i}]: {w}");
            if bad.len() > 1 {
                let others: Vec<String> = bad[1..].iter().map(|(j, _)| format!("goals[{j}]")).collect();
                msg += &format!("; also off it: {}", others.join(", "));
            }
            return Err(PlanError::InvalidGoal(msg));
        }
        let goals = out.split_off(nq);
        Ok((out, goals))
    }

    /// One attempt: returns the goal node and the goal's index on success.
    fn attempt(&mut self, tree: &mut Tree, goals: &[f64], valid_goals: &[usize]) -> PlanResult<Option<(usize, usize)>> {
        let nq = self.space.nq();
        for _ in 0..self.st.max_extensions {
            (self.c.interrupt)()?;
            self.stats.extensions += 1;
            let q_rand = self.next_sample()?;
            let near = tree.nearest(self.space, &q_rand);
            let a = self.extend(tree, near, &q_rand, self.st.project_samples)?;
            if a.added == 0 {
                continue;
            }
            let qa = tree.node(a.node).to_vec();
            let g = *valid_goals
                .iter()
                .min_by(|&&i, &&j| {
                    let di = self.space.distance(&qa, &goals[i * nq..(i + 1) * nq]);
                    let dj = self.space.distance(&qa, &goals[j * nq..(j + 1) * nq]);
                    di.total_cmp(&dj)
                })
                .expect("at least one valid goal");
            let goal = &goals[g * nq..(g + 1) * nq];
            let b = self.extend(tree, a.node, goal, true)?;
            if b.reached && self.space.distance(tree.node(b.node), goal) <= self.st.goal_tolerance && self.validate_path(tree, b.node)? {
                return Ok(Some((b.node, g)));
            }
        }
        Ok(None)
    }

    /// The next (projected, when `project_samples`) sample, refilling the buffer in batches.
    fn next_sample(&mut self) -> PlanResult<Vec<f64>> {
        let nq = self.space.nq();
        let mut empty = 0;
        while self.samples.is_empty() {
            (self.c.interrupt)()?;
            let n = self.st.sample_batch;
            let mut raw = vec![0.0; n * nq];
            let t = Instant::now();
            self.c.sampler.sample(n, &mut raw)?;
            self.stats.sampler_s += t.elapsed().as_secs_f64();
            for (i, q) in raw.chunks(nq).enumerate() {
                self.space
                    .check(q, &format!("sampler output row {i}"))
                    .map_err(|e| PlanError::Sampler(format!("the sampler returned a bad configuration: {e}")))?;
            }
            self.stats.samples += n;
            if self.st.project_samples {
                let mut out = vec![0.0; n * nq];
                let mut reps = vec![Projection::default(); n];
                self.project(&raw, &raw, &mut out, &mut reps)?;
                self.stats.projection_calls += n;
                for (q, r) in out.chunks(nq).zip(&reps) {
                    self.stats.projections += r.iterations;
                    if r.success && q.iter().all(|x| x.is_finite()) {
                        self.samples.push_back(q.to_vec());
                    } else {
                        self.stats.samples_rejected += 1;
                    }
                }
            } else {
                self.samples.extend(raw.chunks(nq).map(<[f64]>::to_vec));
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
        Ok(self.samples.pop_front().expect("refilled above"))
    }

    /// ConstrainedExtend from tree node `from` towards `target` (on the manifold when
    /// `target_on_manifold`).
    fn extend(&mut self, tree: &mut Tree, from: usize, target: &[f64], target_on_manifold: bool) -> PlanResult<Reach> {
        let space = self.space;
        let nq = space.nq();
        let st = self.st;
        let mut cur = from;
        let mut added = 0;
        let mut q_next = vec![0.0; nq];
        for _ in 0..st.max_increments {
            let q_cur = tree.node(cur).to_vec();
            let dist = space.distance(&q_cur, target);
            let last = dist <= st.step;
            let mut candidate = if last {
                target.to_vec()
            } else {
                space.interpolate(&q_cur, target, st.step / dist, &mut q_next);
                q_next.clone()
            };
            if !(last && target_on_manifold) {
                let mut out = vec![0.0; nq];
                let mut rep = [Projection::default()];
                self.project(&candidate, &candidate, &mut out, &mut rep)?;
                self.stats.projection_calls += 1;
                self.stats.projections += rep[0].iterations;
                if !rep[0].success || out.iter().any(|x| !x.is_finite()) {
                    break;
                }
                candidate = out;
            }
            let jump = space.distance(&q_cur, &candidate);
            if jump > st.max_jump * st.step || jump < 1e-12 {
                break;
            }
            if st.lazy_edges {
                let mut ok = [false];
                self.check_valid(&candidate, &mut ok)?;
                if !ok[0] {
                    break;
                }
                cur = tree.add(space, &candidate, cur, None);
            } else {
                match self.validate_edge(&q_cur, &candidate, true)? {
                    Some(edge) => cur = tree.add(space, &candidate, cur, Some(&edge)),
                    None => break,
                }
            }
            added += 1;
            if last {
                return Ok(Reach { node: cur, reached: true, added });
            }
        }
        Ok(Reach { node: cur, reached: false, added })
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
                (self.c.interrupt)()?;
                if let Some(states) = self.validate_edge(&waypoints[i], &waypoints[j], false)? {
                    self.stats.shortcuts += 1;
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
    fn validate_path(&mut self, tree: &mut Tree, node: usize) -> PlanResult<bool> {
        for i in tree.chain(node) {
            if tree.validated[i] {
                continue;
            }
            let (a, b) = (tree.node(tree.parent[i]).to_vec(), tree.node(i).to_vec());
            match self.validate_edge(&a, &b, false)? {
                Some(states) => tree.set_edge(i, &states),
                None => {
                    self.stats.pruned += tree.prune(i);
                    return Ok(false);
                }
            }
        }
        Ok(true)
    }

    /// Check the edge from `a` to `b` (and `b` itself when `check_end`): interpolate at
    /// `edge_resolution`, project each intermediate state (posture around its interpolation),
    /// check every state. Returns the projected intermediate states (rows), or None when the edge
    /// is not valid (or would need more than [`Settings::MAX_EDGE_STATES`] states: only a
    /// shortcut can, never a tree edge).
    fn validate_edge(&mut self, a: &[f64], b: &[f64], check_end: bool) -> PlanResult<Option<Vec<f64>>> {
        let space = self.space;
        let nq = space.nq();
        let dist = space.distance(a, b);
        let n_mid = if self.st.edge_resolution > 0.0 {
            // intervals at the resolution; a tree edge needs at most Settings::MAX_EDGE_STATES
            // (Settings::validate), a longer edge (a shortcut) that needs more is not taken
            let intervals = (dist / self.st.edge_resolution).ceil();
            if intervals.is_nan() || intervals > Settings::MAX_EDGE_STATES as f64 {
                return Ok(None);
            }
            (intervals as usize).saturating_sub(1)
        } else {
            0
        };
        let mut states = vec![0.0; (n_mid + 1) * nq];
        if n_mid > 0 {
            let mut lin = vec![0.0; n_mid * nq];
            for k in 0..n_mid {
                let t = (k + 1) as f64 / (n_mid + 1) as f64;
                space.interpolate(a, b, t, &mut lin[k * nq..(k + 1) * nq]);
            }
            let mut reps = vec![Projection::default(); n_mid];
            self.project(&lin, &lin, &mut states[..n_mid * nq], &mut reps)?;
            self.stats.edge_projections += reps.iter().map(|r| r.iterations).sum::<usize>();
            if reps.iter().any(|r| !r.success) || states.iter().any(|x| !x.is_finite()) {
                return Ok(None);
            }
            // consecutive states must stay close (no jump to another branch of the manifold, and
            // chords short enough to stay on it): at most MAX_SPACING x the edge resolution apart
            let max_gap = MAX_SPACING * self.st.edge_resolution;
            let mut prev = a;
            for k in 0..n_mid {
                let s = &states[k * nq..(k + 1) * nq];
                if space.distance(prev, s) > max_gap {
                    return Ok(None);
                }
                prev = s;
            }
            if space.distance(prev, b) > max_gap {
                return Ok(None);
            }
        }
        states[n_mid * nq..].copy_from_slice(b);
        let n_check = n_mid + usize::from(check_end);
        let mut valid = vec![false; n_check];
        self.check_valid(&states[..n_check * nq], &mut valid)?;
        if valid.iter().all(|&v| v) {
            states.truncate(n_mid * nq);
            Ok(Some(states))
        } else {
            Ok(None)
        }
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

    /// The identity projector (R^n is its own manifold).
    struct Identity;

    impl crate::planning::Projector for Identity {
        fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
            out.copy_from_slice(qs);
            reports.fill(Projection { success: true, iterations: 0 });
            Ok(())
        }
    }

    /// Never called.
    struct NoSampler;

    impl crate::planning::Sampler for NoSampler {
        fn sample(&mut self, _n: usize, _out: &mut [f64]) -> PlanResult<()> {
            Err(PlanError::Sampler("not used".into()))
        }
    }

    /// Finding PLAN-1 (fixed): an edge that would need more than Settings::MAX_EDGE_STATES
    /// states (a shortcut between far waypoints) is not taken; nothing is allocated for it.
    #[test]
    fn an_edge_beyond_the_state_cap_is_not_taken() {
        let st = Settings { edge_resolution: Settings::MIN_EDGE_RESOLUTION, step: 0.3, max_jump: 3.0, ..Settings::default() };
        st.validate().unwrap();
        let space = EuclideanSpace(2);
        let (mut sampler, mut projector, mut checker) = (NoSampler, Identity, crate::planning::AlwaysValid);
        let mut interrupt = || Ok(());
        let mut c = Components { sampler: &mut sampler, projector: &mut projector, checker: &mut checker, interrupt: &mut interrupt };
        let mut run = Run { space: &space, st: &st, c: &mut c, stats: Stats::default(), samples: VecDeque::new() };
        // the longest tree edge (max_jump * step = 0.9: 900000 states) is validated
        let states = run.validate_edge(&[0.0, 0.0], &[0.9, 0.0], true).unwrap().expect("a tree edge is validated");
        assert!(states.len() % 2 == 0 && (899_999..=900_000).contains(&(states.len() / 2)), "{} states", states.len() / 2);
        // 2^20 intervals at most, not one more
        let cap = Settings::MAX_EDGE_STATES as f64 * Settings::MIN_EDGE_RESOLUTION;
        assert!(run.validate_edge(&[0.0, 0.0], &[cap * 0.9999, 0.0], false).unwrap().is_some());
        assert!(run.validate_edge(&[0.0, 0.0], &[cap * 1.001, 0.0], false).unwrap().is_none());
        // 1e12 states would be 16 TB
        assert!(run.validate_edge(&[0.0, 0.0], &[1e6, 0.0], false).unwrap().is_none());
        assert!(run.validate_edge(&[-1e300, 0.0], &[1e300, 0.0], false).unwrap().is_none());
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

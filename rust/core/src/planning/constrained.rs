//! The constrained space of one plan, as OMPL's `ProjectedStateSpace` with its
//! `ConstrainedMotionValidator`: the ambient [`Space`], the [`Projector`] that defines the
//! manifold and the [`ValidityChecker`], behind one type ([`ConstrainedSpace`]) that offers
//!
//! * [`step`](ConstrainedSpace::step): one constrained step from a state towards a target (the
//!   unit of the paper's ConstrainedExtend: a step of `step` along the straight line, projected,
//!   refused when the projection fails or jumps, then checked);
//! * [`geodesic`](ConstrainedSpace::geodesic): the projected, checked walk between two states
//!   on the manifold at `edge_resolution` (the dense states of an edge, or None);
//! * [`check_motion`](ConstrainedSpace::check_motion): the motion validator (a geodesic exists);
//! * [`onto_manifold`](ConstrainedSpace::onto_manifold): a plan's inputs checked against the
//!   manifold.
//!
//! Without a projector the space is free: the ambient space is the manifold, nothing is
//! projected (samples, steps, edge states, chords), and the checker alone says which states are
//! valid; the steps and edges are the same straight lines, checked at the same resolution.
//!
//! The planners (`rrt`: the paper's cRRT; `rrt_connect`) keep the tree logic only; every state
//! they add and every edge they return went through this type, which also keeps the plan's
//! counts of projections and checks and the time spent in the projector and the checker
//! ([`ConstrainedSpace::stats`]).

use std::time::Instant;

use super::rrt::short;
use super::{EdgeCheck, PlanError, PlanResult, Projection, Projector, Settings, Space, Stats, ValidityChecker, MAX_SPACING};

/// The constrained space of one plan: the ambient space, the projector (None: free space) and the
/// validity checker, with the planner's settings (`step`, `max_jump`, `edge_resolution`,
/// `lazy_edges`, `goal_tolerance`).
pub struct ConstrainedSpace<'a> {
    /// The ambient configuration space.
    pub ambient: &'a dyn Space,
    projector: Option<&'a mut dyn Projector>,
    checker: &'a mut dyn ValidityChecker,
    settings: &'a Settings,
    /// What the space's calls cost so far (projections, edge projections, checks, projector and
    /// checker times); a planner adds its own counts to it.
    pub stats: Stats,
    /// An edge's states in rake order ([`rake_into`]), in memory kept from edge to edge.
    raked: Vec<f64>,
}

/// One constrained step that succeeded ([`ConstrainedSpace::step`]).
#[derive(Debug, Clone)]
pub struct Step {
    /// The new state: on the manifold and valid.
    pub q: Vec<f64>,
    /// It is the target itself (the target was within one step).
    pub reached: bool,
    /// The validated states between the step's start and `q` (both excluded), or None with lazy
    /// edges (validated later, with [`ConstrainedSpace::geodesic`]).
    pub edge: Option<Vec<f64>>,
}

impl<'a> ConstrainedSpace<'a> {
    /// The constrained space of `ambient` whose manifold `projector` defines (None: the whole
    /// ambient space, free space) and whose valid states `checker` says, with `settings`
    /// (validated by the caller).
    pub fn new(
        ambient: &'a dyn Space,
        projector: Option<&'a mut dyn Projector>,
        checker: &'a mut dyn ValidityChecker,
        settings: &'a Settings,
    ) -> ConstrainedSpace<'a> {
        ConstrainedSpace { ambient, projector, checker, settings, stats: Stats::default(), raked: Vec::new() }
    }

    /// A projector defines the manifold (false: free space, nothing is projected).
    pub fn constrained(&self) -> bool {
        self.projector.is_some()
    }

    /// The settings the space walks with.
    pub fn settings(&self) -> &Settings {
        self.settings
    }

    /// The checker's [`lanes`](ValidityChecker::lanes): states checked for about the price of one.
    pub fn lanes(&self) -> usize {
        self.checker.lanes().max(1)
    }

    /// Check the rows of `qs` (counted in `validity_checks`, timed in `checker_s`).
    pub fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        self.stats.validity_checks += valid.len();
        let t = Instant::now();
        let r = self.checker.check(qs, valid);
        self.stats.checker_s += t.elapsed().as_secs_f64();
        r
    }

    /// True when each of the `n` rows of `qs` is valid ([`ValidityChecker::all_valid`]: the
    /// checker may stop at the first invalid row; the rows it checked counted in
    /// `validity_checks`, timed in `checker_s`).
    pub fn all_valid(&mut self, qs: &[f64], n: usize) -> PlanResult<bool> {
        let t = Instant::now();
        let r = self.checker.all_valid(qs, n);
        self.stats.checker_s += t.elapsed().as_secs_f64();
        let (valid, checked) = r?;
        self.stats.validity_checks += checked;
        Ok(valid)
    }

    /// Project the rows of `qs`, each around its row of `q_noms` (timed in `projector_s`; the
    /// caller counts the iterations where they belong). In free space the rows are copied as
    /// they are, each a success in no iteration (callers skip the call there; this keeps the
    /// method total).
    pub fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let Some(projector) = self.projector.as_deref_mut() else {
            out.copy_from_slice(qs);
            reports.fill(Projection { success: true, iterations: 0 });
            return Ok(());
        };
        let t = Instant::now();
        let r = projector.project(qs, q_noms, out, reports);
        self.stats.projector_s += t.elapsed().as_secs_f64();
        r
    }

    /// The start and goals checked against the manifold (see
    /// [`Planner::plan`](super::Planner::plan)): each projected around itself in one batch;
    /// refused when the projection fails or moves it by more than `goal_tolerance`, else replaced
    /// by its projection. Not counted in the stats (an input check, not the search). In free
    /// space every configuration is on the manifold: the start and goals are returned as given.
    pub fn onto_manifold(&mut self, start: &[f64], goals: &[f64]) -> PlanResult<(Vec<f64>, Vec<f64>)> {
        let Some(projector) = self.projector.as_deref_mut() else {
            return Ok((start.to_vec(), goals.to_vec()));
        };
        let nq = self.ambient.nq();
        let rows = [start, goals].concat();
        let n = rows.len() / nq;
        let mut out = vec![0.0; rows.len()];
        let mut reps = vec![Projection::default(); n];
        projector.project(&rows, &rows, &mut out, &mut reps)?;
        let tol = self.settings.goal_tolerance;
        let why = |i: usize| -> Option<String> {
            let (q, p) = (&rows[i * nq..(i + 1) * nq], &out[i * nq..(i + 1) * nq]);
            if !reps[i].success || p.iter().any(|x| !x.is_finite()) {
                return Some("not on the constraint manifold: the projector could not project it".into());
            }
            let d = self.ambient.distance(q, p);
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

    /// One constrained step from `from` (on the manifold) towards `target` (on it too when
    /// `target_on_manifold`): the state `step` along the straight line (the target itself when
    /// within `step`: then unprojected if `target_on_manifold`), projected around itself. None
    /// when the projection fails, lands more than `max_jump * step` from `from` (another branch
    /// of the manifold) or does not move, or the state (with eager edges: the edge) is not valid.
    /// Projections are counted in `projection_calls` and `projections`; in free space the state
    /// on the line is taken as it is.
    pub fn step(&mut self, from: &[f64], target: &[f64], target_on_manifold: bool) -> PlanResult<Option<Step>> {
        let space = self.ambient;
        let st = self.settings;
        let dist = space.distance(from, target);
        let last = dist <= st.step;
        let mut candidate = target.to_vec();
        if !last {
            space.interpolate(from, target, st.step / dist, &mut candidate);
        }
        if !(last && target_on_manifold) && self.constrained() {
            let mut out = vec![0.0; candidate.len()];
            let mut rep = [Projection::default()];
            self.project(&candidate, &candidate, &mut out, &mut rep)?;
            self.stats.projection_calls += 1;
            self.stats.projections += rep[0].iterations;
            if !rep[0].success || out.iter().any(|x| !x.is_finite()) {
                return Ok(None);
            }
            candidate = out;
        }
        let jump = space.distance(from, &candidate);
        if jump > st.max_jump * st.step || jump < 1e-12 {
            return Ok(None);
        }
        let edge = if st.lazy_edges {
            let mut ok = [false];
            self.check(&candidate, &mut ok)?;
            if !ok[0] {
                return Ok(None);
            }
            None
        } else {
            match self.geodesic(from, &candidate, true)? {
                Some(edge) => Some(edge),
                None => return Ok(None),
            }
        };
        Ok(Some(Step { q: candidate, reached: last, edge }))
    }

    /// The geodesic from `a` to `b` (both on the manifold; `b` checked too when `check_end`):
    /// the straight line interpolated at `edge_resolution`, each intermediate state projected
    /// around its interpolation (a tree edge, at most `max_jump * step` long, with
    /// [`Projector::project_edge`]; a longer one, a shortcut, with [`Projector::project`]) and
    /// checked. With a projector that holds chords to a tolerance ([`Projector::check_chords`]),
    /// the midpoint of every chord between consecutive states is checked too, and a chord that
    /// strays is split at its projected midpoint (`hold_chords`). Returns the projected
    /// intermediate states (rows, `a` and `b` excluded; none when `edge_resolution` is 0), or
    /// None when a projection fails, two consecutive states are more than
    /// [`MAX_SPACING`]` x edge_resolution` apart (a jump to another branch, or a chord too long
    /// to stay on the manifold), a chord strays from the manifold down to
    /// `edge_resolution /` [`Settings::CERTIFY_REFINEMENT`], a state is not valid, or the edge
    /// would need more than [`Settings::MAX_EDGE_STATES`] states (only a shortcut can, never a
    /// tree edge).
    ///
    /// With [`EdgeCheck::Certified`] the motion between consecutive states is certified as well
    /// (`certify_states`: [`ValidityChecker::certify_path`]), and states are added where it cannot be.
    ///
    /// In free space the states are the interpolations themselves, evenly spaced: nothing is
    /// projected and no chord can stray.
    pub fn geodesic(&mut self, a: &[f64], b: &[f64], check_end: bool) -> PlanResult<Option<Vec<f64>>> {
        let mut states = Vec::new();
        Ok(self.geodesic_into(a, b, check_end, &mut states)?.then_some(states))
    }

    /// [`geodesic`](Self::geodesic) into `out` (its memory reused: a planner validating edge
    /// after edge allocates nothing per edge in free space): true and the states in `out`, or
    /// false (`out` then holds nothing of use).
    pub fn geodesic_into(&mut self, a: &[f64], b: &[f64], check_end: bool, out: &mut Vec<f64>) -> PlanResult<bool> {
        let space = self.ambient;
        let nq = space.nq();
        let resolution = self.settings.edge_resolution;
        let dist = space.distance(a, b);
        let n_mid = if resolution > 0.0 {
            // intervals at the resolution; a tree edge needs at most Settings::MAX_EDGE_STATES
            // (Settings::validate), a longer edge (a shortcut) that needs more is not taken
            let intervals = (dist / resolution).ceil();
            if intervals.is_nan() || intervals > Settings::MAX_EDGE_STATES as f64 {
                return Ok(false);
            }
            (intervals as usize).saturating_sub(1)
        } else {
            0
        };
        let mut states = std::mem::take(out);
        states.clear();
        states.resize((n_mid + 1) * nq, 0.0);
        if n_mid > 0 && !self.constrained() {
            for k in 0..n_mid {
                let t = (k + 1) as f64 / (n_mid + 1) as f64;
                space.interpolate(a, b, t, &mut states[k * nq..(k + 1) * nq]);
            }
        } else if n_mid > 0 {
            let mut lin = vec![0.0; n_mid * nq];
            for k in 0..n_mid {
                let t = (k + 1) as f64 / (n_mid + 1) as f64;
                space.interpolate(a, b, t, &mut lin[k * nq..(k + 1) * nq]);
            }
            let mut reps = vec![Projection::default(); n_mid];
            self.project_edge_states(&lin, self.is_tree_edge(dist), &mut states[..n_mid * nq], &mut reps)?;
            if reps.iter().any(|r| !r.success) || states.iter().any(|x| !x.is_finite()) {
                return Ok(false);
            }
            let max_gap = MAX_SPACING * resolution;
            let mut prev = a;
            for k in 0..n_mid {
                let s = &states[k * nq..(k + 1) * nq];
                if space.distance(prev, s) > max_gap {
                    return Ok(false);
                }
                prev = s;
            }
            if space.distance(prev, b) > max_gap {
                return Ok(false);
            }
        }
        states[n_mid * nq..].copy_from_slice(b);
        if resolution == 0.0 {
            // no edge validation: the end only
            let mut valid = [false];
            let n_check = usize::from(check_end);
            self.check(&states[..n_check * nq], &mut valid[..n_check])?;
            states.clear();
            *out = states;
            return Ok(valid[..n_check].iter().all(|&v| v));
        }
        let tree_edge = self.is_tree_edge(dist);
        let Some(mut states) = self.hold_chords(a, states, tree_edge)? else {
            return Ok(false);
        };
        let n_mid = states.len() / nq - 1;
        if self.settings.edge_check == EdgeCheck::Certified {
            return Ok(match self.certify_states(a, states, tree_edge)? {
                Some(states) => {
                    *out = states;
                    true
                }
                None => false,
            });
        }
        let n_check = n_mid + usize::from(check_end);
        let ok = self.all_valid_raked(&states[..n_check * nq]);
        states.truncate(n_mid * nq);
        *out = states;
        ok
    }

    /// [`all_valid`](Self::all_valid) of the rows of `states` (in order along a motion), checked
    /// in [`rake`] order (arranged in memory kept from call to call).
    pub(super) fn all_valid_raked(&mut self, states: &[f64]) -> PlanResult<bool> {
        let nq = self.ambient.nq();
        let mut raked = std::mem::take(&mut self.raked);
        rake_into(states, nq, &mut raked);
        let ok = self.all_valid(&raked, states.len().checked_div(nq).unwrap_or(0));
        self.raked = raked;
        ok
    }

    /// The chords of an edge held to the projector's chord tolerance
    /// ([`Projector::check_chords`]; a projector without one: not checked): `rest` is the edge's
    /// states after `a` (rows, the last one its end `b`). The midpoint of every chord between
    /// consecutive states is checked (the chord of a manifold of bounded curvature strays
    /// farthest from it there); a chord whose midpoint is off is split at its projected midpoint
    /// (within [`MAX_SPACING`] half-chords of either end) and both halves are checked the same
    /// way, down to chords of `edge_resolution /` [`Settings::CERTIFY_REFINEMENT`]. Returns the
    /// states after `a` with those added (rows, in order, the last one still `b`), or None when a
    /// chord still strays there, a midpoint cannot be projected, or the edge would need more than
    /// [`Settings::MAX_EDGE_STATES`] states. Timed in `projector_s`; the midpoints checked are
    /// counted in `chord_checks`.
    fn hold_chords(&mut self, a: &[f64], rest: Vec<f64>, tree_edge: bool) -> PlanResult<Option<Vec<f64>>> {
        if !self.constrained() {
            return Ok(Some(rest));
        }
        let space = self.ambient;
        let nq = space.nq();
        let finest = self.settings.edge_resolution / Settings::CERTIFY_REFINEMENT;
        let mut states = Vec::with_capacity(rest.len() + nq);
        states.extend_from_slice(a);
        states.extend_from_slice(&rest);
        // the chords still to check, each by the index of its first state: all of them, then the
        // halves of those split
        let mut pending: Vec<usize> = (0..rest.len() / nq).collect();
        while !pending.is_empty() {
            let mut mids = vec![0.0; pending.len() * nq];
            for (m, &k) in mids.chunks_mut(nq).zip(&pending) {
                space.interpolate(&states[k * nq..(k + 1) * nq], &states[(k + 1) * nq..(k + 2) * nq], 0.5, m);
            }
            let mut ok = vec![true; pending.len()];
            let t = Instant::now();
            let checked = match self.projector.as_deref_mut() {
                Some(projector) => projector.check_chords(&mids, &mut ok),
                None => Ok(false),
            };
            self.stats.projector_s += t.elapsed().as_secs_f64();
            if !checked? {
                return Ok(Some(rest));
            }
            self.stats.chord_checks += pending.len();
            let bad: Vec<usize> = (0..pending.len()).filter(|&i| !ok[i]).collect();
            if bad.is_empty() {
                break;
            }
            let n_states = states.len() / nq;
            if n_states - 1 + bad.len() > Settings::MAX_EDGE_STATES {
                return Ok(None);
            }
            let mut lin = Vec::with_capacity(bad.len() * nq);
            for &i in &bad {
                let k = pending[i];
                if space.distance(&states[k * nq..(k + 1) * nq], &states[(k + 1) * nq..(k + 2) * nq]) / 2.0 < finest {
                    return Ok(None);
                }
                lin.extend_from_slice(&mids[i * nq..(i + 1) * nq]);
            }
            let mut projected = vec![0.0; lin.len()];
            let mut reps = vec![Projection::default(); bad.len()];
            self.project_edge_states(&lin, tree_edge, &mut projected, &mut reps)?;
            // the states with each projected midpoint after the first state of its chord
            let mut next = Vec::with_capacity(states.len() + projected.len());
            let mut halves = Vec::with_capacity(2 * bad.len());
            let mut splits = bad.iter().map(|&i| pending[i]).zip(projected.chunks(nq)).zip(&reps).peekable();
            for k in 0..n_states {
                let s0 = &states[k * nq..(k + 1) * nq];
                next.extend_from_slice(s0);
                let Some(((_, m), r)) = splits.next_if(|((at, _), _)| *at == k) else {
                    continue;
                };
                let s1 = &states[(k + 1) * nq..(k + 2) * nq];
                let max_gap = MAX_SPACING * space.distance(s0, s1) / 2.0;
                if !r.success || m.iter().any(|x| !x.is_finite()) || space.distance(s0, m) > max_gap || space.distance(m, s1) > max_gap {
                    return Ok(None);
                }
                let first = next.len() / nq - 1;
                next.extend_from_slice(m);
                halves.extend([first, first + 1]);
            }
            states = next;
            pending = halves;
        }
        states.drain(..nq);
        Ok(Some(states))
    }

    /// An edge `dist` long is a tree edge (at most `max_jump * step`), not a shortcut.
    fn is_tree_edge(&self, dist: f64) -> bool {
        dist <= self.settings.max_jump * self.settings.step
    }

    /// Project interpolated states of an edge (rows of `lin`, each around itself) into `out`:
    /// those of a tree edge without the posture step, which changes nothing there; those of a
    /// longer one (a shortcut, far off the manifold between its ends) with it: without, its
    /// states drift apart (wider chords: tests/test_planning.py). Timed in `projector_s`,
    /// counted in `edge_projections`. In free space the states are copied as they are (callers
    /// skip the call there).
    fn project_edge_states(&mut self, lin: &[f64], tree_edge: bool, out: &mut [f64], reps: &mut [Projection]) -> PlanResult<()> {
        let Some(projector) = self.projector.as_deref_mut() else {
            out.copy_from_slice(lin);
            reps.fill(Projection { success: true, iterations: 0 });
            return Ok(());
        };
        let t = Instant::now();
        let r = if tree_edge {
            projector.project_edge(lin, lin, out, reps)
        } else {
            projector.project(lin, lin, out, reps)
        };
        self.stats.projector_s += t.elapsed().as_secs_f64();
        r?;
        self.stats.edge_projections += reps.iter().map(|r| r.iterations).sum::<usize>();
        Ok(())
    }

    /// Certified edges ([`EdgeCheck::Certified`]): `rest` is the edge's projected states after
    /// `a` (rows, the last one its end `b`). The checker certifies the motions between
    /// consecutive states ([`ValidityChecker::certify_path`]: every state valid, every chord
    /// collision-free); a chord it cannot certify is split at its projected midpoint (valid,
    /// within [`MAX_SPACING`] half-chords of either end) and each half certified
    /// ([`ValidityChecker::certify_motion`]), down to chords of `edge_resolution /`
    /// [`Settings::CERTIFY_REFINEMENT`]. Returns the states between `a` and `b`, with those added
    /// (rows, in order), or None when a state is not valid or a chord cannot be certified.
    fn certify_states(&mut self, a: &[f64], rest: Vec<f64>, tree_edge: bool) -> PlanResult<Option<Vec<f64>>> {
        let nq = self.ambient.nq();
        let path = [a, &rest[..]].concat();
        let n_seg = rest.len() / nq;
        let mut certified = vec![false; n_seg];
        let mut valid = vec![false; n_seg + 1];
        let t = Instant::now();
        let r = self.checker.certify_path(&path, &mut valid, &mut certified);
        self.stats.checker_s += t.elapsed().as_secs_f64();
        self.stats.motion_certificates += r?;
        if !valid[1..].iter().all(|&v| v) {
            return Ok(None);
        }
        let finest = self.settings.edge_resolution / Settings::CERTIFY_REFINEMENT;
        let mut out = Vec::with_capacity(rest.len());
        for k in 0..n_seg {
            let (s0, s1) = (&path[k * nq..(k + 1) * nq], &path[(k + 1) * nq..(k + 2) * nq]);
            if !certified[k] && !self.certify_chord(s0, s1, tree_edge, finest, &mut out)? {
                return Ok(None);
            }
            if k + 1 < n_seg {
                out.extend_from_slice(s1);
            }
        }
        Ok(Some(out))
    }

    /// One chord between two valid states: certified ([`ValidityChecker::certify_motion`]), or
    /// split at its projected midpoint and both halves certified the same way (the states
    /// between appended to `out`, in order); false when that fails down to `finest`.
    fn certify_chord(&mut self, a: &[f64], b: &[f64], tree_edge: bool, finest: f64, out: &mut Vec<f64>) -> PlanResult<bool> {
        self.stats.motion_certificates += 1;
        let t = Instant::now();
        let ok = self.checker.certify_motion(a, b);
        self.stats.checker_s += t.elapsed().as_secs_f64();
        if ok? {
            return Ok(true);
        }
        let space = self.ambient;
        let nq = space.nq();
        let d = space.distance(a, b);
        if d / 2.0 < finest {
            return Ok(false);
        }
        let mut mid = vec![0.0; nq];
        space.interpolate(a, b, 0.5, &mut mid);
        let mut m = vec![0.0; nq];
        let mut rep = [Projection::default()];
        self.project_edge_states(&mid, tree_edge, &mut m, &mut rep)?;
        if !rep[0].success || m.iter().any(|x| !x.is_finite()) {
            return Ok(false);
        }
        let max_gap = MAX_SPACING * d / 2.0;
        if space.distance(a, &m) > max_gap || space.distance(&m, b) > max_gap {
            return Ok(false);
        }
        let mut ok = [false];
        self.check(&m, &mut ok)?;
        if !ok[0] || !self.certify_chord(a, &m, tree_edge, finest, out)? {
            return Ok(false);
        }
        out.extend_from_slice(&m);
        self.certify_chord(&m, b, tree_edge, finest, out)
    }

    /// The motion validator: the geodesic from `a` to `b` exists and `b` is valid.
    pub fn check_motion(&mut self, a: &[f64], b: &[f64]) -> PlanResult<bool> {
        Ok(self.geodesic(a, b, true)?.is_some())
    }
}

/// States checked together along a motion (the sphere checker's lanes).
pub(super) const RAKE: usize = 8;

/// The rows of `states` (n x nq, in order along a motion) in "rake" order: a batch of [`RAKE`]
/// rows spread evenly along the motion first (every `ceil(n / RAKE)`-th row), then the batches
/// between them, so that a checker that stops at its first invalid row
/// ([`ValidityChecker::all_valid`]) refuses a blocked motion after a few checks instead of
/// all of its states. (The planner arranges them with [`rake_into`], in memory it keeps.)
#[cfg(test)]
pub(super) fn rake(states: &[f64], nq: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(states.len());
    rake_into(states, nq, &mut out);
    out
}

/// [`rake`] into `out` (cleared first; its memory reused).
pub(super) fn rake_into(states: &[f64], nq: usize, out: &mut Vec<f64>) {
    out.clear();
    let n = states.len().checked_div(nq).unwrap_or(0);
    let stride = n.div_ceil(RAKE).max(1);
    for r in 0..stride.min(n) {
        for k in (r..n).step_by(stride) {
            out.extend_from_slice(&states[k * nq..(k + 1) * nq]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::{AlwaysValid, EuclideanSpace};

    #[test]
    fn rake_order_spreads_the_first_batch_and_keeps_every_row_once() {
        // 20 rows of nq = 2, row k = (k, -k): stride ceil(20 / 8) = 3
        let states: Vec<f64> = (0..20).flat_map(|k| [k as f64, -(k as f64)]).collect();
        let raked = rake(&states, 2);
        let order: Vec<usize> = raked.chunks(2).map(|r| { assert_eq!(r[1], -r[0]); r[0] as usize }).collect();
        assert_eq!(&order[..7], &[0, 3, 6, 9, 12, 15, 18]);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..20).collect::<Vec<_>>());
        assert!(rake(&[], 2).is_empty());
        assert_eq!(rake(&states[..6], 2), states[..6].to_vec(), "fewer rows than a batch: in order");
    }

    /// The identity projector (R^n is its own manifold).
    pub(crate) struct Identity;

    impl Projector for Identity {
        fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
            out.copy_from_slice(qs);
            reports.fill(Projection { success: true, iterations: 0 });
            Ok(())
        }
    }

    /// Finding PLAN-1 (fixed): an edge that would need more than Settings::MAX_EDGE_STATES
    /// states (a shortcut between far waypoints) is not taken; nothing is allocated for it.
    #[test]
    fn an_edge_beyond_the_state_cap_is_not_taken() {
        let st = Settings { edge_resolution: Settings::MIN_EDGE_RESOLUTION, step: 0.3, max_jump: 3.0, ..Settings::default() };
        st.validate().unwrap();
        let space = EuclideanSpace(2);
        let (mut projector, mut checker) = (Identity, AlwaysValid);
        let mut cs = ConstrainedSpace::new(&space, Some(&mut projector), &mut checker, &st);
        // the longest tree edge (max_jump * step = 0.9: 900000 states) is validated
        let states = cs.geodesic(&[0.0, 0.0], &[0.9, 0.0], true).unwrap().expect("a tree edge is validated");
        assert!(states.len() % 2 == 0 && (899_999..=900_000).contains(&(states.len() / 2)), "{} states", states.len() / 2);
        // 2^20 intervals at most, not one more
        let cap = Settings::MAX_EDGE_STATES as f64 * Settings::MIN_EDGE_RESOLUTION;
        assert!(cs.geodesic(&[0.0, 0.0], &[cap * 0.9999, 0.0], false).unwrap().is_some());
        assert!(cs.geodesic(&[0.0, 0.0], &[cap * 1.001, 0.0], false).unwrap().is_none());
        // 1e12 states would be 16 TB
        assert!(cs.geodesic(&[0.0, 0.0], &[1e6, 0.0], false).unwrap().is_none());
        assert!(cs.geodesic(&[-1e300, 0.0], &[1e300, 0.0], false).unwrap().is_none());
    }

    /// The unit circle of R^2 (radial projection), the arc (80, 100] degrees blocked.
    struct Circle;

    impl Projector for Circle {
        fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
            for ((q, o), r) in qs.chunks(2).zip(out.chunks_mut(2)).zip(reports.iter_mut()) {
                let n = q[0].hypot(q[1]);
                o[0] = q[0] / n;
                o[1] = q[1] / n;
                *r = Projection { success: n > 1e-9, iterations: 1 };
            }
            Ok(())
        }
    }

    struct Gap;

    impl ValidityChecker for Gap {
        fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
            for (q, v) in qs.chunks(2).zip(valid.iter_mut()) {
                let deg = q[1].atan2(q[0]).to_degrees();
                *v = !(deg > 80.0 && deg <= 100.0);
            }
            Ok(())
        }
    }

    fn on_circle(deg: f64) -> [f64; 2] {
        let r = deg.to_radians();
        [r.cos(), r.sin()]
    }

    #[test]
    fn the_geodesic_is_dense_on_the_manifold_and_valid() {
        let st = Settings::default();
        let space = EuclideanSpace(2);
        let (mut projector, mut checker) = (Circle, Gap);
        let mut cs = ConstrainedSpace::new(&space, Some(&mut projector), &mut checker, &st);
        let (a, b) = (on_circle(0.0), on_circle(30.0));
        let states = cs.geodesic(&a, &b, true).unwrap().expect("a free arc");
        let n = states.len() / 2;
        assert_eq!(n, (space.distance(&a, &b) / st.edge_resolution).ceil() as usize - 1);
        let mut prev = a.to_vec();
        for s in states.chunks(2).chain([&b[..]]) {
            assert!((s[0].hypot(s[1]) - 1.0).abs() < 1e-12);
            assert!(space.distance(&prev, s) <= MAX_SPACING * st.edge_resolution);
            prev = s.to_vec();
        }
        assert_eq!(cs.stats.edge_projections, n);
        assert_eq!(cs.stats.validity_checks, n + 1);
        assert!(cs.check_motion(&a, &b).unwrap());
        // through the blocked arc: no geodesic; the end itself blocked: only with check_end
        assert!(cs.geodesic(&on_circle(70.0), &on_circle(110.0), false).unwrap().is_none());
        assert!(cs.geodesic(&on_circle(60.0), &on_circle(80.5), false).unwrap().is_some());
        assert!(!cs.check_motion(&on_circle(60.0), &on_circle(80.5)).unwrap());
        // no resolution: the ends only
        let st0 = Settings { edge_resolution: 0.0, ..Settings::default() };
        let mut cs0 = ConstrainedSpace::new(&space, Some(&mut projector), &mut checker, &st0);
        assert_eq!(cs0.geodesic(&on_circle(70.0), &on_circle(110.0), false).unwrap(), Some(vec![]));
    }

    /// Counts the rows each method projects.
    #[derive(Default)]
    struct Counting {
        project: usize,
        edge: usize,
    }

    impl Projector for Counting {
        fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
            self.project += reports.len();
            Identity.project(qs, q_noms, out, reports)
        }
        fn project_edge(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
            self.edge += reports.len();
            Identity.project(qs, q_noms, out, reports)
        }
    }

    /// A tree edge (at most max_jump * step long) is projected with project_edge (the native
    /// projector: no posture step), a longer one (a shortcut) with project.
    #[test]
    fn tree_edges_use_project_edge_and_shortcuts_project() {
        let st = Settings::default();
        let space = EuclideanSpace(2);
        let (mut projector, mut checker) = (Counting::default(), AlwaysValid);
        let mut cs = ConstrainedSpace::new(&space, Some(&mut projector), &mut checker, &st);
        let tree_edge = st.max_jump * st.step;
        assert_eq!(cs.geodesic(&[0.0, 0.0], &[tree_edge, 0.0], false).unwrap().unwrap().len() / 2, 35);
        assert!(cs.geodesic(&[0.0, 0.0], &[tree_edge + 0.01, 0.0], false).unwrap().is_some());
        drop(cs);
        assert_eq!((projector.edge, projector.project), (35, 36));
    }

    #[test]
    fn a_step_is_projected_checked_and_refuses_jumps() {
        let st = Settings { lazy_edges: false, ..Settings::default() };
        let space = EuclideanSpace(2);
        let (mut projector, mut checker) = (Circle, Gap);
        let mut cs = ConstrainedSpace::new(&space, Some(&mut projector), &mut checker, &st);
        let from = on_circle(0.0);
        let s = cs.step(&from, &on_circle(60.0), true).unwrap().expect("a free step");
        assert!(!s.reached && (s.q[0].hypot(s.q[1]) - 1.0).abs() < 1e-12);
        assert!(s.edge.is_some_and(|e| !e.is_empty()));
        assert_eq!((cs.stats.projection_calls, cs.stats.projections), (1, 1));
        // within a step of a target on the manifold: the target itself, unprojected
        let near = on_circle(10.0);
        let s = cs.step(&from, &near, true).unwrap().unwrap();
        assert!(s.reached && s.q == near);
        assert_eq!(cs.stats.projection_calls, 1);
        // into the blocked arc: refused
        assert!(cs.step(&on_circle(75.0), &on_circle(95.0), true).unwrap().is_none());
        // straight outwards: the projection lands where it started, no move
        assert!(cs.step(&from, &[3.0, 0.0], false).unwrap().is_none());
    }
}

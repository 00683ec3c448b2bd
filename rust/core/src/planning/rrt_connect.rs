//! A bidirectional constrained RRT-Connect ([`Algorithm::RrtConnect`](super::Algorithm)), on
//! the same [`ConstrainedSpace`](super::ConstrainedSpace) and components as the paper's cRRT:
//! a tree from the start and one tree holding every valid goal as a root. Each iteration draws a
//! (projected) sample, extends one tree towards it (ConstrainedExtend: constrained steps, each a
//! node), then *connects* the other tree to the state reached (ConstrainedExtend after
//! ConstrainedExtend while each ends closer to it), and the trees swap roles (or, with
//! [`Settings::balance`](super::Settings::balance), the smaller tree grows next). When the trees
//! meet, the path through the meeting state is validated edge by edge like the cRRT's (lazy
//! edges: a failing edge prunes its subtree and the search goes on); the goal reached is the
//! goal tree's root the path ends at. Tree logic only: every state and edge comes from the
//! constrained space, so the returned path is dense, each state on the manifold and valid.

use super::rrt::{Found, Run};
use super::tree::{extract, Tree};
use super::PlanResult;

impl Run<'_> {
    /// One attempt of RRT-Connect from fresh trees (`start`; every valid goal a root of the goal
    /// tree, root k being goal `valid_goals[k]`).
    pub(super) fn connect_attempt(&mut self, start: &[f64], goals: &[f64], valid_goals: &[usize]) -> PlanResult<Option<Found>> {
        let space = self.ambient();
        let nq = space.nq();
        let mut trees = [Tree::new(nq, space.nv(), self.st.neighbors), Tree::new(nq, space.nv(), self.st.neighbors)];
        trees[0].add(space, start, usize::MAX, Some(&[]));
        for &g in valid_goals {
            trees[1].add(space, &goals[g * nq..(g + 1) * nq], usize::MAX, Some(&[]));
        }
        // the tree extended towards the samples (0: the start tree); the other connects
        let mut a = 0;
        let mut found = None;
        // the sample and the state reached, in memory kept across iterations
        let (mut q_rand, mut target) = (Vec::with_capacity(nq), Vec::with_capacity(nq));
        for _ in 0..self.st.max_extensions {
            // kept current: a time-out (poll, next_sample) leaves the attempt by `?`
            self.space.stats.nodes = trees[0].len() + trees[1].len();
            self.poll()?;
            self.space.stats.extensions += 1;
            self.next_sample(&mut q_rand)?;
            let (grow, other) = split(&mut trees, a);
            let near = grow.nearest(space, &q_rand);
            let ext = self.extend(grow, near, &q_rand, self.st.project_samples)?;
            if ext.added > 0 {
                target.clear();
                target.extend_from_slice(grow.node(ext.node));
                if let Some(met) = self.connect(other, &target)? {
                    let (s_node, g_node) = if a == 0 { (ext.node, met) } else { (met, ext.node) };
                    // both halves validated (lazy edges): a failing edge prunes its subtree
                    if self.validate_path(&mut trees[0], s_node)? && self.validate_path(&mut trees[1], g_node)? {
                        found = Some(join(&trees[0], s_node, &trees[1], g_node, valid_goals));
                        break;
                    }
                }
            }
            a = if self.st.balance { usize::from(trees[0].len() > trees[1].len()) } else { 1 - a };
        }
        self.space.stats.nodes = trees[0].len() + trees[1].len();
        Ok(found)
    }

    /// Connect `tree` to `target` (a state on the manifold): ConstrainedExtend from the nearest
    /// node, again from where it ended while each extension ends closer to the target. The node
    /// that reached it (the target itself), or None.
    fn connect(&mut self, tree: &mut Tree, target: &[f64]) -> PlanResult<Option<usize>> {
        let space = self.ambient();
        let mut from = tree.nearest(space, target);
        let mut dist = space.distance(tree.node(from), target);
        loop {
            let r = self.extend(tree, from, target, true)?;
            if r.reached {
                return Ok(Some(r.node));
            }
            let d = space.distance(tree.node(r.node), target);
            if r.added == 0 || !(d < dist) {
                return Ok(None);
            }
            self.poll()?;
            (from, dist) = (r.node, d);
        }
    }
}

/// The tree that grows (`trees[a]`) and the other one.
fn split(trees: &mut [Tree; 2], a: usize) -> (&mut Tree, &mut Tree) {
    let [t0, t1] = trees;
    if a == 0 {
        (t0, t1)
    } else {
        (t1, t0)
    }
}

/// The path from the start tree's root to `s_node`, then from `g_node` (the same state) down
/// the goal tree to its root: the goal tree's edges walked backwards, their states reversed.
fn join(start_tree: &Tree, s_node: usize, goal_tree: &Tree, g_node: usize, valid_goals: &[usize]) -> Found {
    let nq = start_tree.nq;
    let (mut waypoints, mut edges) = extract(start_tree, s_node);
    let chain = goal_tree.chain(g_node);
    for &i in chain[1..].iter().rev() {
        waypoints.push(goal_tree.node(goal_tree.parent[i]).to_vec());
        let states = goal_tree.edge(i);
        let mut reversed = Vec::with_capacity(states.len());
        states.chunks(nq).rev().for_each(|q| reversed.extend_from_slice(q));
        edges.push(reversed);
    }
    Found { waypoints, edges, goal: valid_goals[chain[0]] }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::super::{Algorithm, Components, EuclideanSpace, PlanResult, Planner, Projection, Projector, Sampler, Settings, Space, ValidityChecker, MAX_SPACING};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The unit sphere of R^3 (radial projection).
    struct Sphere;

    impl Projector for Sphere {
        fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
            for ((q, o), r) in qs.chunks(3).zip(out.chunks_mut(3)).zip(reports.iter_mut()) {
                let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                o.iter_mut().zip(q).for_each(|(a, b)| *a = b / n);
                *r = Projection { success: n > 1e-9, iterations: 1 };
            }
            Ok(())
        }
    }

    /// The points of R^3 where the function holds are valid.
    struct Region(fn(&[f64]) -> bool);

    impl ValidityChecker for Region {
        fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
            for (q, v) in qs.chunks(3).zip(valid.iter_mut()) {
                *v = (self.0)(q);
            }
            Ok(())
        }
    }

    /// The band |z| < 0.2 blocked but for a door around +y.
    const WALL: Region = Region(|q| q[2].abs() >= 0.2 || q[1] > 0.8);

    /// Uniform samples of [-1, 1]^2 x `z`.
    struct Cube(StdRng, std::ops::Range<f64>);

    impl Sampler for Cube {
        fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
            for q in out.chunks_mut(3).take(n) {
                q.copy_from_slice(&[self.0.random_range(-1.0..1.0), self.0.random_range(-1.0..1.0), self.0.random_range(self.1.clone())]);
            }
            Ok(())
        }
    }

    #[test]
    fn rrt_connect_goes_through_the_door_to_one_of_the_goals() {
        // two goals in the north, one of them blocked (in the band, away from the door)
        let goals = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0];
        for (lazy_edges, balance) in [(true, false), (false, false), (true, true), (false, true)] {
            for seed in 0..5 {
                let st = Settings { algorithm: Algorithm::RrtConnect, lazy_edges, balance, ..Settings::default() };
                let planner = Planner::new(Arc::new(EuclideanSpace(3)), st.clone()).unwrap();
                let (mut sampler, mut projector, mut checker) = (Cube(StdRng::seed_from_u64(seed), -1.0..1.0), Sphere, WALL);
                let mut interrupt = || Ok(());
                let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
                let sol = planner.plan(&[0.0, 0.0, -1.0], &goals, &mut c).unwrap();
                assert!(sol.success, "seed {seed}: {:?}", sol.stats);
                assert_eq!(sol.goal_index, Some(0));
                let path: Vec<&[f64]> = sol.path.chunks(3).collect();
                assert_eq!(path[0], &[0.0, 0.0, -1.0]);
                assert_eq!(*path.last().unwrap(), &[0.0, 0.0, 1.0]);
                for w in path.windows(2) {
                    assert!(EuclideanSpace(3).distance(w[0], w[1]) <= MAX_SPACING * st.edge_resolution + 1e-9);
                }
                for q in &path {
                    assert!((q.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.0).abs() < 1e-12);
                    assert!(q[2].abs() >= 0.2 || q[1] > 0.8, "{q:?} in the wall");
                }
                assert!(path.iter().any(|q| q[2].abs() < 0.2));
                // the waypoints are on the path, in order
                let mut k = 0;
                for w in sol.waypoints.chunks(3) {
                    k += path[k..].iter().position(|q| *q == w).expect("a waypoint on the path");
                }
                assert!(sol.stats.nodes >= sol.waypoints.len() / 3 && sol.stats.extensions > 0 && sol.stats.projections > 0);
            }
        }
    }

    #[test]
    fn balanced_rrt_connect_grows_the_smaller_tree() {
        // in free R^3 (no projector): three goal roots near (0, 0, 1) in a slab no step of 0.3
        // leaves valid, samples in the open south, one node per extension: the goal tree never
        // grows. Alternating, the start tree (1 node) grows on iterations 0 and 2 of 3; balanced,
        // on all three (the smaller tree each time: 1, 2, 3 nodes against 3, the start tree on a tie)
        let goals = [0.0, 0.0, 1.0, 0.05, 0.0, 1.0, 0.0, 0.05, 1.0];
        for (balance, start_nodes) in [(false, 3), (true, 4)] {
            let st = Settings { algorithm: Algorithm::RrtConnect, balance, max_increments: 1, max_extensions: 3, retries: 0, ..Settings::default() };
            let planner = Planner::new(Arc::new(EuclideanSpace(3)), st).unwrap();
            let (mut sampler, mut checker) = (Cube(StdRng::seed_from_u64(3), -1.0..-0.5), Region(|q| q[2] <= -0.2 || q[2] >= 0.95));
            let mut interrupt = || Ok(());
            let mut c = Components { sampler: &mut sampler, projector: None, checker: &mut checker, interrupt: &mut interrupt };
            let sol = planner.plan(&[0.0, 0.0, -1.0], &goals, &mut c).unwrap();
            assert!(!sol.success);
            assert_eq!(sol.stats.nodes, start_nodes + 3, "balance {balance}: {:?}", sol.stats);
        }
    }

    #[test]
    fn rrt_connect_reports_failure_when_the_goal_is_walled_off() {
        // the door closed: no path from the south to the north
        let st = Settings { algorithm: Algorithm::RrtConnect, max_extensions: 60, retries: 1, ..Settings::default() };
        let planner = Planner::new(Arc::new(EuclideanSpace(3)), st).unwrap();
        let (mut sampler, mut projector, mut checker) = (Cube(StdRng::seed_from_u64(1), -1.0..1.0), Sphere, Region(|q| q[2].abs() >= 0.2));
        let mut interrupt = || Ok(());
        let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
        let sol = planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c).unwrap();
        assert!(!sol.success && sol.path.is_empty() && sol.goal_index.is_none());
        assert_eq!((sol.stats.extensions, sol.stats.retries), (120, 1));
    }
}

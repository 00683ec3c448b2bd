//! The constrained RRT: a point on a sphere around an obstacle band (pure Rust), the Panda with
//! its gripper kept horizontal (native projector, parry collision; needs example-robot-data),
//! bad input, and errors from components.

#[path = "common/fixtures.rs"]
mod fixtures;

use std::sync::Arc;

use fixtures::{no_interrupt, panda_horizontal_gripper, Band, CubeSampler, SphereProjector, WithPosture};
use genplan_core::planning::{
    Algorithm, Components, DataSampler, EuclideanSpace, GaussNewtonProjector, MixtureSampler, NeighborIndex, PlanError, PlanResult, Planner, Projection,
    Projector, Sampler, Sampling, Settings, Space, UniformSampler, ValidityChecker,
};
use genplan_core::robot::preset;
use rand::rngs::StdRng;
use rand::SeedableRng;

fn sphere_plan(algorithm: Algorithm, neighbors: NeighborIndex, lazy_edges: bool, simplify: bool, seed: u64) -> genplan_core::planning::Solution {
    let settings = Settings { algorithm, neighbors, lazy_edges, simplify, ..Settings::default() };
    pole_to_pole(settings, &mut Band, seed)
}

/// From the south to the north pole of the unit sphere with `settings` and `checker`.
fn pole_to_pole(settings: Settings, checker: &mut dyn ValidityChecker, seed: u64) -> genplan_core::planning::Solution {
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), settings).unwrap();
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(seed) };
    let mut projector = SphereProjector { radius: 1.0 };
    let mut interrupt = no_interrupt;
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker, interrupt: &mut interrupt };
    planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c).unwrap()
}

#[test]
fn sphere_through_the_door() {
    let cases = [(NeighborIndex::Linear, true, false), (NeighborIndex::KdForest, true, false), (NeighborIndex::Linear, false, false), (NeighborIndex::Linear, true, true)];
    for ((neighbors, lazy, simplify), algorithm) in cases.into_iter().flat_map(|c| [(c, Algorithm::Crrt), (c, Algorithm::RrtConnect)]) {
        for seed in 0..5 {
            let sol = sphere_plan(algorithm, neighbors, lazy, simplify, seed);
            assert!(sol.success, "{algorithm:?} seed {seed}: {:?}", sol.stats);
            let path: Vec<&[f64]> = sol.path.chunks(3).collect();
            assert_eq!(path.first().unwrap(), &[0.0, 0.0, -1.0]);
            assert_eq!(path.last().unwrap(), &[0.0, 0.0, 1.0]);
            for w in path.windows(2) {
                // dense: consecutive states at most ~edge_resolution apart (x2 for curvature)
                assert!(EuclideanSpace(3).distance(w[0], w[1]) <= genplan_core::planning::MAX_SPACING * Settings::default().edge_resolution + 1e-9);
                // and the straight chord between them stays valid and near the sphere
                for k in 0..=10 {
                    let t = k as f64 / 10.0;
                    let p: Vec<f64> = (0..3).map(|i| w[0][i] + t * (w[1][i] - w[0][i])).collect();
                    let r = p.iter().map(|x| x * x).sum::<f64>().sqrt();
                    assert!((r - 1.0).abs() < 2e-3, "off the sphere by {}", r - 1.0);
                }
            }
            for q in &path {
                assert!(Band::ok(q), "path state {q:?} in the band");
                let r = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                assert!((r - 1.0).abs() < 1e-12);
            }
            // the path passes through the door
            assert!(path.iter().any(|q| q[2].abs() < 0.2 && q[1] > 0.8));
            if simplify {
                // shortcuts shorten the path: no longer than the unsimplified one
                let plain = sphere_plan(algorithm, neighbors, lazy, false, seed);
                let length = |p: &[f64]| p.chunks(3).collect::<Vec<_>>().windows(2).map(|w| EuclideanSpace(3).distance(w[0], w[1])).sum::<f64>();
                assert!(length(&sol.path) <= length(&plain.path) + 1e-9);
                assert!(sol.stats.shortcuts > 0);
            }
            assert!(sol.stats.projections > 0 && sol.stats.extensions > 0 && sol.stats.nodes > 2);
        }
    }
}

/// `f` given the sphere problem's planner (default settings) and components (a seeded cube
/// sampler, the unit sphere, the band).
fn on_the_sphere<R>(f: impl FnOnce(&Planner, &mut Components<'_>) -> R) -> R {
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings::default()).unwrap();
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(0) };
    let mut projector = SphereProjector { radius: 1.0 };
    let mut checker = Band;
    let mut interrupt = no_interrupt;
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    f(&planner, &mut c)
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    on_the_sphere(bad_input_cases);
}

fn bad_input_cases(planner: &Planner, c: &mut Components<'_>) {
    let mut plan = |start: &[f64], goals: &[f64]| planner.plan(start, goals, c).map(|s| s.success);
    assert!(matches!(plan(&[0.0, 0.0], &[0.0, 0.0, 1.0]), Err(PlanError::InvalidStart(m)) if m == "start: expected length 3, got 2"));
    assert!(matches!(plan(&[0.0, f64::NAN, -1.0], &[0.0, 0.0, 1.0]), Err(PlanError::InvalidStart(m)) if m.contains("not finite")));
    assert!(matches!(plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0, 2.0]), Err(PlanError::InvalidGoal(m)) if m.starts_with("goals")));
    // a start inside the band
    assert!(matches!(plan(&[1.0, 0.0, 0.0], &[0.0, 0.0, 1.0]), Err(PlanError::InvalidStart(m)) if m.contains("not valid")));
    assert!(matches!(plan(&[0.0, 0.0, -1.0], &[1.0, 0.0, 0.0]), Err(PlanError::InvalidGoal(m)) if m.contains("none of the goal")));
    assert!(matches!(planner.extend(&[0.0], &[0.0, 0.0, 1.0], false, c), Err(PlanError::Input(m)) if m.starts_with("from")));
    let settings_error = |bad: Settings| Planner::new(Arc::new(EuclideanSpace(3)), bad).err().expect("bad settings").to_string();
    let e = settings_error(Settings { step: -1.0, ..Settings::default() });
    assert_eq!(e, "settings: step must be positive and finite, got -1");
    let e = Settings { sample_batch: 0, ..Settings::default() }.validate().unwrap_err();
    assert!(matches!(e, PlanError::Settings { field: "sample_batch", .. }));
    assert_eq!(e.to_string(), "settings: max_increments, max_extensions, sample_batch and max_empty_batches must be >= 1");
}

/// A projector that cannot project anything with z > 0.9 (e.g. an IK target out of reach).
struct RefusesTheTop(SphereProjector);
impl Projector for RefusesTheTop {
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        self.0.project(qs, q_noms, out, reports)?;
        for (q, r) in qs.chunks(3).zip(reports.iter_mut()) {
            r.success &= q[2] <= 0.9;
        }
        Ok(())
    }
}

#[test]
fn start_and_goals_off_the_manifold_are_refused_or_projected() {
    on_the_sphere(off_the_manifold_cases);
}

fn off_the_manifold_cases(planner: &Planner, c: &mut Components<'_>) {
    let mut plan = |start: &[f64], goals: &[f64]| planner.plan(start, goals, c);
    let (start, goal) = ([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]);
    // 0.1 off the sphere: refused, named, with the distance and the tolerance
    match plan(&[0.0, 0.0, -1.1], &goal) {
        Err(PlanError::InvalidStart(m)) => {
            assert_eq!(m, "start: not on the constraint manifold: the projector moved it by 0.100 (goal_tolerance 0.001)")
        }
        other => panic!("expected InvalidStart, got {:?}", other.map(|s| s.success)),
    }
    // every goal off the manifold is named, even when another is fine
    let goals = [0.0, 0.0, 1.0, 0.0, 0.0, 1.3, 0.0, 1.0, 0.0, 0.6, 0.0, 0.8, 0.5, 0.0, 0.0];
    match plan(&start, &goals) {
        Err(PlanError::InvalidGoal(m)) => assert_eq!(
            m,
            "goals[1]: not on the constraint manifold: the projector moved it by 0.300 (goal_tolerance 0.001); also off it: goals[4]"
        ),
        other => panic!("expected InvalidGoal, got {:?}", other.map(|s| s.success)),
    }
    // within goal_tolerance of the sphere: planned from / to its projection, so that every state
    // of the path is on the sphere
    let sol = plan(&[0.0, 0.0, -1.0005], &[0.0, 0.0, 1.0004]).unwrap();
    assert!(sol.success);
    assert_eq!(&sol.path[..3], &start);
    assert_eq!(&sol.path[sol.path.len() - 3..], &goal);
    // a start or goal the projector cannot project
    let mut projector = RefusesTheTop(SphereProjector { radius: 1.0 });
    let mut c = Components { sampler: &mut *c.sampler, projector: Some(&mut projector), checker: &mut *c.checker, interrupt: &mut *c.interrupt };
    match planner.plan(&start, &goal, &mut c) {
        Err(PlanError::InvalidGoal(m)) => assert_eq!(m, "goals[0]: not on the constraint manifold: the projector could not project it"),
        other => panic!("expected InvalidGoal, got {:?}", other.map(|s| s.success)),
    }
    match planner.plan(&goal, &start, &mut c) {
        Err(PlanError::InvalidStart(m)) => assert_eq!(m, "start: not on the constraint manifold: the projector could not project it"),
        other => panic!("expected InvalidStart, got {:?}", other.map(|s| s.success)),
    }
}

#[derive(Debug)]
struct Boom;
impl std::fmt::Display for Boom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "boom")
    }
}
impl std::error::Error for Boom {}

struct FailingSampler;
impl Sampler for FailingSampler {
    fn sample(&mut self, _n: usize, _out: &mut [f64]) -> PlanResult<()> {
        Err(PlanError::Component(Box::new(Boom)))
    }
}

/// Returns NaN (and claims success) for every configuration not already on the unit sphere.
struct NaNProjector;
impl Projector for NaNProjector {
    fn project(&mut self, qs: &[f64], _n: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        for (q, o) in qs.chunks(3).zip(out.chunks_mut(3)) {
            let on = (q.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-12;
            o.copy_from_slice(if on { q } else { &[f64::NAN; 3] });
        }
        reports.fill(Projection { success: true, iterations: 1 });
        Ok(())
    }
}

#[test]
fn component_errors_come_back_intact() {
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings::default()).unwrap();
    let mut projector = SphereProjector { radius: 1.0 };
    let mut checker = Band;
    let mut interrupt = no_interrupt;
    let mut sampler = FailingSampler;
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    match planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c) {
        Err(PlanError::Component(e)) => assert!(e.downcast_ref::<Boom>().is_some()),
        other => panic!("expected the sampler's error, got {:?}", other.map(|s| s.success)),
    }
    // an interrupt ends the plan with its error
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(0) };
    let mut calls = 0;
    let mut interrupt = || {
        calls += 1;
        if calls > 3 {
            Err(PlanError::Component(Box::new(Boom)))
        } else {
            Ok(())
        }
    };
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    assert!(matches!(planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c), Err(PlanError::Component(_))));
    // a projector that returns NaN never puts NaN in the tree: the samples are rejected
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(0) };
    let mut nan = NaNProjector;
    let mut interrupt = no_interrupt;
    let settings = Settings { max_empty_batches: 3, ..Settings::default() };
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), settings).unwrap();
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut nan), checker: &mut checker, interrupt: &mut interrupt };
    match planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c) {
        Err(PlanError::NoProjectableSample(m)) => assert!(m.contains("no sample could be projected"), "{m}"),
        other => panic!("expected an error, got {:?}", other.map(|s| s.success)),
    }
    // nor as a start: a NaN projection of the start is a start off the manifold
    match planner.plan(&[0.0, 0.0, -1.1], &[0.0, 0.0, 1.0], &mut c) {
        Err(PlanError::InvalidStart(m)) => assert!(m.ends_with("the projector could not project it"), "{m}"),
        other => panic!("expected an error, got {:?}", other.map(|s| s.success)),
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn panda_keeps_its_gripper_horizontal_around_a_box() {
    let (model, mut world) = preset("panda").unwrap().load().unwrap();
    // a box between the two sides of the robot
    world
        .add_box("wall", [0.05, 0.05, 0.3], nalgebra::Isometry3::translation(0.45, 0.0, 0.35))
        .unwrap();
    let world = Arc::new(world);
    let gn = Arc::new(panda_horizontal_gripper(model.clone(), 1e-4));
    let mut projector = GaussNewtonProjector::new(gn.clone(), false);
    let mut checker = genplan_core::planning::CollisionChecker::new(world.clone(), false);

    // start and goal: projected random configurations, valid, on opposite sides of the wall
    let mut sampler = UniformSampler::new(model.clone(), None, 3).unwrap();
    let mut pick = |want_y_positive: bool| -> Vec<f64> {
        let mut q = vec![0.0; 7];
        loop {
            sampler.sample(1, &mut q).unwrap();
            let o = gn.solve_unchecked(&q, None);
            let mut poses = Vec::new();
            model.forward_kinematics(&o.q, &mut poses).unwrap();
            let hand = poses[model.link_index("panda_hand").unwrap()].translation.vector;
            let mut v = [false];
            checker.check(&o.q, &mut v).unwrap();
            if o.success && v[0] && (hand.y > 0.25) == want_y_positive && hand.y.abs() > 0.25 && hand.x > 0.3 {
                return o.q;
            }
        }
    };
    let start = pick(false);
    let goal = pick(true);

    for algorithm in [Algorithm::Crrt, Algorithm::RrtConnect] {
        let planner = Planner::new(model.clone(), Settings { algorithm, ..Settings::default() }).unwrap();
        let plan = |projector: &mut dyn Projector, checker: &mut dyn ValidityChecker| {
            let uniform = UniformSampler::new(model.clone(), None, 11).unwrap();
            let uniform2 = UniformSampler::new(model.clone(), None, 12).unwrap();
            let mut mixture = MixtureSampler::new(Box::new(uniform), Box::new(uniform2), 0.8, 7, 5).unwrap();
            let mut interrupt = no_interrupt;
            let mut c = Components { sampler: &mut mixture, projector: Some(projector), checker, interrupt: &mut interrupt };
            planner.plan(&start, &goal, &mut c).unwrap()
        };
        let sol = plan(&mut projector, &mut checker);
        assert!(sol.success, "{algorithm:?}: {:?}", sol.stats);
        let path: Vec<&[f64]> = sol.path.chunks(7).collect();
        assert_eq!(path[0], &start[..]);
        assert_eq!(*path.last().unwrap(), &goal[..]);
        for q in &path {
            // every state satisfies the constraint: the projector has nothing to do
            let o = gn.solve_unchecked(q, None);
            assert!(o.success && o.iterations == 0, "{algorithm:?}: state off the manifold: residuals {:?}", o.residuals);
            assert!(!world.in_collision(q).unwrap());
        }
        for w in path.windows(2) {
            assert!(model.as_ref().distance(w[0], w[1]) <= genplan_core::planning::MAX_SPACING * Settings::default().edge_resolution + 1e-9);
        }
        // edge states projected without the posture step (GaussNewtonProjector::project_edge)
        // or with it (the trait's default): the same tree, the same waypoints
        let mut with_posture = WithPosture(GaussNewtonProjector::new(gn.clone(), false));
        let same = plan(&mut with_posture, &mut checker);
        assert_eq!(same.waypoints, sol.waypoints, "{algorithm:?}");
        assert_eq!((same.stats.extensions, same.stats.projections, same.stats.nodes), (sol.stats.extensions, sol.stats.projections, sol.stats.nodes));
        assert_eq!(same.path.len(), sol.path.len());
    }
}

/// Edge states projected without the posture step land on the manifold like those projected
/// with it, a few micro-radians apart at most (the posture only picks among the nearby solutions).
#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn panda_edge_states_without_the_posture_step_land_on_the_manifold() {
    let (model, _) = preset("panda").unwrap().load().unwrap();
    let gn = Arc::new(panda_horizontal_gripper(model.clone(), 1e-5));
    let mut projector = GaussNewtonProjector::new(gn.clone(), false);
    let mut sampler = UniformSampler::new(model.clone(), None, 5).unwrap();
    let mut on_manifold = || loop {
        let mut q = vec![0.0; 7];
        sampler.sample(1, &mut q).unwrap();
        let o = gn.solve_unchecked(&q, None);
        if o.success {
            return o.q;
        }
    };
    let mut states = 0;
    while states < 100 {
        // an edge as the planner makes: from a state on the manifold, 0.3 rad towards another
        let (a, far) = (on_manifold(), on_manifold());
        let mut b = vec![0.0; 7];
        model.as_ref().interpolate(&a, &far, 0.3 / model.as_ref().distance(&a, &far), &mut b);
        let o = gn.solve_unchecked(&b, None);
        if !o.success {
            continue;
        }
        let b = o.q;
        let n = 9;
        let mut lin = vec![0.0; n * 7];
        for k in 0..n {
            model.as_ref().interpolate(&a, &b, (k + 1) as f64 / (n + 1) as f64, &mut lin[k * 7..(k + 1) * 7]);
        }
        let (mut with, mut without) = (vec![0.0; n * 7], vec![0.0; n * 7]);
        let (mut rw, mut ro) = (vec![Projection::default(); n], vec![Projection::default(); n]);
        projector.project(&lin, &lin, &mut with, &mut rw).unwrap();
        projector.project_edge(&lin, &lin, &mut without, &mut ro).unwrap();
        for k in 0..n {
            if !rw[k].success {
                continue;
            }
            assert!(ro[k].success, "edge state {k}: projected with the posture step, not without");
            let (w, o) = (&with[k * 7..(k + 1) * 7], &without[k * 7..(k + 1) * 7]);
            assert!(gn.solve_unchecked(o, None).iterations == 0, "not on the manifold");
            let gap = model.as_ref().distance(w, o);
            let moved = model.as_ref().distance(&lin[k * 7..(k + 1) * 7], o);
            assert!(gap <= 0.05 * moved.max(1e-3), "state {k}: {gap} apart, moved by {moved}");
            states += 1;
        }
    }
}

#[test]
fn uniform_sampler_draws_a_free_flyer_base_in_its_box() {
    let (talos, _) = preset("talos").unwrap().load().unwrap();
    let base = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let (lo, hi) = ([-0.1, -0.1, 0.6], [0.1, 0.1, 1.1]);
    let mut s = UniformSampler::new(talos.clone(), Some(base), 5).unwrap().with_base_box(lo, hi).unwrap();
    let n = 400;
    let mut q = vec![0.0; n * talos.nq];
    s.sample(n, &mut q).unwrap();
    let mut spread = [(f64::INFINITY, f64::NEG_INFINITY); 3];
    for row in q.chunks(talos.nq) {
        for k in 0..3 {
            assert!(row[k] >= lo[k] && row[k] <= hi[k], "base position {k}: {}", row[k]);
            spread[k] = (spread[k].0.min(row[k]), spread[k].1.max(row[k]));
        }
        assert_eq!(&row[3..7], &base[3..7], "orientation held");
        for i in 7..talos.nq {
            assert!(row[i] >= talos.lower[i] && row[i] <= talos.upper[i]);
        }
    }
    // the positions fill the box (400 draws: each coordinate within 5 % of both faces)
    for k in 0..3 {
        let w = hi[k] - lo[k];
        assert!(spread[k].0 < lo[k] + 0.05 * w && spread[k].1 > hi[k] - 0.05 * w, "{k}: {:?}", spread[k]);
    }
    // without a box the base stays put
    let mut fixed = UniformSampler::new(talos.clone(), Some(base), 5).unwrap();
    fixed.sample(3, &mut q[..3 * talos.nq]).unwrap();
    assert!(q[..3 * talos.nq].chunks(talos.nq).all(|r| r[..7] == base));

    let bad = UniformSampler::new(talos.clone(), None, 5).unwrap().with_base_box([0.0, 0.0, 1.0], [0.1, 0.1, 0.9]);
    assert!(matches!(bad, Err(PlanError::Input(m)) if m.contains("bad base box")));
    let (panda, _) = preset("panda").unwrap().load().unwrap();
    let fixed_base = UniformSampler::new(panda, None, 5).unwrap().with_base_box(lo, hi);
    assert!(matches!(fixed_base, Err(PlanError::Input(m)) if m.contains("free-flyer")));
}

/// Halton sampling: the same points for the same seed and other points for another, the
/// sequence continued across calls, every row within the joint limits (continuous joints on
/// their circle, a free-flyer base's position in its box), and the box covered more evenly than
/// by random draws (the squared deviations of 16 bins per coordinate, summed).
#[test]
fn halton_sampling_is_seeded_within_the_limits_and_covers_the_box() {
    use genplan_core::kinematics::Motion;
    let (kinova, _) = preset("kinova").unwrap().load().unwrap();
    assert!(kinova.nq > kinova.nv, "the Kinova has continuous joints");
    let nq = kinova.nq;
    let n = 512;
    let draw = |seed: u64, sampling: Sampling, calls: &[usize]| {
        let mut s = UniformSampler::new(kinova.clone(), None, seed).unwrap().with_sampling(sampling);
        assert_eq!(s.sampling(), sampling);
        let mut q = vec![0.0; n * nq];
        let mut at = 0;
        for &m in calls {
            s.sample(m, &mut q[at * nq..(at + m) * nq]).unwrap();
            at += m;
        }
        q
    };
    let a = draw(3, Sampling::Halton, &[n]);
    assert_eq!(a, draw(3, Sampling::Halton, &[100, 1, n - 101]), "the sequence continues across calls");
    assert_ne!(a, draw(4, Sampling::Halton, &[n]), "another seed, other points");
    let random = draw(3, Sampling::Random, &[n]);
    assert_ne!(a, random);
    // each coordinate's value in [0, 1) of its range (a continuous joint: its angle)
    let units = |q: &[f64]| -> Vec<Vec<f64>> {
        let mut cols = Vec::new();
        for j in kinova.joints.iter().filter(|j| j.q_index != usize::MAX) {
            let i = j.q_index;
            let col: Vec<f64> = match j.motion {
                Motion::Continuous { .. } => q.chunks(nq).map(|r| {
                    assert!((r[i].hypot(r[i + 1]) - 1.0).abs() < 1e-12, "{}: off its circle", j.name);
                    (r[i + 1].atan2(r[i]) + std::f64::consts::PI) / (2.0 * std::f64::consts::PI)
                }).collect(),
                Motion::Fixed => continue,
                _ => q.chunks(nq).map(|r| {
                    assert!(r[i] >= kinova.lower[i] && r[i] <= kinova.upper[i], "{}: {} outside its limits", j.name, r[i]);
                    (r[i] - kinova.lower[i]) / (kinova.upper[i] - kinova.lower[i])
                }).collect(),
            };
            cols.push(col);
        }
        cols
    };
    let deviation = |q: &[f64]| -> f64 {
        units(q).iter().map(|col| {
            let mut bins = [0usize; 16];
            col.iter().for_each(|&u| bins[((u * 16.0) as usize).min(15)] += 1);
            bins.iter().map(|&b| (b as f64 - n as f64 / 16.0).powi(2)).sum::<f64>()
        }).sum()
    };
    let (dh, dr) = (deviation(&a), deviation(&random));
    assert!(dh < dr / 4.0, "Halton's bins deviate by {dh}, random ones by {dr}");
    // a free-flyer base's position drawn from the sequence, in its box
    let (talos, _) = preset("talos").unwrap().load().unwrap();
    let (lo, hi) = ([-0.1, -0.1, 0.6], [0.1, 0.1, 1.1]);
    let base = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let mut s = UniformSampler::new(talos.clone(), Some(base), 5).unwrap().with_sampling(Sampling::Halton).with_base_box(lo, hi).unwrap();
    assert_eq!(s.sampling(), Sampling::Halton);
    let mut q = vec![0.0; 64 * talos.nq];
    s.sample(64, &mut q).unwrap();
    for row in q.chunks(talos.nq) {
        assert!((0..3).all(|k| row[k] >= lo[k] && row[k] <= hi[k]), "{:?}", &row[..3]);
        assert_eq!(&row[3..7], &base[3..7]);
        assert!((7..talos.nq).all(|i| row[i] >= talos.lower[i] && row[i] <= talos.upper[i]));
    }
}

/// The data sampler draws whole rows of its data, every row in time, the same stream for the same
/// seed; bad data are refused with the reason.
#[test]
fn data_sampler_draws_whole_rows_of_its_data() {
    let nq = 3;
    let rows: Vec<f64> = (0..5 * nq).map(|i| i as f64).collect();
    let mut s = DataSampler::new(rows.clone(), nq, 7).unwrap();
    assert_eq!(s.len(), 5);
    let mut out = vec![f64::NAN; 200 * nq];
    s.sample(200, &mut out).unwrap();
    let mut seen = [false; 5];
    for r in out.chunks(nq) {
        let i = (r[0] / nq as f64) as usize;
        assert_eq!(r, &rows[i * nq..(i + 1) * nq], "a drawn row is a row of the data");
        seen[i] = true;
    }
    assert!(seen.iter().all(|&b| b), "200 draws reach each of 5 rows");
    let mut again = vec![0.0; 200 * nq];
    DataSampler::new(rows.clone(), nq, 7).unwrap().sample(200, &mut again).unwrap();
    assert_eq!(out, again);
    let mut small = vec![0.0; nq];
    assert!(matches!(s.sample(2, &mut small), Err(PlanError::Input(m)) if m.contains("do not fit")));
    for (data, n, why) in [
        (vec![], 3, "one or more rows"),
        (vec![1.0; 4], 3, "rows of 3"),
        (vec![1.0; 3], 0, "nq = 0"),
        (vec![0.0, 1.0, 2.0, 3.0, f64::NAN, 5.0], 3, "row 1"),
    ] {
        assert!(matches!(DataSampler::new(data, n, 0), Err(PlanError::Input(m)) if m.contains(why)), "{why}");
    }
}

/// A sampler that fills every row with one value (0 or 1): which sampler a mixture row came from.
struct Constant(f64);

impl Sampler for Constant {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        out[..n].fill(self.0);
        Ok(())
    }
}

#[test]
fn an_adaptive_mixture_hands_over_to_the_secondary_sampler() {
    // p = 1 halving every 100 rows: rows 0..100 ~ 72 % primary (the mean of 0.5^(k/100)),
    // rows 400..500 ~ 4.5 %, and in the long run none; a constant mixture stays at p
    let primary_share = |m: &mut MixtureSampler, rows: usize| {
        let mut out = vec![0.0; rows];
        for chunk in out.chunks_mut(16) {
            let n = chunk.len();
            m.sample(n, chunk).unwrap();
        }
        out.iter().sum::<f64>() / rows as f64
    };
    let mut shares = Vec::new();
    for seed in 0..20 {
        let mut m = MixtureSampler::new(Box::new(Constant(1.0)), Box::new(Constant(0.0)), 1.0, 1, seed)
            .unwrap()
            .with_half_life(100.0)
            .unwrap();
        assert_eq!(m.p_at(0), 1.0);
        assert!((m.p_at(100) - 0.5).abs() < 1e-12 && (m.p_at(300) - 0.125).abs() < 1e-12);
        let first = primary_share(&mut m, 100);
        let _ = primary_share(&mut m, 300);
        let fifth = primary_share(&mut m, 100);
        shares.push((first, fifth));
    }
    let mean = |f: &dyn Fn(&(f64, f64)) -> f64| shares.iter().map(f).sum::<f64>() / shares.len() as f64;
    let (first, fifth) = (mean(&|s| s.0), mean(&|s| s.1));
    let expect = |a: f64| (0..100).map(|k| 0.5f64.powf((a + k as f64) / 100.0)).sum::<f64>() / 100.0;
    assert!((first - expect(0.0)).abs() < 0.03, "rows 0..100: {first} vs {}", expect(0.0));
    assert!((fifth - expect(400.0)).abs() < 0.02, "rows 400..500: {fifth} vs {}", expect(400.0));
    let mut constant = MixtureSampler::new(Box::new(Constant(1.0)), Box::new(Constant(0.0)), 0.8, 1, 1).unwrap();
    let _ = primary_share(&mut constant, 400);
    assert!((primary_share(&mut constant, 2000) - 0.8).abs() < 0.03);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let m = MixtureSampler::new(Box::new(Constant(1.0)), Box::new(Constant(0.0)), 1.0, 1, 0).unwrap();
        assert!(m.with_half_life(bad).is_err(), "half_life {bad} accepted");
    }
}

/// A start within goal_tolerance of a valid goal has reached it: one state, no search, the
/// nearest such goal (both algorithms).
#[test]
fn integrity_3_a_start_at_the_goal_is_a_one_state_path() {
    for algorithm in [Algorithm::Crrt, Algorithm::RrtConnect] {
        let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings { algorithm, ..Settings::default() }).unwrap();
        let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(0) };
        let (mut projector, mut checker, mut interrupt) = (SphereProjector { radius: 1.0 }, Band, no_interrupt);
        let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
        let start = [0.0, 0.0, -1.0];
        let sol = planner.plan(&start, &start, &mut c).unwrap();
        assert!(sol.success, "{algorithm:?}");
        assert_eq!((sol.path.as_slice(), sol.waypoints.as_slice(), sol.goal_index), (&start[..], &start[..], Some(0)));
        assert_eq!((sol.stats.extensions, sol.stats.nodes, sol.stats.samples), (0, 1, 0));
        // 5e-4 away on the sphere (within goal_tolerance 1e-3), after a far goal and a farther
        // one within the tolerance
        let (near, nearer) = ([(8e-4f64).sin(), 0.0, -(8e-4f64).cos()], [0.0, (5e-4f64).sin(), -(5e-4f64).cos()]);
        let goals = [[0.0, 0.0, 1.0], near, nearer].concat();
        let sol = planner.plan(&start, &goals, &mut c).unwrap();
        assert!(sol.success && sol.goal_index == Some(2) && sol.path == start.to_vec(), "{algorithm:?}: {:?}", sol.goal_index);
        // farther than the tolerance: a search, a path of many states ending at the goal
        let far = [(0.01f64).sin(), 0.0, -(0.01f64).cos()];
        let sol = planner.plan(&start, &far, &mut c).unwrap();
        assert!(sol.success && sol.path.len() / 3 > 1 && sol.path[sol.path.len() - 3..] == far, "{algorithm:?}");
    }
}

/// A goal within one step whose direct edge is valid is joined by that edge: a short path along
/// the manifold, not a tree grown away and back; a goal farther than a step is left to the search.
#[test]
fn integrity_rerun_a_goal_within_a_step_is_joined_directly() {
    for algorithm in [Algorithm::Crrt, Algorithm::RrtConnect] {
        let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings { algorithm, ..Settings::default() }).unwrap();
        let step = planner.settings.step;
        let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(0) };
        let (mut projector, mut checker, mut interrupt) = (SphereProjector { radius: 1.0 }, Band, no_interrupt);
        let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
        let start = [0.0, 0.0, -1.0];
        for angle in [0.003, 0.05, 0.2] {
            let goal = [f64::sin(angle), 0.0, -f64::cos(angle)];
            let sol = planner.plan(&start, &goal, &mut c).unwrap();
            assert!(sol.success, "{algorithm:?} {angle}");
            let length: f64 = sol.path.chunks(3).zip(sol.path.chunks(3).skip(1))
                .map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt())
                .sum();
            assert!(length <= angle * 1.01 + 1e-9, "{algorithm:?} {angle}: a path {length} long");
            assert_eq!(sol.stats.samples, 0, "{algorithm:?} {angle}: no sample drawn");
        }
        let far = [f64::sin(2.0 * step), 0.0, -f64::cos(2.0 * step)];
        let sol = planner.plan(&start, &far, &mut c).unwrap();
        assert!(sol.success && sol.stats.samples > 0, "{algorithm:?}: a goal two steps away is searched for");
    }
}

/// The unit sphere whose chords are held to `chord`: a chord's midpoint is within `chord` of
/// the sphere (the sagitta of a chord d long is about d^2 / 8: 7.8e-5 at 0.025).
struct ChordSphere {
    chord: f64,
    calls: usize,
}

impl Projector for ChordSphere {
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        SphereProjector { radius: 1.0 }.project(qs, q_noms, out, reports)
    }
    fn check_chords(&mut self, qs: &[f64], ok: &mut [bool]) -> PlanResult<bool> {
        self.calls += 1;
        for (q, o) in qs.chunks(3).zip(ok.iter_mut()) {
            *o = (q.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.0).abs() <= self.chord;
        }
        Ok(true)
    }
}

/// With a projector that holds chords to a tolerance, every chord of the path keeps it: the
/// chords that stray are split at their projected midpoints (tree edges and shortcuts, both
/// algorithms); a tolerance no chord of `edge_resolution / 8` can meet refuses every edge.
#[test]
fn integrity_3_every_chord_keeps_the_chord_tolerance() {
    let sagitta = |d: f64| 1.0 - (1.0 - d * d / 4.0).sqrt();
    for (algorithm, simplify) in [(Algorithm::Crrt, false), (Algorithm::Crrt, true), (Algorithm::RrtConnect, true)] {
        let chord = 5e-5;
        let settings = Settings { algorithm, simplify, ..Settings::default() };
        let planner = Planner::new(Arc::new(EuclideanSpace(3)), settings.clone()).unwrap();
        let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(2) };
        let (mut projector, mut checker, mut interrupt) = (ChordSphere { chord, calls: 0 }, Band, no_interrupt);
        let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
        let sol = planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c).unwrap();
        assert!(sol.success, "{algorithm:?}");
        assert!(sol.stats.chord_checks > 0);
        let path: Vec<&[f64]> = sol.path.chunks(3).collect();
        let mut longest: f64 = 0.0;
        for w in path.windows(2) {
            let d = EuclideanSpace(3).distance(w[0], w[1]);
            longest = longest.max(d);
            assert!(sagitta(d) <= chord, "{algorithm:?}: a chord {d} long strays {} from the sphere", sagitta(d));
            assert!(d <= genplan_core::planning::MAX_SPACING * settings.edge_resolution + 1e-12);
        }
        // the states were split: no chord as long as the resolution is left
        assert!(longest < 0.0201, "{algorithm:?}: {longest}");
    }
    // the control: the same plan without the chord check has chords that stray beyond it
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings::default()).unwrap();
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(2) };
    let (mut projector, mut checker, mut interrupt) = (SphereProjector { radius: 1.0 }, Band, no_interrupt);
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    let sol = planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c).unwrap();
    let path: Vec<&[f64]> = sol.path.chunks(3).collect();
    assert!(sol.success && sol.stats.chord_checks == 0);
    assert!(path.windows(2).any(|w| sagitta(EuclideanSpace(3).distance(w[0], w[1])) > 5e-5));
    // chords of edge_resolution / 8 stray 1.2e-6: a tolerance of 1e-7 refuses every edge
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings { max_extensions: 20, retries: 0, ..Settings::default() }).unwrap();
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(2) };
    let (mut projector, mut checker, mut interrupt) = (ChordSphere { chord: 1e-7, calls: 0 }, Band, no_interrupt);
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    let sol = planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c).unwrap();
    assert!(!sol.success && sol.stats.pruned > 0);
}

/// A square wall in the plane, |x| < 0.1 and |y| < 0.6, blocks the straight line between the
/// free-space test's start and goal.
struct Wall;

impl Wall {
    fn ok(q: &[f64]) -> bool {
        !(q[0].abs() < 0.1 && q[1].abs() < 0.6)
    }
}

impl ValidityChecker for Wall {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        for (q, v) in qs.chunks(2).zip(valid.iter_mut()) {
            *v = Wall::ok(q);
        }
        Ok(())
    }
}

/// The identity projector (the plane is its own manifold), counting the rows it is given.
#[derive(Default)]
struct CountingIdentity(usize);

impl Projector for CountingIdentity {
    fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        self.0 += reports.len();
        out.copy_from_slice(qs);
        reports.fill(Projection { success: true, iterations: 0 });
        Ok(())
    }
}

/// Free space (no projector): the planner goes round the wall without projecting anything (no
/// projection counted, no time in the projector, no chord checked), every state valid and the
/// states of the dense path at most the edge spacing apart; and it grows the same trees, hence the
/// same waypoints, as with a projector that leaves every configuration where it is (which is
/// called, and costs its time, on every sample, step and edge state). Simplified, the two differ:
/// free space has its own simplifier (`free_space_simplification_finds_the_short_way_round`), the
/// manifold keeps the projected shortcuts; both compare their search unsimplified.
#[test]
fn free_space_plans_project_nothing_and_match_the_identity_projector() {
    for (algorithm, simplify, lazy_edges) in [(Algorithm::Crrt, false, true), (Algorithm::Crrt, true, false), (Algorithm::RrtConnect, true, true)] {
        let settings = Settings { algorithm, simplify, lazy_edges, ..Settings::default() };
        let planner = Planner::new(Arc::new(EuclideanSpace(2)), settings.clone()).unwrap();
        let (start, goal) = ([-0.8, 0.0], [0.8, 0.0]);
        let plan = |projector: Option<&mut dyn Projector>| {
            let mut sampler = CubeSampler { dim: 2, half: 1.0, rng: StdRng::seed_from_u64(4) };
            let (mut checker, mut interrupt) = (Wall, no_interrupt);
            let projector = projector.map(|p| -> &mut dyn Projector { p });
            let mut c = Components { sampler: &mut sampler, projector, checker: &mut checker, interrupt: &mut interrupt };
            planner.plan(&start, &goal, &mut c).unwrap()
        };
        let sol = plan(None);
        assert!(sol.success, "{algorithm:?}: {:?}", sol.stats);
        let s = &sol.stats;
        assert_eq!((s.projections, s.projection_calls, s.edge_projections, s.chord_checks, s.samples_rejected), (0, 0, 0, 0, 0), "{algorithm:?}");
        assert_eq!(s.projector_s, 0.0);
        let path: Vec<&[f64]> = sol.path.chunks(2).collect();
        assert_eq!((path[0], *path.last().unwrap()), (&start[..], &goal[..]));
        assert!(path.iter().all(|q| Wall::ok(q)), "{algorithm:?}: a state in the wall");
        // round the wall, not through it
        assert!(path.iter().any(|q| q[1].abs() >= 0.6 && q[0].abs() < 0.1));
        for w in path.windows(2) {
            assert!(EuclideanSpace(2).distance(w[0], w[1]) <= genplan_core::planning::MAX_SPACING * settings.edge_resolution + 1e-12);
        }
        if simplify {
            continue; // the search's equality is checked by the unsimplified cases
        }
        let mut identity = CountingIdentity::default();
        let same = plan(Some(&mut identity));
        assert!(identity.0 > 0);
        assert_eq!(same.waypoints, sol.waypoints, "{algorithm:?}");
        assert_eq!(same.path, sol.path, "{algorithm:?}");
        assert_eq!((same.stats.extensions, same.stats.nodes, same.stats.samples), (s.extensions, s.nodes, s.samples));
    }
}

/// [`Wall`] as a checker of 8 lanes: the free-space extension checks its steps 8 at a time.
struct WideWall(usize);

impl ValidityChecker for WideWall {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        self.0 += 1;
        Wall.check(qs, valid)
    }
    fn lanes(&self) -> usize {
        8
    }
}

/// In free space a vector checker gets an extension's steps in batches of its lanes, and the
/// search is the same as with a checker of one lane (the same trees, waypoints and path) in
/// fewer checker calls; a goal in plain view is joined by the straight edge without a search.
#[test]
fn free_space_extensions_fill_the_checker_lanes_and_a_clear_goal_is_joined_directly() {
    for algorithm in [Algorithm::Crrt, Algorithm::RrtConnect] {
        let settings = Settings { algorithm, ..Settings::default() };
        let planner = Planner::new(Arc::new(EuclideanSpace(2)), settings.clone()).unwrap();
        let plan = |checker: &mut dyn ValidityChecker, start: [f64; 2], goal: [f64; 2]| {
            let mut sampler = CubeSampler { dim: 2, half: 1.0, rng: StdRng::seed_from_u64(7) };
            let mut interrupt = no_interrupt;
            let mut c = Components { sampler: &mut sampler, projector: None, checker, interrupt: &mut interrupt };
            planner.plan(&start, &goal, &mut c).unwrap()
        };
        let (start, goal) = ([-0.8, 0.0], [0.8, 0.0]);
        let (mut wide, mut narrow) = (WideWall(0), CountingWall(0));
        let (a, b) = (plan(&mut wide, start, goal), plan(&mut narrow, start, goal));
        assert!(a.success && b.success, "{algorithm:?}");
        assert_eq!((&a.waypoints, &a.path), (&b.waypoints, &b.path), "{algorithm:?}");
        assert_eq!((a.stats.extensions, a.stats.nodes, a.stats.samples), (b.stats.extensions, b.stats.nodes, b.stats.samples));
        assert!(wide.0 < narrow.0, "{algorithm:?}: {} calls of 8 lanes against {} of one", wide.0, narrow.0);
        // the wall not in the way: the straight edge, no sample drawn, states at the resolution
        let (start, goal) = ([-0.8, 0.7], [0.8, 0.7]);
        let sol = plan(&mut WideWall(0), start, goal);
        assert!(sol.success && sol.stats.samples == 0 && sol.stats.extensions == 1, "{algorithm:?}: {:?}", sol.stats);
        assert_eq!(sol.waypoints, [start, goal].concat());
        let path: Vec<&[f64]> = sol.path.chunks(2).collect();
        assert!(path.iter().all(|q| (q[1] - 0.7).abs() < 1e-12));
        assert!(path.windows(2).all(|w| EuclideanSpace(2).distance(w[0], w[1]) <= settings.edge_resolution + 1e-12));
    }
}

/// [`Wall`], counting its calls.
struct CountingWall(usize);

impl ValidityChecker for CountingWall {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        self.0 += 1;
        Wall.check(qs, valid)
    }
}

/// Free-space simplification (reduce, partial shortcuts, smoothing) round the wall: from ten
/// seeds' trees, paths of median length within 6 % of the shortest way round (over the corners
/// (+-0.1, 0.6): 2 sqrt(0.7^2 + 0.6^2) + 0.2) and each within 20 %, every state valid,
/// consecutive states at most the edge spacing apart, never longer than the unsimplified path,
/// the time counted in `simplify_s`.
#[test]
fn free_space_simplification_finds_the_short_way_round() {
    let shortest = 2.0 * (0.7f64.powi(2) + 0.6f64.powi(2)).sqrt() + 0.2;
    let length = |p: &[f64]| p.chunks(2).collect::<Vec<_>>().windows(2).map(|w| EuclideanSpace(2).distance(w[0], w[1])).sum::<f64>();
    for algorithm in [Algorithm::Crrt, Algorithm::RrtConnect] {
        let mut ratios = Vec::new();
        for seed in 0..10 {
            let plan = |simplify: bool| {
                let settings = Settings { algorithm, simplify, ..Settings::default() };
                let planner = Planner::new(Arc::new(EuclideanSpace(2)), settings).unwrap();
                let mut sampler = CubeSampler { dim: 2, half: 1.0, rng: StdRng::seed_from_u64(seed) };
                let (mut checker, mut interrupt) = (Wall, no_interrupt);
                let mut c = Components { sampler: &mut sampler, projector: None, checker: &mut checker, interrupt: &mut interrupt };
                planner.plan(&[-0.8, 0.0], &[0.8, 0.0], &mut c).unwrap()
            };
            let (plain, sol) = (plan(false), plan(true));
            assert!(sol.success && plain.success, "{algorithm:?} seed {seed}");
            let (l, l0) = (length(&sol.path), length(&plain.path));
            assert!(l <= l0 + 1e-9, "{algorithm:?} seed {seed}: simplified {l} > unsimplified {l0}");
            assert!(l <= 1.2 * shortest, "{algorithm:?} seed {seed}: {l} against the shortest {shortest} (unsimplified {l0})");
            ratios.push(l / shortest);
            let path: Vec<&[f64]> = sol.path.chunks(2).collect();
            assert_eq!((path[0], *path.last().unwrap()), (&[-0.8, 0.0][..], &[0.8, 0.0][..]));
            assert!(path.iter().all(|q| Wall::ok(q)), "{algorithm:?} seed {seed}: a state in the wall");
            for w in path.windows(2) {
                assert!(EuclideanSpace(2).distance(w[0], w[1]) <= Settings::default().edge_resolution + 1e-12);
            }
            // the waypoints are states of the path
            for q in sol.waypoints.chunks(2) {
                assert!(path.contains(&q), "{algorithm:?} seed {seed}: waypoint {q:?} not on the path");
            }
            assert!(sol.stats.shortcuts > 0 && sol.stats.simplify_s > 0.0 && sol.stats.simplify_s <= sol.stats.time_s);
            assert_eq!(plain.stats.simplify_s, 0.0);
        }
        ratios.sort_by(f64::total_cmp);
        let median = (ratios[4] + ratios[5]) / 2.0;
        assert!(median <= 1.06, "{algorithm:?}: median length {median} x the shortest ({ratios:?})");
    }
}

/// The Panda in free space around a box (no projector, the native collision checker: joint
/// limits and collisions), with sampled and with certified edges: every state of the path within
/// the joint limits and collision-free, nothing projected.
#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn panda_plans_in_free_space_around_a_box() {
    use genplan_core::planning::EdgeCheck;
    let (model, mut world) = preset("panda").unwrap().load().unwrap();
    world
        .add_box("wall", [0.05, 0.3, 0.3], nalgebra::Isometry3::translation(0.45, 0.0, 0.35))
        .unwrap();
    let world = Arc::new(world);
    let mut checker = genplan_core::planning::CollisionChecker::new(world.clone(), false);
    // start and goal: valid random configurations, the hand on either side of the box
    let mut sampler = UniformSampler::new(model.clone(), None, 5).unwrap();
    let hand = model.link_index("panda_hand").unwrap();
    let mut pick = |want_y_positive: bool| -> Vec<f64> {
        let mut q = vec![0.0; 7];
        loop {
            sampler.sample(1, &mut q).unwrap();
            let mut poses = Vec::new();
            model.forward_kinematics(&q, &mut poses).unwrap();
            let p = poses[hand].translation.vector;
            let mut v = [false];
            checker.check(&q, &mut v).unwrap();
            if v[0] && (p.y > 0.0) == want_y_positive && p.y.abs() > 0.3 && p.x > 0.3 && p.z > 0.1 {
                return q.clone();
            }
        }
    };
    let (start, goal) = (pick(false), pick(true));
    for (algorithm, edge_check) in [(Algorithm::Crrt, EdgeCheck::Sampled), (Algorithm::RrtConnect, EdgeCheck::Sampled), (Algorithm::RrtConnect, EdgeCheck::Certified)] {
        let settings = Settings { algorithm, edge_check, simplify: true, ..Settings::default() };
        let planner = Planner::new(model.clone(), settings.clone()).unwrap();
        let mut uniform = UniformSampler::new(model.clone(), None, 9).unwrap();
        let mut interrupt = no_interrupt;
        let mut c = Components { sampler: &mut uniform, projector: None, checker: &mut checker, interrupt: &mut interrupt };
        let sol = planner.plan(&start, &goal, &mut c).unwrap();
        assert!(sol.success, "{algorithm:?} {edge_check:?}: {:?}", sol.stats);
        assert_eq!((sol.stats.projections, sol.stats.edge_projections, sol.stats.chord_checks), (0, 0, 0));
        assert_eq!(sol.stats.projector_s, 0.0);
        let path: Vec<&[f64]> = sol.path.chunks(7).collect();
        assert_eq!((path[0], *path.last().unwrap()), (&start[..], &goal[..]));
        for q in &path {
            for (i, x) in q.iter().enumerate() {
                assert!(model.lower[i] <= *x && *x <= model.upper[i], "{algorithm:?}: joint {i} at {x} outside its limits");
            }
            assert!(!world.in_collision(q).unwrap(), "{algorithm:?}: a state in collision");
        }
        for w in path.windows(2) {
            assert!(model.as_ref().distance(w[0], w[1]) <= genplan_core::planning::MAX_SPACING * settings.edge_resolution + 1e-9);
        }
    }
}

/// The band with its door shut: no path from the south pole to the north pole.
struct ShutBand;
impl ValidityChecker for ShutBand {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        for (q, v) in qs.chunks(3).zip(valid.iter_mut()) {
            *v = q[2].abs() >= 0.2;
        }
        Ok(())
    }
}

#[test]
fn a_search_out_of_its_time_limit_is_an_unsuccessful_plan() {
    for algorithm in [Algorithm::Crrt, Algorithm::RrtConnect] {
        let plan = |time_limit: f64, max_extensions: usize| {
            let settings = Settings { algorithm, time_limit, max_extensions, retries: 1_000, ..Settings::default() };
            pole_to_pole(settings, &mut ShutBand, 1)
        };
        // a budget of 10^9 iterations a try and 1,000 retries: only the clock ends the search
        let sol = plan(0.05, 1_000_000_000);
        assert!(!sol.success && sol.path.is_empty(), "{algorithm:?}");
        assert!(sol.stats.timed_out, "{algorithm:?}: {:?}", sol.stats);
        assert!(sol.stats.time_s >= 0.05, "{algorithm:?} stopped before its limit: {:?}", sol.stats);
        assert!(sol.stats.extensions < 1_000_000_000);
        // the tree the search had grown when the clock stopped it
        assert!(sol.stats.nodes > 1, "{algorithm:?}: {:?}", sol.stats);
        // without a limit, the budget ends it: not a time-out
        let sol = plan(0.0, 50);
        assert!(!sol.success && !sol.stats.timed_out, "{algorithm:?}: {:?}", sol.stats);
        assert_eq!(sol.stats.retries, 1_000);
    }
    // a path found within the limit is returned and simplified as without one
    let sol = pole_to_pole(Settings { time_limit: 60.0, simplify: true, ..Settings::default() }, &mut Band, 1);
    assert!(sol.success && !sol.stats.timed_out);
    let plain = sphere_plan(Algorithm::Crrt, NeighborIndex::Auto, true, true, 1);
    assert_eq!((&sol.path, &sol.waypoints, sol.stats.shortcuts), (&plain.path, &plain.waypoints, plain.stats.shortcuts));
}

#[test]
fn a_time_limit_is_zero_or_a_positive_finite_number_of_seconds() {
    for bad in [-1.0, f64::NAN, f64::INFINITY, 2e6] {
        let e = Settings { time_limit: bad, ..Settings::default() }.validate().unwrap_err();
        assert!(matches!(e, PlanError::Settings { field: "time_limit", .. }), "{bad}: {e}");
        assert!(e.to_string().contains("time_limit must be 0 (no limit) or in (0, 1e6] seconds"), "{e}");
    }
    for good in [0.0, 1e-9, 1e6] {
        Settings { time_limit: good, ..Settings::default() }.validate().unwrap();
    }
}

//! Criterion: the constrained RRT's parts and whole plans with native parts only.
//!
//! * nearest neighbour among 1k / 10k nodes in 7 and 34 dimensions: brute force vs kd-forest;
//! * one ConstrainedExtend and a whole plan on the sphere (OMPL's constrained-planning demo: a
//!   point of R^3 kept on the unit sphere, a band around the equator blocked but for a door);
//! * a whole Panda plan (gripper horizontal, native Gauss-Newton projector, parry collision,
//!   self-collision included) between two fixed configurations around a box, with the paper's
//!   cRRT and with RRT-Connect; needs example-robot-data (GENPLAN_ROBOTS_DIR or the project's
//!   .venv);
//! * the Panda's constrained space: one constrained step (0.3 rad, projected, checked) and the
//!   check of a 0.3 rad edge (11 projected, checked states at 0.025 rad), its states projected
//!   without the posture step (as the planner does) and with it (as before issue 17);
//! * the Talos paper projection (both soles fixed, centre of mass in its box, joint limits, the
//!   left arm held; posture in the null space, as python/genplan/presets/tasks/talos_projection.toml):
//!   one solve from a random configuration (the sampler's projection), and one from a
//!   configuration 0.02 rad off the manifold without the posture step (an edge state).

#[path = "../rust/core/tests/common/fixtures.rs"]
mod fixtures;

use std::hint::black_box;
use std::sync::Arc;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use fixtures::{no_interrupt, panda_horizontal_gripper, Band, CubeSampler, SphereProjector, WithPosture};
use genplan_core::planning::{
    Algorithm, CollisionChecker, Components, ConstrainedSpace, EuclideanSpace, GaussNewtonProjector, KdForest, LinearNearest, NearestNeighbors,
    Planner, Projector, Sampler, Settings, UniformSampler,
};
use genplan_core::robot::preset;
use rand::{rngs::StdRng, Rng, SeedableRng};

fn nearest(c: &mut Criterion) {
    let mut group = c.benchmark_group("nearest");
    for &dim in &[7usize, 34] {
        for &n in &[1_000usize, 10_000] {
            let mut rng = StdRng::seed_from_u64(1);
            let points: Vec<f64> = (0..n * dim).map(|_| rng.random_range(-3.0..3.0)).collect();
            let queries: Vec<Vec<f64>> = (0..256).map(|_| (0..dim).map(|_| rng.random_range(-3.0..3.0)).collect()).collect();
            let mut lin = LinearNearest::new(dim);
            let mut kd = KdForest::new(dim);
            for p in points.chunks(dim) {
                lin.add(p);
                kd.add(p);
            }
            let mut i = 0;
            group.bench_function(BenchmarkId::new(format!("linear/{dim}d"), n), |b| {
                b.iter(|| {
                    i = (i + 1) % queries.len();
                    black_box(lin.nearest(black_box(&queries[i])))
                })
            });
            group.bench_function(BenchmarkId::new(format!("kdforest/{dim}d"), n), |b| {
                b.iter(|| {
                    i = (i + 1) % queries.len();
                    black_box(kd.nearest(black_box(&queries[i])))
                })
            });
        }
    }
    group.finish();
}

fn sphere(c: &mut Criterion) {
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), Settings::default()).unwrap();
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(3) };
    let mut projector = SphereProjector { radius: 1.0 };
    let mut checker = Band;
    let mut interrupt = no_interrupt;
    let from = [0.0, -1.0, 0.0];
    let mut c_ = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    // a full extension: 10 steps of 0.3 rad along the equator's door side
    c.bench_function("constrained_extend/sphere_10_steps", |b| {
        b.iter(|| black_box(planner.extend(black_box(&from), &[0.0, 1.0, 0.05], false, &mut c_).unwrap()))
    });
    let mut seed = 0;
    c.bench_function("plan/sphere", |b| {
        b.iter(|| {
            seed += 1;
            let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(seed) };
            let mut c_ = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
            let sol = planner.plan(&[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], &mut c_).unwrap();
            assert!(sol.success);
            black_box(sol)
        })
    });
}

fn panda(c: &mut Criterion) {
    let (model, mut world) = preset("panda").unwrap().load().unwrap();
    world.add_box("wall", [0.05, 0.05, 0.3], nalgebra::Isometry3::translation(0.45, 0.0, 0.35)).unwrap();
    let world = Arc::new(world);
    let hand = model.link_index("panda_hand").unwrap();
    // states ten times tighter than the constraint, as the Python planner projects them
    let gn = Arc::new(panda_horizontal_gripper(model.clone(), 1e-5));
    // two valid configurations on either side of the wall
    let pick = |seed: u64, y_positive: bool| {
        let mut s = UniformSampler::new(model.clone(), None, seed).unwrap();
        let mut q = vec![0.0; 7];
        let mut poses = Vec::new();
        loop {
            s.sample(1, &mut q).unwrap();
            let o = gn.solve_unchecked(&q, None);
            model.forward_kinematics(&o.q, &mut poses).unwrap();
            let p = poses[hand].translation.vector;
            if o.success && !world.in_collision(&o.q).unwrap() && p.x > 0.3 && (p.y > 0.25) == y_positive && p.y.abs() > 0.25 {
                return o.q;
            }
        }
    };
    let (start, goal) = (pick(1, false), pick(2, true));
    for (name, algorithm) in [("plan/panda_around_a_box", Algorithm::Crrt), ("plan/panda_around_a_box_rrt_connect", Algorithm::RrtConnect)] {
        let planner = Planner::new(model.clone(), Settings { algorithm, ..Settings::default() }).unwrap();
        let mut seed = 0;
        c.bench_function(name, |b| {
            b.iter(|| {
                seed += 1;
                let mut sampler = UniformSampler::new(model.clone(), None, seed).unwrap();
                let mut projector = GaussNewtonProjector::new(gn.clone(), false);
                let mut checker = CollisionChecker::new(world.clone(), false);
                let mut interrupt = no_interrupt;
                let mut c_ = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
                let sol = planner.plan(&start, &goal, &mut c_).unwrap();
                black_box(sol)
            })
        });
    }
}

/// The Panda's constrained space (the shelf-free world of `panda` with its box): a step and an
/// edge check from a valid state on the manifold.
fn constrained_space(c: &mut Criterion) {
    let (model, mut world) = preset("panda").unwrap().load().unwrap();
    world.add_box("wall", [0.05, 0.05, 0.3], nalgebra::Isometry3::translation(0.45, 0.0, 0.35)).unwrap();
    let world = Arc::new(world);
    let gn = Arc::new(panda_horizontal_gripper(model.clone(), 1e-5));
    let settings = Settings::default();
    let mut checker = CollisionChecker::new(world.clone(), false);
    let mut projector = GaussNewtonProjector::new(gn.clone(), false);
    let mut with_posture = WithPosture(GaussNewtonProjector::new(gn.clone(), false));
    // a valid state on the manifold and a step of 0.3 rad from it towards a random target
    let mut sampler = UniformSampler::new(model.clone(), None, 4).unwrap();
    let (a, target, b) = {
        let mut space = ConstrainedSpace::new(model.as_ref(), Some(&mut projector), &mut checker, &settings);
        let mut q = vec![0.0; 7];
        loop {
            sampler.sample(1, &mut q).unwrap();
            let o = gn.solve_unchecked(&q, None);
            let mut ok = [false];
            space.check(&o.q, &mut ok).unwrap();
            if !(o.success && ok[0]) {
                continue;
            }
            sampler.sample(1, &mut q).unwrap();
            let t = q.clone();
            if let Some(step) = space.step(&o.q, &t, false).unwrap() {
                if space.geodesic(&o.q, &step.q, false).unwrap().is_some_and(|e| e.len() == 11 * 7) {
                    break (o.q, t, step.q);
                }
            }
        }
    };
    let mut space = ConstrainedSpace::new(model.as_ref(), Some(&mut projector), &mut checker, &settings);
    c.bench_function("constrained_space/panda_step", |bch| bch.iter(|| black_box(space.step(black_box(&a), &target, false).unwrap())));
    c.bench_function("constrained_space/panda_edge_check", |bch| bch.iter(|| black_box(space.geodesic(black_box(&a), &b, false).unwrap())));
    let mut space = ConstrainedSpace::new(model.as_ref(), Some(&mut with_posture as &mut dyn Projector), &mut checker, &settings);
    c.bench_function("constrained_space/panda_edge_check_with_posture", |bch| {
        bch.iter(|| black_box(space.geodesic(black_box(&a), &b, false).unwrap()))
    });
}

/// The Talos paper projection task (python/genplan/presets/tasks/talos_projection.toml) at the
/// SRDF's half-sitting state (the soles on the ground), and that state.
fn talos_projection() -> (Arc<genplan_core::kinematics::KinematicModel>, genplan_core::projection::Projector, Vec<f64>) {
    use genplan_core::projection::{Projector as Solver, Settings as SolverSettings, Term, TermKind};
    use nalgebra::Vector3;
    let desc = preset("talos").unwrap();
    let srdf = desc.read_srdf().unwrap().unwrap();
    let (model, _) = desc.load().unwrap();
    let state = &srdf.group_states["half_sitting"];
    let mut q = vec![0.0; model.nq];
    q[6] = 1.0;
    for j in &model.joints {
        if model.active_joints.contains(&j.name) && j.name != "root_joint" {
            if let Some(v) = state.get(&j.name) {
                q[j.q_index] = v[0];
            }
        }
    }
    let (left, right) = (model.link_index("left_sole_link").unwrap(), model.link_index("right_sole_link").unwrap());
    let mut poses = Vec::new();
    model.forward_kinematics(&q, &mut poses).unwrap();
    q[2] = -poses[left].translation.vector.z;
    model.forward_kinematics(&q, &mut poses).unwrap();
    let mut arm = vec![0.0; model.nv];
    for j in model.joints.iter().filter(|j| j.name.starts_with("arm_left_") && model.active_joints.contains(&j.name)) {
        arm[j.v_index] = 1.0;
    }
    let term = |name: &str, kind, tolerance| Term { name: name.into(), kind, weight: 20.0, tolerance };
    let primary = vec![
        term("left_sole", TermKind::FramePose { link: left, target: poses[left], mask: [1.0; 6] }, 1e-4),
        term("right_sole", TermKind::FramePose { link: right, target: poses[right], mask: [1.0; 6] }, 1e-4),
        term("com", TermKind::ComBox { lower: Vector3::new(-0.1, -0.1, 0.6), upper: Vector3::new(0.1, 0.1, 1.1), margin: 1e-3 }, 1e-3),
        term("joint_limits", TermKind::JointLimits { margin: 1e-3 }, 1e-3),
        Term { name: "left_arm".into(), kind: TermKind::Posture { q_nom: Some(q.clone()), weights: arm, overrides: vec![] }, weight: 10.0, tolerance: 1e-3 },
    ];
    let secondary = vec![Term {
        name: "posture".into(),
        kind: TermKind::Posture { q_nom: None, weights: vec![1.0; model.nv], overrides: vec![] },
        weight: 1.0,
        tolerance: 1e-3,
    }];
    let solver = Solver::new(model.clone(), primary, secondary, SolverSettings::default()).unwrap();
    (model, solver, q)
}

/// One Talos projection from a random configuration (joints uniform within their limits, the base
/// at half-sitting: the sampler's projection, with the posture step), and one of a state 0.02 rad
/// off the manifold without it (an edge state: `GaussNewtonProjector::project_edge`).
fn projection(c: &mut Criterion) {
    let (model, solver, q_default) = talos_projection();
    let mut rng = StdRng::seed_from_u64(7);
    let random: Vec<Vec<f64>> = (0..64)
        .map(|_| {
            let mut q = q_default.clone();
            for i in 7..model.nq {
                q[i] = rng.random_range(model.lower[i]..=model.upper[i]);
            }
            q
        })
        .collect();
    let on: Vec<Vec<f64>> = random.iter().map(|q| solver.solve_unchecked(q, None)).filter(|o| o.success).map(|o| o.q).collect();
    assert!(on.len() >= 48, "only {} of 64 random configurations projected", on.len());
    let near: Vec<Vec<f64>> = on
        .iter()
        .map(|q| {
            let mut q = q.clone();
            for i in 7..model.nq {
                q[i] = (q[i] + rng.random_range(-0.02..=0.02)).clamp(model.lower[i], model.upper[i]);
            }
            q
        })
        .collect();
    let mut primary_only = solver.clone();
    primary_only.secondary.clear();
    let mut k = 0;
    c.bench_function("projection/talos_random", |b| {
        b.iter(|| {
            k = (k + 1) % random.len();
            black_box(solver.solve_unchecked(black_box(&random[k]), None))
        })
    });
    c.bench_function("projection/talos_edge_state", |b| {
        b.iter(|| {
            k = (k + 1) % near.len();
            black_box(primary_only.solve_unchecked(black_box(&near[k]), None))
        })
    });
}

criterion_group!(benches, nearest, sphere, panda, constrained_space, projection);
criterion_main!(benches);

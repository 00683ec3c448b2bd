//! Criterion: the constrained RRT's parts and whole plans with native parts only.
//!
//! * nearest neighbour among 1k / 10k nodes in 7 and 34 dimensions: brute force vs kd-forest;
//! * one ConstrainedExtend and a whole plan on the sphere (OMPL's constrained-planning demo: a
//!   point of R^3 kept on the unit sphere, a band around the equator blocked but for a door);
//! * a whole Panda plan (gripper horizontal, native Gauss-Newton projector, parry collision,
//!   self-collision included) between two fixed configurations around a box; needs
//!   example-robot-data (GENPLAN_ROBOTS_DIR or the project's .venv).

#[path = "../rust/core/tests/common/fixtures.rs"]
mod fixtures;

use std::hint::black_box;
use std::sync::Arc;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use fixtures::{no_interrupt, panda_horizontal_gripper, Band, CubeSampler, SphereProjector};
use genplan_core::planning::{
    CollisionChecker, Components, EuclideanSpace, GaussNewtonProjector, KdForest, LinearNearest, NearestNeighbors, Planner, Sampler,
    Settings, UniformSampler,
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
    let mut c_ = Components { sampler: &mut sampler, projector: &mut projector, checker: &mut checker, interrupt: &mut interrupt };
    // a full extension: 10 steps of 0.3 rad along the equator's door side
    c.bench_function("constrained_extend/sphere_10_steps", |b| {
        b.iter(|| black_box(planner.extend(black_box(&from), &[0.0, 1.0, 0.05], false, &mut c_).unwrap()))
    });
    let mut seed = 0;
    c.bench_function("plan/sphere", |b| {
        b.iter(|| {
            seed += 1;
            let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(seed) };
            let mut c_ = Components { sampler: &mut sampler, projector: &mut projector, checker: &mut checker, interrupt: &mut interrupt };
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
    let planner = Planner::new(model.clone(), Settings::default()).unwrap();
    let mut seed = 0;
    c.bench_function("plan/panda_around_a_box", |b| {
        b.iter(|| {
            seed += 1;
            let mut sampler = UniformSampler::new(model.clone(), None, seed).unwrap();
            let mut projector = GaussNewtonProjector { inner: gn.clone(), parallel: false };
            let mut checker = CollisionChecker::new(world.clone(), false);
            let mut interrupt = no_interrupt;
            let mut c_ = Components { sampler: &mut sampler, projector: &mut projector, checker: &mut checker, interrupt: &mut interrupt };
            let sol = planner.plan(&start, &goal, &mut c_).unwrap();
            black_box(sol)
        })
    });
}

criterion_group!(benches, nearest, sphere, panda);
criterion_main!(benches);

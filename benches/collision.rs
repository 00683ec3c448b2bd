//! Criterion: one collision check (FK + self-collision + obstacles) for Panda and Talos.
//! `random`: cycling through uniform random configurations (early exit on the first hit);
//! `free`: a collision-free configuration, so every pair is looked at (the worst case).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use genplan_core::robot::preset;
use genplan_core::Scratch;
use nalgebra::Isometry3;

#[path = "kinematics.rs"]
#[allow(dead_code)]
mod kinematics_bench;
use kinematics_bench::random_configurations;

fn collision(c: &mut Criterion) {
    for name in ["panda", "talos"] {
        let (model, mut world) = preset(name).unwrap().load().unwrap();
        // a table in front of the robot, as in the paper's environments
        let table = if name == "panda" { (0.7, 0.0, -0.5) } else { (0.7, 0.0, 0.75) };
        world
            .add_box("table", [0.25, 0.4, 0.03], Isometry3::translation(table.0, table.1, table.2))
            .unwrap();
        let qs = random_configurations(&model, 1024, 2);
        let mut s = Scratch::default();
        let free: Vec<Vec<f64>> = qs.iter().filter(|q| !world.in_collision_unchecked(q, &mut s)).cloned().collect();
        assert!(!free.is_empty());
        let mut i = 0;
        c.bench_function(&format!("collision_check/{name}/random"), |b| {
            b.iter(|| {
                i = (i + 1) % qs.len();
                black_box(world.in_collision_unchecked(black_box(&qs[i]), &mut s))
            })
        });
        let mut j = 0;
        c.bench_function(&format!("collision_check/{name}/free"), |b| {
            b.iter(|| {
                j = (j + 1) % free.len();
                black_box(world.in_collision_unchecked(black_box(&free[j]), &mut s))
            })
        });
        c.bench_function(&format!("min_distance/{name}/free"), |b| {
            b.iter(|| {
                j = (j + 1) % free.len();
                black_box(world.min_distance_unchecked(black_box(&free[j]), &mut s))
            })
        });
    }
}

criterion_group!(benches, collision);
criterion_main!(benches);

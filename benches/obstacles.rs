//! Criterion: collision queries as the scene grows. The Panda in the GAN paper's shelf scene
//! (`python/genplan/presets/scenes/panda_shelf.toml`: a table, a bookshelf, the floor) with 0 and
//! with 200 extra random boxes placed out of the robot's reach ([`extra_boxes`]), and Talos
//! self-collision alone (no obstacles).
//! `random`: cycling through uniform random configurations (early exit on the first hit);
//! `free`: collision-free configurations of the scene without extra boxes (every pair is looked
//! at; the extra boxes never touch the robot, so these stay free with them).

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use genplan_core::robot::preset;
use genplan_core::{CollisionWorld, Scratch};
use nalgebra::{Isometry3, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

#[path = "kinematics.rs"]
#[allow(dead_code)]
mod kinematics_bench;
use kinematics_bench::random_configurations;

/// Add the boxes and half-spaces of a scene file (the subset of docs/SCENES.md the shipped
/// `panda_shelf.toml` uses: axis-aligned boxes with `half_extents` and `position`, and
/// `[[halfspace]]` with `normal` and `offset`).
pub fn add_scene_file(world: &mut CollisionWorld, path: &Path) {
    let text = std::fs::read_to_string(path).unwrap();
    let table: toml::Table = text.parse().unwrap();
    let vec3 = |v: &toml::Value| -> [f64; 3] {
        let a = v.as_array().unwrap();
        [0, 1, 2].map(|i| a[i].as_float().or_else(|| a[i].as_integer().map(|x| x as f64)).unwrap())
    };
    for b in table.get("box").and_then(|v| v.as_array()).into_iter().flatten() {
        assert!(b.get("rotation").is_none() && b.get("quaternion").is_none(), "rotated boxes are not read here");
        let p = vec3(&b["position"]);
        world
            .add_box(b["name"].as_str().unwrap(), vec3(&b["half_extents"]), Isometry3::translation(p[0], p[1], p[2]))
            .unwrap();
    }
    for h in table.get("halfspace").and_then(|v| v.as_array()).into_iter().flatten() {
        let off = h["offset"].as_float().unwrap();
        world.add_halfspace(h["name"].as_str().unwrap(), vec3(&h["normal"]), off).unwrap();
    }
}

/// `n` random boxes (seeded), none within the Panda's reach: centres 1.6 to 3 m from the base
/// horizontally, z in [-0.4, 1.6], half extents 0.03 to 0.15 m, random rotations.
/// (The Panda reaches about 1.2 m from its base; the shelf ends 1.0 m from it.)
pub fn extra_boxes(world: &mut CollisionWorld, n: usize, seed: u64) {
    let mut rng = StdRng::seed_from_u64(seed);
    for k in 0..n {
        let r = rng.random_range(1.6..3.0);
        let a = rng.random_range(0.0..std::f64::consts::TAU);
        let z = rng.random_range(-0.4..1.6);
        let h = [0, 1, 2].map(|_| rng.random_range(0.03..0.15));
        let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let pose = Isometry3::new(Vector3::new(r * a.cos(), r * a.sin(), z), axis * rng.random_range(0.0..1.0));
        world.add_box(&format!("extra_{k}"), h, pose).unwrap();
    }
}

fn obstacles(c: &mut Criterion) {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../python/genplan/presets/scenes/panda_shelf.toml");
    let (model, mut base) = preset("panda").unwrap().load().unwrap();
    add_scene_file(&mut base, &scene);
    let qs = random_configurations(&model, 1024, 2);
    let mut s = Scratch::default();
    let free: Vec<Vec<f64>> = qs.iter().filter(|q| !base.in_collision_unchecked(q, &mut s)).cloned().collect();
    assert!(free.len() > 50);
    for extra in [0, 200] {
        let mut world = base.clone();
        extra_boxes(&mut world, extra, 11);
        for q in &qs {
            assert_eq!(world.in_collision_unchecked(q, &mut s), base.in_collision_unchecked(q, &mut s));
        }
        let mut i = 0;
        c.bench_function(&format!("obstacles/panda_shelf+{extra}/collision_random"), |b| {
            b.iter(|| {
                i = (i + 1) % qs.len();
                black_box(world.in_collision_unchecked(black_box(&qs[i]), &mut s))
            })
        });
        let mut j = 0;
        c.bench_function(&format!("obstacles/panda_shelf+{extra}/collision_free"), |b| {
            b.iter(|| {
                j = (j + 1) % free.len();
                black_box(world.in_collision_unchecked(black_box(&free[j]), &mut s))
            })
        });
        c.bench_function(&format!("obstacles/panda_shelf+{extra}/min_distance_free"), |b| {
            b.iter(|| {
                j = (j + 1) % free.len();
                black_box(world.min_distance_unchecked(black_box(&free[j]), &mut s))
            })
        });
    }

    let (model, world) = preset("talos").unwrap().load().unwrap();
    let qs = random_configurations(&model, 1024, 2);
    let free: Vec<Vec<f64>> = qs.iter().filter(|q| !world.in_collision_unchecked(q, &mut s)).cloned().collect();
    assert!(!free.is_empty());
    let mut i = 0;
    c.bench_function("obstacles/talos_self/collision_random", |b| {
        b.iter(|| {
            i = (i + 1) % qs.len();
            black_box(world.in_collision_unchecked(black_box(&qs[i]), &mut s))
        })
    });
    let mut j = 0;
    c.bench_function("obstacles/talos_self/collision_free", |b| {
        b.iter(|| {
            j = (j + 1) % free.len();
            black_box(world.in_collision_unchecked(black_box(&free[j]), &mut s))
        })
    });
}

criterion_group!(benches, obstacles);
criterion_main!(benches);

//! Criterion: forward kinematics of every link, and of the joints above the hand only, Panda
//! (7 joints) and Talos (free-flyer + 28).
//! Needs example-robot-data: GENPLAN_ROBOTS_DIR or the project's .venv (scripts/setup).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use genplan_core::robot::preset;
use rand::{rngs::StdRng, Rng, SeedableRng};

/// Configurations uniform within the joint limits; a free-flyer base at 1 m, upright.
pub fn random_configurations(model: &genplan_core::KinematicModel, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let mut q: Vec<f64> = model
                .lower
                .iter()
                .zip(&model.upper)
                .map(|(&l, &u)| if l.is_finite() && u.is_finite() { rng.random_range(l..=u) } else { 0.0 })
                .collect();
            if model.floating_base {
                q[2] = 1.0;
                q[6] = 1.0;
            }
            q
        })
        .collect()
}

fn fk(c: &mut Criterion) {
    for (name, hand) in [("panda", "panda_hand"), ("talos", "gripper_right_base_link")] {
        let (model, _) = preset(name).unwrap().load().unwrap();
        let qs = random_configurations(&model, 1024, 1);
        let mut out = Vec::new();
        let mut i = 0;
        c.bench_function(&format!("fk_all_links/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % qs.len();
                model.forward_kinematics_unchecked(black_box(&qs[i]), &mut out);
                black_box(&out);
            })
        });
        // one link: the joints above it only (what `link_poses(q, [hand])` runs)
        let joints = model.joints_placing(&[model.link_index(hand).unwrap()]);
        c.bench_function(&format!("fk_hand/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % qs.len();
                model.forward_kinematics_prefix(black_box(&qs[i]), &mut out, joints);
                black_box(&out);
            })
        });
    }
}

criterion_group!(benches, fk);
criterion_main!(benches);

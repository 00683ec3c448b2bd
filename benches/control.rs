//! Criterion: the 1 kHz spatula controller (issue [controller]) on the UR5.
//!
//! * `control_tick/ur5`: one control period = measure + task-space P-D + DOB + torque through
//!   M and J, then the plant's RK4 step (4 forward dynamics of the true arm with friction and a
//!   payload error) and the pancake step. Target: median <= 10 us (100x faster than real time).
//! * the dynamics pieces it is made of, at random states of the UR5.
//!
//! Needs example-robot-data: GENPLAN_ROBOTS_DIR or the project's .venv (scripts/setup).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use genplan_core::control::{Disturbances, SimConfig, Simulation};
use genplan_core::dynamics::Dynamics;
use genplan_core::robot::preset;
use nalgebra::{DMatrix, Isometry3};
use rand::{rngs::StdRng, Rng, SeedableRng};

fn control(c: &mut Criterion) {
    let arm = Dynamics::from_description(&preset("ur5").unwrap()).unwrap();

    // a smooth periodic trajectory (1 s period) so that cycling through it never jumps
    let k = 1000;
    let traj: Vec<f64> = (0..k)
        .flat_map(|i| {
            let s = (2.0 * std::f64::consts::PI * i as f64 / k as f64).sin();
            [0.05 * s, 0.05 * s, 0.8 * s]
        })
        .collect();
    let mut config = SimConfig::new(6);
    config.disturbances = Disturbances::reference();
    let mut sim = Simulation::new(&arm, config).unwrap();
    let (cmds, q0) = sim.prepare(&traj).unwrap();
    sim.reset(&q0).unwrap();
    let mut i = 0;
    c.bench_function("control_tick/ur5", |b| {
        b.iter(|| {
            let out = sim.tick(black_box(&cmds[i])).unwrap();
            i = (i + 1) % cmds.len();
            black_box(out);
        })
    });

    let mut rng = StdRng::seed_from_u64(3);
    let states: Vec<(Vec<f64>, Vec<f64>)> = (0..256)
        .map(|_| {
            let q = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
            let v = (0..6).map(|_| rng.random_range(-2.0..2.0)).collect();
            (q, v)
        })
        .collect();
    let mut ws = arm.workspace();
    let frame = arm.frame("tool0", &Isometry3::identity()).unwrap();
    let (mut j, mut dj) = (DMatrix::zeros(6, 6), DMatrix::zeros(6, 6));
    let mut out = [0.0; 6];
    let tau = [1.0; 6];
    let mut n = 0;
    let mut next = || {
        n = (n + 1) % states.len();
        &states[n]
    };
    c.bench_function("dynamics/ur5/mass_matrix", |b| {
        b.iter(|| {
            let (q, _) = next();
            arm.update_kinematics_unchecked(black_box(q), None, &mut ws);
            arm.mass_matrix_from_kinematics(&mut ws);
            black_box(&ws.mass);
        })
    });
    c.bench_function("dynamics/ur5/nonlinear_effects", |b| {
        b.iter(|| {
            let (q, v) = next();
            arm.update_kinematics_unchecked(black_box(q), Some(v), &mut ws);
            arm.rnea_from_kinematics(None, true, &mut ws, &mut out);
            black_box(&out);
        })
    });
    c.bench_function("dynamics/ur5/pieces/kinematics_local", |b| {
        b.iter(|| {
            let (q, v) = next();
            arm.update_local_kinematics_unchecked(black_box(q), Some(v), &mut ws);
            black_box(&ws.v);
        })
    });
    c.bench_function("dynamics/ur5/pieces/rnea_after_kinematics", |b| {
        b.iter(|| {
            arm.rnea_from_kinematics(None, true, &mut ws, &mut out);
            black_box(&out);
        })
    });
    c.bench_function("dynamics/ur5/pieces/crba_after_kinematics", |b| {
        b.iter(|| {
            arm.mass_matrix_from_kinematics(&mut ws);
            black_box(&ws.mass);
        })
    });
    let m = ws.mass.clone();
    let mut l = DMatrix::zeros(6, 6);
    c.bench_function("dynamics/ur5/pieces/cholesky_solve", |b| {
        b.iter(|| {
            genplan_core::dynamics::cholesky_in_place(black_box(&m), &mut l).unwrap();
            let mut x = tau;
            genplan_core::dynamics::cholesky_solve(&l, &mut x);
            black_box(x);
        })
    });
    c.bench_function("dynamics/ur5/forward_dynamics", |b| {
        b.iter(|| {
            let (q, v) = next();
            arm.update_kinematics_unchecked(black_box(q), Some(v), &mut ws);
            arm.forward_dynamics_from_kinematics(&tau, &mut ws, &mut out).unwrap();
            black_box(&out);
        })
    });
    c.bench_function("dynamics/ur5/jacobian_and_time_variation", |b| {
        b.iter(|| {
            let (q, v) = next();
            arm.update_kinematics_unchecked(black_box(q), Some(v), &mut ws);
            arm.frame_jacobians_from_kinematics(&frame, &ws, &mut j, Some(&mut dj));
            black_box((&j, &dj));
        })
    });
}

criterion_group!(benches, control);
criterion_main!(benches);

//! Criterion: the 1 kHz loop (`genplan_core::control`).
//!
//! * `control_tick/ur5`: one control period of the seq2seq paper's spatula configuration =
//!   measure + task-space P-D + DOB + torque through M and J, then the plant's RK4 step (4
//!   forward dynamics of the true arm with friction and a payload error) and the pancake step.
//!   Target: median <= 6 us.
//! * `control_tick/panda_joint`, `control_tick/panda_task`: the same period on the 7-joint Panda
//!   (joint space; task space on the hand with the damped pseudo-inverse and the null-space
//!   posture term), with friction, offsets and a 0.6 kg unknown load. Target: <= 10 us.
//! * the dynamics pieces a tick is made of, at random states of the UR5.
//!
//! The `control_tick` group is measured twice: in wall time (`control_tick/*`) and, on Linux, in
//! the thread's CPU time (`control_tick_cpu/*`: `CLOCK_THREAD_CPUTIME_ID`), which a machine
//! shared with other jobs does not inflate by the time the thread waits for a core.
//!
//! Needs example-robot-data: GENPLAN_ROBOTS_DIR or the project's .venv (scripts/setup).

use std::hint::black_box;

use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use criterion::{criterion_group, criterion_main, Criterion};
use genplan_core::control::{
    reference_disturbances, ControlSpace, ControllerSettings, Disturbances, Payload, Reference, SimConfig, Simulation, Spatula,
    SpatulaConfig,
};
use genplan_core::dynamics::Dynamics;
use genplan_core::robot::preset;
use nalgebra::{DMatrix, Isometry3};
use rand::{rngs::StdRng, Rng, SeedableRng};

/// One tick of the spatula configuration and of the Panda in joint and task space, as `group/*`.
fn ticks<M: Measurement + 'static>(c: &mut Criterion<M>, group: &str) {
    let arm = Dynamics::from_description(&preset("ur5").unwrap()).unwrap();

    // a smooth periodic trajectory (1 s period) so that cycling through it never jumps
    let k = 1000;
    let traj: Vec<f64> = (0..k)
        .flat_map(|i| {
            let s = (2.0 * std::f64::consts::PI * i as f64 / k as f64).sin();
            [0.05 * s, 0.05 * s, 0.8 * s]
        })
        .collect();
    let config = SpatulaConfig { disturbances: reference_disturbances(), ..Default::default() };
    let mut spatula = Spatula::new(&arm, config).unwrap();
    let (reference, q0) = spatula.prepare(&traj).unwrap();
    spatula.sim.reset(&q0).unwrap();
    let mut i = 0;
    c.bench_function(&format!("{group}/ur5"), |b| {
        b.iter(|| {
            let out = spatula.sim.tick(black_box(&reference.task[i]), None).unwrap();
            i = (i + 1) % reference.len();
            black_box(out);
        })
    });

    // the Panda: a periodic joint motion about a posture away from the limits
    let panda = Dynamics::from_description(&preset("panda").unwrap()).unwrap();
    let center = [0.0, -0.3, 0.0, -2.0, 0.0, 1.9, 0.8];
    let (mut q, mut qd, mut qdd) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..k {
        let w = 2.0 * std::f64::consts::PI;
        let t = i as f64 / k as f64;
        for (j, c0) in center.iter().enumerate() {
            let a = 0.2 / (1.0 + j as f64 * 0.3);
            q.push(c0 + a * (w * t).sin());
            qd.push(a * w * (w * t).cos());
            qdd.push(-a * w * w * (w * t).sin());
        }
    }
    for (name, space) in [("panda_joint", ControlSpace::Joint), ("panda_task", ControlSpace::Task)] {
        let controller = ControllerSettings { space, frame: Some("panda_hand".into()), ..Default::default() };
        let disturbances = Disturbances {
            coulomb: vec![1.0; 7],
            viscous: vec![0.5; 7],
            offset: vec![0.5; 7],
            payload: Some(Payload::point(0.6, [0.0, 0.0, 0.1])),
            ..Default::default()
        };
        let mut sim = Simulation::new(&panda, SimConfig { controller, disturbances, ..Default::default() }).unwrap();
        let (reference, _) =
            Reference::from_joints(&panda, &sim.controller.frame, &sim.limits, q.clone(), qd.clone(), qdd.clone(), 1e-3).unwrap();
        sim.reset(&q[..7]).unwrap();
        let mut i = 0;
        c.bench_function(&format!("{group}/{name}"), |b| {
            b.iter(|| {
                let out = sim.tick(black_box(&reference.task[i]), reference.joint_command(i)).unwrap();
                i = (i + 1) % reference.len();
                black_box(out);
            })
        });
    }
}

/// The calling thread's CPU time (ns): `clock_gettime(CLOCK_THREAD_CPUTIME_ID)`.
#[cfg(target_os = "linux")]
fn thread_cpu_ns() -> u64 {
    #[repr(C)]
    struct Timespec {
        sec: i64,
        nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clock: i32, ts: *mut Timespec) -> i32;
    }
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut ts = Timespec { sec: 0, nsec: 0 };
    // SAFETY: clock_gettime writes one timespec through a valid pointer
    let rc = unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID) failed");
    ts.sec as u64 * 1_000_000_000 + ts.nsec as u64
}

/// Criterion's measurement of the thread's CPU time (ns), formatted as durations.
#[cfg(target_os = "linux")]
struct ThreadCpu;

#[cfg(target_os = "linux")]
impl Measurement for ThreadCpu {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, start: u64) -> u64 {
        thread_cpu_ns() - start
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        WallTime.formatter()
    }
}

fn control(c: &mut Criterion) {
    ticks(c, "control_tick");
    let arm = Dynamics::from_description(&preset("ur5").unwrap()).unwrap();
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
    c.bench_function("dynamics/ur5/aba", |b| {
        b.iter(|| {
            let (q, v) = next();
            arm.update_kinematics_unchecked(black_box(q), Some(v), &mut ws);
            arm.aba_from_kinematics(&tau, &mut ws, &mut out).unwrap();
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

#[cfg(target_os = "linux")]
fn control_cpu(c: &mut Criterion<ThreadCpu>) {
    ticks(c, "control_tick_cpu");
}

#[cfg(target_os = "linux")]
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ThreadCpu);
    targets = control_cpu
}
criterion_group!(benches, control);
#[cfg(target_os = "linux")]
criterion_main!(benches, cpu);
#[cfg(not(target_os = "linux"))]
criterion_main!(benches);

//! The 1 kHz loop: conventions (phi, attitude), the pancake's stick/slip against closed forms and
//! the paper's cone criterion, the controllers' linear algebra, and on the robots (need
//! example-robot-data: ignored by a bare `cargo test`): the spatula configuration on the UR5
//! (reachability, input errors, the plant integrator's accuracy, disturbance rejection by the
//! DOB, singularity damping, slip verdicts, paced mode, joint limits, settings errors naming the
//! field), and the general loop on the Panda (joint and task space, a redundant arm's null
//! space, free axes, payloads known and unknown, limit policies, reference checks), the Kinova
//! (continuous joints on their circle), and no allocation per tick.

use std::alloc::{GlobalAlloc, Layout, System};
use std::f64::consts::{FRAC_PI_2, PI};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use genplan_core::control::{
    attitude_matrix, phi, reference_disturbances, wrap_angle, ControlSpace, ControllerSettings, Disturbances, JointLimits, LimitKind,
    LimitPolicy, Pancake, PancakeMode, PancakeSettings, Payload, PlanarMotion, Reference, ReferenceError, SimConfig, Simulation,
    Spatula, SpatulaConfig, TaskCommand,
};
use genplan_core::dynamics::Dynamics;
use genplan_core::robot::preset;
use genplan_core::Error;
use nalgebra::Vector3;
use rand::{rngs::StdRng, Rng, SeedableRng};

/// Counts the allocations a thread makes while its `COUNTING` is set (this test binary's
/// allocator): per thread, so that tests running at the same time do not count.
struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

fn count_allocation() {
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_allocation();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_allocation();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const G: f64 = 9.81;

#[test]
fn phi_sign_convention() {
    // level at rest: 0; tilted by theta at rest: -theta (as genplan.pancake.trajectories.phi); wrapped to (-pi, pi]
    assert!(phi(0.0, 0.0, 0.0, 9.8).abs() < 1e-15);
    for th in [-2.5, -0.7, 0.3, 1.2, 3.0] {
        assert!((phi(th, 0.0, 0.0, 9.8) + th).abs() < 1e-12, "{th}");
    }
    // accelerating the level spatula towards +y tilts the resultant g - a towards -y: phi < 0
    let p = phi(0.0, 9.8, 0.0, 9.8);
    assert!((p + PI / 4.0).abs() < 1e-12, "{p}");
    // tilting the spatula into that resultant brings phi back to 0
    assert!(phi(-PI / 4.0, 9.8, 0.0, 9.8).abs() < 1e-12);
    assert!((wrap_angle(PI) - PI).abs() < 1e-15 && (wrap_angle(-PI) - PI).abs() < 1e-15);
    assert!((wrap_angle(3.0 * PI + 0.1) - (-PI + 0.1)).abs() < 1e-12);
}

#[test]
fn attitude_convention_tilts_the_blade_about_world_x() {
    for th in [-PI, -2.0, -0.5, 0.0, 0.7, 2.5] {
        let r = attitude_matrix(th, FRAC_PI_2, 0.0);
        // handle (z) along world +x, blade direction (y) and normal (-x) in the y-z plane
        assert!((r.column(2) - Vector3::x()).norm() < 1e-12);
        assert!((r.column(1) - Vector3::new(0.0, th.cos(), th.sin())).norm() < 1e-12);
        assert!((-r.column(0) - Vector3::new(0.0, -th.sin(), th.cos())).norm() < 1e-12);
    }
    // intrinsic X-Y'-Z'': R = Rx(a) Ry(b) Rz(c)
    let (a, b, c) = (0.3, -0.4, 1.1);
    let r = attitude_matrix(a, b, c);
    let expect = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), a)
        * nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), b)
        * nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), c);
    assert!((r - expect.into_inner()).amax() < 1e-15);
}

fn still(theta: f64) -> PlanarMotion {
    PlanarMotion { theta, w: 0.0, dw: 0.0, a_y: 0.0, a_z: 0.0 }
}

#[test]
fn pancake_sticks_on_gentle_tilts_and_slides_on_steep_ones() {
    let g = [0.0, -G];
    let mut p = Pancake::new(PancakeSettings::default());
    p.step(&still(0.0), g, 1e-3);
    assert_eq!(p.mode, PancakeMode::Stuck);
    assert!((p.normal - G).abs() < 1e-12);
    let mut p = Pancake::new(PancakeSettings::default());
    for _ in 0..1000 {
        p.step(&still(0.7), g, 1e-3); // 40 deg < 45 deg = atan(1)
    }
    assert_eq!(p.mode, PancakeMode::Stuck);
    assert_eq!(p.s, 0.0);
    // 60 deg with mu = 0.5: slides down the blade (towards -s) with g (sin - mu cos)
    let cfg = PancakeSettings { mu_static: 0.5, mu_kinetic: 0.5, blade_half_length: 1.0 };
    let mut p = Pancake::new(cfg);
    let (th, dt, n) = (PI / 3.0, 1e-5, 10_000);
    for _ in 0..n {
        p.step(&still(th), g, dt);
    }
    let a = -G * (th.sin() - 0.5 * th.cos());
    let t = n as f64 * dt;
    assert_eq!(p.mode, PancakeMode::Sliding);
    assert!((p.ds - a * t).abs() < 1e-9, "{} vs {}", p.ds, a * t);
    // semi-implicit Euler: s_n = a dt^2 n (n + 1) / 2, within 1/n of a t^2 / 2
    let discrete = a * dt * dt * (n * (n + 1)) as f64 / 2.0;
    assert!((p.s - discrete).abs() < 1e-12, "{} vs {discrete}", p.s);
    assert!((p.s - 0.5 * a * t * t).abs() < 1.5 / n as f64 * (0.5 * a * t * t).abs());
}

#[test]
fn pancake_lifts_off_when_the_spatula_falls_faster_than_gravity_and_falls_past_the_blade() {
    let g = [0.0, -G];
    let mut p = Pancake::new(PancakeSettings::default());
    p.step(&PlanarMotion { theta: 0.0, w: 0.0, dw: 0.0, a_y: 0.0, a_z: -1.5 * G }, g, 1e-3);
    assert_eq!(p.mode, PancakeMode::Off);
    // a level spatula jerked sideways: the pancake slides and, pulled long enough, falls off
    let mut p = Pancake::new(PancakeSettings::default());
    let mut n = 0;
    while p.mode != PancakeMode::Off && n < 10_000 {
        p.step(&PlanarMotion { theta: 0.0, w: 0.0, dw: 0.0, a_y: 2.0 * G, a_z: 0.0 }, g, 1e-3);
        n += 1;
    }
    assert_eq!(p.mode, PancakeMode::Off);
    assert!(p.s < -0.06 + 1e-3, "slid back along -y: s = {}", p.s);
    // sliding is decelerated by friction and sticks again once the spatula stops pulling
    let mut p = Pancake::new(PancakeSettings::default());
    for _ in 0..20 {
        p.step(&PlanarMotion { theta: 0.0, w: 0.0, dw: 0.0, a_y: 1.5 * G, a_z: 0.0 }, g, 1e-3);
    }
    assert_eq!(p.mode, PancakeMode::Sliding);
    for _ in 0..200 {
        p.step(&still(0.0), g, 1e-3);
    }
    assert_eq!(p.mode, PancakeMode::Stuck);
    assert_eq!(p.ds, 0.0);
}

#[test]
fn at_the_spatula_point_the_pancake_sticks_exactly_inside_the_papers_cone() {
    // at s = 0, ds = 0 the stick test is |phi| <= atan(mu) (eq. 15) whenever the normal force
    // is positive, for any tilt, acceleration and rotation rate
    let mut rng = StdRng::seed_from_u64(11);
    for mu in [0.5, 1.0, 2.0] {
        let cfg = PancakeSettings { mu_static: mu, mu_kinetic: mu, blade_half_length: 1.0 };
        for _ in 0..2000 {
            let m = PlanarMotion {
                theta: rng.random_range(-PI..PI),
                w: rng.random_range(-8.0..8.0),
                dw: rng.random_range(-50.0..50.0),
                a_y: rng.random_range(-30.0..30.0),
                a_z: rng.random_range(-30.0..30.0),
            };
            let mut p = Pancake::new(cfg);
            p.step(&m, [0.0, -G], 1e-3);
            let ph = phi(m.theta, m.a_y, m.a_z, G);
            let inside = ph.abs() < mu.atan() - 1e-9;
            let outside = ph.abs() > mu.atan() + 1e-9;
            if inside {
                assert_eq!(p.mode, PancakeMode::Stuck, "phi {ph}");
            } else if outside {
                assert_ne!(p.mode, PancakeMode::Stuck, "phi {ph}");
            }
        }
    }
}

#[test]
fn settings_errors_name_the_field_before_any_robot() {
    let cases: Vec<(Box<dyn Fn() -> genplan_core::Result<()>>, &str)> = vec![
        (Box::new(|| ControllerSettings { dt: 0.0, ..Default::default() }.validate()), "controller.dt"),
        (Box::new(|| ControllerSettings { dt: f64::NAN, ..Default::default() }.validate()), "controller.dt"),
        (Box::new(|| ControllerSettings { dob_cutoff_hz: 0.0, ..Default::default() }.validate()), "controller.dob_cutoff_hz"),
        (Box::new(|| ControllerSettings { kv: [1.0, 1.0, 1.0, 1.0, 1.0, -1.0], ..Default::default() }.validate()), "controller.kv"),
        (Box::new(|| ControllerSettings { axes: [1.0, 1.0, 1.0, 0.5, 1.0, 1.0], ..Default::default() }.validate()), "controller.axes"),
        (Box::new(|| ControllerSettings { axes: [0.0; 6], ..Default::default() }.validate()), "controller.axes"),
        (Box::new(|| ControllerSettings { joint_kp: vec![], ..Default::default() }.validate()), "controller.joint_kp"),
        (Box::new(|| ControllerSettings { frame_offset: [0.0, 0.0, 2.0], ..Default::default() }.validate()), "controller.frame_offset"),
        (Box::new(|| Disturbances { coulomb: vec![-1.0], ..Default::default() }.validate()), "disturbances.coulomb"),
        (Box::new(|| Disturbances { friction_velocity: 0.0, ..Default::default() }.validate()), "disturbances.friction_velocity"),
        (Box::new(|| Payload { mass: -1.0, ..Default::default() }.validate()), "payload.mass"),
        (Box::new(|| Payload { mass: 150.0, ..Default::default() }.validate()), "payload.mass"),
        (Box::new(|| Payload { com: [2.0, 0.0, 0.0], ..Default::default() }.validate()), "payload.com"),
        (Box::new(|| Payload { inertia: [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], ..Default::default() }.validate()), "payload.inertia"),
        (Box::new(|| Payload { inertia: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], ..Default::default() }.validate()), "payload.inertia"),
        (Box::new(|| JointLimits { velocity: Some(vec![f64::NAN]), ..Default::default() }.validate()), "limits.velocity"),
        (Box::new(|| PancakeSettings { blade_half_length: f64::INFINITY, ..Default::default() }.validate()), "pancake.blade_half_length"),
    ];
    for (check, field) in cases {
        match check() {
            Err(Error::Settings { field: f, msg }) => assert_eq!(f, field, "{msg}"),
            Err(e) => panic!("{field}: {e}"),
            Ok(()) => panic!("{field}: accepted"),
        }
    }
    assert!(ControllerSettings::default().validate().is_ok() && ControllerSettings::paper().validate().is_ok());
    assert!(!ControllerSettings::paper().acceleration_feedforward && ControllerSettings::default().acceleration_feedforward);
}

// ------------------------------------------------------------------------------------- UR5

fn ur5() -> Dynamics {
    Dynamics::from_description(&preset("ur5").unwrap()).unwrap()
}

fn spatula(config: SpatulaConfig) -> Spatula {
    Spatula::new(&ur5(), config).unwrap()
}

/// Cycloidal S-curve rows from a to b over k samples.
fn s_curve(a: [f64; 3], b: [f64; 3], k: usize) -> Vec<f64> {
    (0..k)
        .flat_map(|i| {
            let t = i as f64 / (k - 1) as f64;
            let s = t - (2.0 * PI * t).sin() / (2.0 * PI);
            (0..3).map(move |c| a[c] + s * (b[c] - a[c]))
        })
        .collect()
}

/// The pancake's mode per tick of a spatula run.
fn modes(r: &genplan_core::control::SpatulaRun) -> Vec<f64> {
    r.run.log.payload.chunks(5).map(|c| c[4]).collect()
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_papers_task_region_is_reachable_away_from_singularities() {
    // y, z in [-0.15, 0.15] (the paper: +-0.1), theta over [-pi, pi], from the start pose
    let mut s = spatula(SpatulaConfig::default());
    let (reference, q0) = s.prepare(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
    assert_eq!(reference.len(), 2);
    let mut min_det = f64::INFINITY;
    for y in [-0.15, 0.0, 0.15] {
        for z in [-0.15, 0.0, 0.15] {
            let mut rows = Vec::new();
            for i in 0..=20 {
                let t = i as f64 / 20.0;
                rows.push([y * t, z * t, 0.0]);
            }
            for i in 0..=100 {
                rows.push([y, z, -PI * i as f64 / 100.0]);
            }
            for i in 0..=200 {
                rows.push([y, z, -PI + 2.0 * PI * i as f64 / 200.0]);
            }
            let qs = s.track_ik(&rows, &q0).unwrap();
            for q in &qs {
                min_det = min_det.min(s.jacobian_det(q).unwrap());
                let (p, r) = s.spatula_pose(q).unwrap();
                assert!(p.iter().all(|x| x.is_finite()) && (r.determinant() - 1.0).abs() < 1e-9);
            }
        }
    }
    let singular = SpatulaConfig::default().controller.singular_det;
    assert!(min_det > 20.0 * singular, "min |det J| = {min_det}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn bad_trajectories_are_refused_before_the_loop() {
    let mut s = spatula(SpatulaConfig::default());
    let e = s.run(&[0.0, 0.0, 0.0, 0.0, 0.0], None, false).unwrap_err().to_string();
    assert!(e.contains("rows [y, z, theta]"), "{e}");
    let mut traj = s_curve([0.0; 3], [0.05, 0.0, -0.3], 50);
    traj[3 * 17 + 2] = f64::NAN;
    let e = s.run(&traj, None, false).unwrap_err().to_string();
    assert!(e.contains("trajectory row 17 (column 2)") && e.contains("NaN"), "{e}");
    let traj = s_curve([0.0; 3], [1.0, 0.0, 0.0], 100); // 1 m sideways: out of reach
    let e = s.run(&traj, None, false).unwrap_err().to_string();
    assert!(e.contains("not reachable") && e.contains("trajectory row"), "{e}");
    assert_eq!(s.sim.ticks, 0, "nothing ran");
    let e = s.run(&s_curve([0.0; 3], [0.0; 3], 10), Some(11), false).unwrap_err().to_string();
    assert!(e.contains("motion_len"), "{e}");
    // bad settings are refused by Spatula::new, naming the field
    let mut c = SpatulaConfig::default();
    c.disturbances.coulomb = vec![1.0; 5];
    assert!(Spatula::new(&ur5(), c).err().unwrap().to_string().contains("disturbances.coulomb"));
    let mut c = SpatulaConfig::default();
    c.substeps = 0;
    match Spatula::new(&ur5(), c) {
        Err(Error::Settings { field, .. }) => assert_eq!(field, "substeps"),
        _ => panic!("substeps 0 accepted"),
    }
    let panda = Dynamics::from_description(&preset("panda").unwrap()).unwrap();
    assert!(Spatula::new(&panda, SpatulaConfig::default()).err().unwrap().to_string().contains("6-joint"));
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_plant_integrator_is_fourth_order_and_conserves_energy() {
    // the plant alone, no torque, no friction: the arm falls from the start pose
    let final_state = |substeps: usize, periods: usize| {
        let mut s = spatula(SpatulaConfig { substeps, ..Default::default() });
        let (_, q0) = s.prepare(&[0.0; 6]).unwrap();
        s.sim.reset(&q0).unwrap();
        let plant = &mut s.sim.plant;
        let energy = |q: &[f64], v: &[f64], model: &Dynamics| {
            let mut ws = model.workspace();
            model.update_kinematics_unchecked(q, Some(v), &mut ws);
            model.kinetic_energy_from_kinematics(&ws) + model.potential_energy_from_kinematics(&ws)
        };
        let e0 = energy(&plant.q, &plant.v, plant.model());
        let mut qdd = [0.0; 6];
        for k in 0..periods {
            plant.step(&[0.0; 6], 1e-3, k as u64, None, &mut qdd).unwrap();
        }
        let de = energy(&plant.q, &plant.v, plant.model()) - e0;
        (plant.q.clone(), plant.v.clone(), de)
    };
    let (q_ref, _, _) = final_state(8, 200);
    let err = |n: usize| {
        let (q, _, _) = final_state(n, 200);
        q.iter().zip(&q_ref).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
    };
    let (e1, e2) = (err(1), err(2));
    assert!(e1 < 1e-6, "1 ms RK4 error {e1}");
    assert!(e1 / e2 > 10.0, "order: error ratio {} (4th order: 16)", e1 / e2);
    let (_, v, de) = final_state(1, 500);
    let speed = v.iter().map(|x| x.abs()).fold(0.0, f64::max);
    assert!(speed > 1.0, "the arm did move ({speed} rad/s)");
    assert!(de.abs() < 1e-5, "energy drift over 0.5 s: {de} J");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn holding_still_is_exact_and_the_dob_rejects_a_constant_offset() {
    let hold = vec![0.02, -0.03, 0.4, 0.02, -0.03, 0.4];
    let offset = [2.0, -3.0, 1.5, 0.5, -0.5, 0.3];
    let run = |dob: bool, scale: f64| {
        let mut c = SpatulaConfig { settle_ticks: 1000, ..Default::default() };
        c.controller.dob = dob;
        c.disturbances.offset = offset.iter().map(|o| o * scale).collect();
        spatula(c).run(&hold, None, false).unwrap().run
    };
    let r = run(true, 0.0);
    assert!(r.summary.max_error_position < 1e-9 && r.summary.max_error_rotation < 1e-9, "{:?}", r.summary);
    assert!(r.log.tau_dis_hat.iter().all(|x| x.abs() < 1e-6));
    let with = run(true, 1.0);
    let without = run(false, 1.0);
    // without the DOB the offset leaves a steady error; with it the error vanishes
    assert!(without.summary.max_error_position > 1e-3, "{:?}", without.summary);
    assert!(with.summary.max_error_position < 1e-2 * without.summary.max_error_position, "{:?}", with.summary);
    // and the estimate converges to minus the offset (tau - M qdd - h = -offset)
    let last = &with.log.tau_dis_hat[with.log.tau_dis_hat.len() - 6..];
    for i in 0..6 {
        assert!((last[i] + offset[i]).abs() < 1e-3, "{last:?}");
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_dob_improves_tracking_under_the_reference_disturbances() {
    let traj = s_curve([0.0; 3], [0.05, 0.03, -0.5], 500);
    let run = |dob: bool| {
        let mut c = SpatulaConfig { settle_ticks: 500, disturbances: reference_disturbances(), ..Default::default() };
        c.controller.dob = dob;
        spatula(c).run(&traj, None, false).unwrap().run.summary
    };
    let (with, without) = (run(true), run(false));
    assert!(without.max_error_position > 1.5 * with.max_error_position, "{with:?} {without:?}");
    assert!(without.max_error_rotation > 1.5 * with.max_error_rotation, "{with:?} {without:?}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn slip_verdicts_gentle_versus_too_fast() {
    let run = |traj: &[f64]| {
        let c = SpatulaConfig { settle_ticks: 200, disturbances: reference_disturbances(), ..Default::default() };
        spatula(c).run(traj, None, false).unwrap()
    };
    let gentle = run(&s_curve([0.0; 3], [0.06, 0.02, -0.4], 500));
    assert!(!gentle.pancake.slipped && gentle.pancake.max_abs_phi < 0.7, "{:?}", gentle.pancake);
    assert!(modes(&gentle).iter().all(|&m| m == 0.0));
    // the same move in 0.12 s: peak accelerations near 2 pi 0.06 / 0.12^2 = 26 m/s^2
    let fast = run(&s_curve([0.0; 3], [0.06, 0.02, -0.4], 120));
    assert!(fast.pancake.slipped && fast.pancake.max_abs_phi > PI / 4.0, "{:?}", fast.pancake);
    let t = fast.pancake.first_slip_time.unwrap();
    assert!(t >= 0.2, "slips during the motion, not the settle phase: {t}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn a_singular_jacobian_is_damped_and_reported() {
    // wrist 2 at 0: the UR5's wrist singularity (wrist 1 and wrist 3 axes parallel)
    let mut s = spatula(SpatulaConfig::default());
    let q_sing = [0.1, -1.5, 1.6, -0.2, 0.0, 0.3];
    assert!(s.jacobian_det(&q_sing).unwrap() < 1e-12);
    s.sim.reset(&q_sing).unwrap();
    let (p, r) = s.spatula_pose(&q_sing).unwrap();
    let cmd = TaskCommand::hold(p + Vector3::new(0.0, 0.01, 0.0), r);
    let mut damped = 0;
    for _ in 0..500 {
        let out = s.sim.tick(&cmd, None).unwrap();
        damped += out.damped as usize;
        assert!(s.sim.tau.iter().all(|x| x.is_finite()));
    }
    assert!(damped > 0);
    let q = s.sim.plant.q.clone();
    let (p_end, _) = s.spatula_pose(&q).unwrap();
    assert!((p_end - cmd.pos).norm() < 0.01, "still converges towards the command");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn paced_mode_ticks_on_the_wall_clock() {
    let mut s = spatula(SpatulaConfig::default());
    let traj = s_curve([0.0; 3], [0.01, 0.0, -0.1], 60);
    let t0 = std::time::Instant::now();
    let r = s.run(&traj, None, true).unwrap().run;
    assert!(t0.elapsed().as_secs_f64() >= 0.059);
    assert_eq!(r.log.lateness.len(), 60);
    assert_eq!(r.log.compute.len(), 60);
    assert!(r.log.lateness.iter().all(|&x| x >= 0.0));
    // the same run unpaced gives the same trajectory (pacing does not change the physics)
    let r2 = spatula(SpatulaConfig::default()).run(&traj, None, false).unwrap().run;
    assert_eq!(r.log.q, r2.log.q);
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn runs_are_checked_against_the_urdf_joint_limits() {
    let arm = ur5();
    assert_eq!(arm.effort_limit, vec![150.0, 150.0, 150.0, 28.0, 28.0, 28.0]);
    assert_eq!(arm.velocity_limit, vec![3.15, 3.15, 3.15, 3.2, 3.2, 3.2]);
    // a gentle move stays within them
    let mut s = spatula(SpatulaConfig::default());
    let r = s.run(&s_curve([0.0; 3], [0.06, 0.02, -0.4], 500), None, false).unwrap().run;
    assert!(r.limit_violation.is_none() && r.summary.limit_ticks == 0);
    assert!(r.summary.max_abs_v.iter().zip(&arm.velocity_limit).all(|(v, l)| v < l));
    // a 30 cm jump of the command after 0.2 s: tens of thousands of N m at the jump
    let mut jump = vec![0.0; 3 * 400];
    for k in 200..400 {
        jump[3 * k] = 0.3;
    }
    let r = s.run(&jump, None, false).unwrap().run;
    let v = r.limit_violation.expect("a violation");
    assert_eq!((v.tick, v.kind, v.unit), (200, LimitKind::Torque, "N m"));
    assert!((v.time - 0.2).abs() < 1e-12 && v.value.abs() > 1e4 && v.limit == 150.0);
    assert!(r.summary.limit_ticks > 1 && r.log.n == 400 && !r.summary.stopped_at_limit);
    assert!(r.summary.max_torque_ratio > 60.0 && r.summary.saturated_ticks == 0, "logged, not clipped");
    let msg = v.describe(&arm.joint_names);
    assert!(msg.starts_with("joint 'shoulder_pan_joint' exceeds its torque limit at t = 0.200 s: |torque| = "), "{msg}");
    assert!(msg.ends_with(" N m > 150 N m"), "{msg}");
    // stop_at_limit: the run ends with the violating tick
    let r = s.run_with(&jump, None, false, true, &mut || false).unwrap().run;
    assert!(r.summary.stopped_at_limit && r.log.n == 201 && r.log.t.len() == 201 && r.summary.ticks == 201);
    assert_eq!(r.limit_violation, Some(v));
    // limits of one's own: unchecked joints (inf) and a speed limit
    let mut c = SpatulaConfig::default();
    c.limits = JointLimits { torque: Some(vec![f64::INFINITY; 6]), velocity: Some(vec![0.5; 6]), policy: LimitPolicy::Log };
    let r = spatula(c).run(&jump, None, false).unwrap().run;
    let v = r.limit_violation.unwrap();
    assert_eq!((v.kind, v.unit, v.limit), (LimitKind::Velocity, "rad/s", 0.5));
    assert!(v.tick > 200);
    // saturate: the torque is clipped to the rated limits (and the demand still logged)
    let c = SpatulaConfig { limits: JointLimits { policy: LimitPolicy::Saturate, ..Default::default() }, ..Default::default() };
    let r = spatula(c).run(&jump, None, false).unwrap().run;
    assert!(r.summary.saturated_ticks > 0 && r.summary.max_torque_ratio > 1.0);
    assert!(r.summary.max_abs_tau.iter().zip(&arm.effort_limit).all(|(t, l)| t <= l), "{:?}", r.summary.max_abs_tau);
    let clipped = r.log.saturated.iter().filter(|&&s| s).count();
    assert_eq!(clipped, r.summary.saturated_ticks);
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn a_tick_allocates_nothing() {
    for (robot, space) in [("ur5", ControlSpace::Task), ("panda", ControlSpace::Task), ("panda", ControlSpace::Joint), ("kinova", ControlSpace::Task)] {
        let arm = Dynamics::from_description(&preset(robot).unwrap()).unwrap();
        let frame = arm.link_names.last().unwrap().clone();
        let controller = ControllerSettings { space, frame: Some(frame), ..Default::default() };
        // a configuration within the range: 0, or the range's middle for a joint whose range excludes 0
        let mut q0 = arm.neutral();
        for b in arm.bodies.iter().filter(|b| b.kind != genplan_core::dynamics::JointKind::Continuous) {
            let (lo, hi) = (arm.lower[b.q_index], arm.upper[b.q_index]);
            if !(lo..=hi).contains(&0.0) {
                q0[b.q_index] = 0.5 * (lo + hi);
            }
        }
        let disturbances = Disturbances {
            coulomb: vec![0.5; arm.nv],
            offset: vec![0.1; arm.nv],
            payload: Some(Payload::point(0.5, [0.0; 3])),
            ..Default::default()
        };
        let mut sim = Simulation::new(&arm, SimConfig { controller, disturbances, ..Default::default() }).unwrap();
        let (reference, _) = Reference::from_joints(&arm, &sim.controller.frame, &sim.limits, q0.clone(), vec![0.0; arm.nv], vec![0.0; arm.nv], 1e-3).unwrap();
        sim.reset(&q0).unwrap();
        let cmd = reference.task[0];
        let joint = reference.joint_command(0);
        sim.tick(&cmd, joint).unwrap(); // first tick: nothing left to allocate lazily
        ALLOCATIONS.store(0, Ordering::SeqCst);
        COUNTING.set(true);
        for _ in 0..100 {
            sim.tick(&cmd, joint).unwrap();
        }
        COUNTING.set(false);
        assert_eq!(ALLOCATIONS.load(Ordering::SeqCst), 0, "{robot} {space:?}: allocations in 100 ticks");
    }
}

// ------------------------------------------------------------------- the general loop: Panda

fn panda() -> Dynamics {
    Dynamics::from_description(&preset("panda").unwrap()).unwrap()
}

/// A smooth joint motion of `seconds` between two configurations (quintic, at rest at both
/// ends), sampled every `dt`: (q, qd, qdd) row-major.
fn quintic(a: &[f64], b: &[f64], seconds: f64, dt: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = (seconds / dt).round() as usize + 1;
    let (mut q, mut qd, mut qdd) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..n {
        let s = (k as f64 * dt / seconds).min(1.0);
        let (p, dp, ddp) = (
            10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5),
            (30.0 * s.powi(2) - 60.0 * s.powi(3) + 30.0 * s.powi(4)) / seconds,
            (60.0 * s - 180.0 * s.powi(2) + 120.0 * s.powi(3)) / (seconds * seconds),
        );
        for i in 0..a.len() {
            q.push(a[i] + p * (b[i] - a[i]));
            qd.push(dp * (b[i] - a[i]));
            qdd.push(ddp * (b[i] - a[i]));
        }
    }
    (q, qd, qdd)
}

const PANDA_A: [f64; 7] = [0.0, -0.4, 0.0, -2.2, 0.0, 1.9, 0.8];
const PANDA_B: [f64; 7] = [0.6, 0.1, -0.3, -1.7, 0.2, 2.1, 0.4];

fn panda_run(controller: ControllerSettings, disturbances: Disturbances, payloads: Vec<Payload>, limits: JointLimits) -> genplan_core::control::Run {
    let arm = panda();
    let mut sim = Simulation::new(&arm, SimConfig { controller, disturbances, payloads, limits, substeps: 1 }).unwrap();
    let (q, qd, qdd) = quintic(&PANDA_A, &PANDA_B, 1.0, 1e-3);
    let (reference, _) = Reference::from_joints(&sim.controller.nominal, &sim.controller.frame, &sim.limits, q, qd, qdd, 1e-3).unwrap();
    sim.run_with(&reference, &PANDA_A, 500, None, false, false, &mut || false).unwrap()
}

fn hand(space: ControlSpace) -> ControllerSettings {
    ControllerSettings { space, frame: Some("panda_hand".into()), ..Default::default() }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_panda_follows_a_joint_trajectory_in_joint_and_task_space() {
    for space in [ControlSpace::Joint, ControlSpace::Task] {
        let r = panda_run(hand(space), Disturbances::default(), vec![], JointLimits::default());
        let s = &r.summary;
        // the nominal model is the plant: with the feed-forward, what is left is the zero-order hold
        // of the torque over a tick (the reference's acceleration changes within it)
        assert!(s.max_error_position < 5e-5 && s.max_error_rotation < 1e-4, "{space:?} {s:?}");
        assert!(s.max_error_joint < 1e-3, "{space:?} {s:?}");
        assert!(r.limit_violation.is_none() && s.saturated_ticks == 0);
        // nothing to estimate: exactly nothing at rest; in motion, what the discretisation leaves
        assert!(r.log.tau_dis_hat[..500 * 7].iter().all(|x| x.abs() < 1e-9), "no disturbance at rest");
        let largest = s.max_abs_tau.iter().copied().fold(0.0, f64::max);
        assert!(r.log.tau_dis_hat.iter().all(|x| x.abs() < 1e-2 * largest), "no disturbance in motion");
        assert_eq!(r.log.n, 1001 + 500);
        // the joint errors are logged (q_ref (-) q)
        assert_eq!(r.log.err_joint.len(), r.log.n * 7);
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn an_unknown_payload_is_estimated_by_the_dob_and_a_known_one_is_compensated() {
    let load = Payload::point(0.6, [0.0, 0.0, 0.1]);
    let unknown = Disturbances { payload: Some(load.clone()), ..Default::default() };
    let with = panda_run(hand(ControlSpace::Task), unknown.clone(), vec![], JointLimits::default());
    let without = panda_run(ControllerSettings { dob: false, ..hand(ControlSpace::Task) }, unknown, vec![], JointLimits::default());
    assert!(without.summary.max_error_position > 3.0 * with.summary.max_error_position, "{:?} vs {:?}", with.summary, without.summary);
    // the estimate at the end of the settle phase is the load's gravity torque (to 1 %: after 0.5
    // s the 2 Hz filter has 0.2 % left of its initial error)
    let arm = panda();
    let mut loaded = arm.clone();
    let frame = arm.frame("panda_hand", &nalgebra::Isometry3::identity()).unwrap();
    loaded.add_inertia(&frame, 0.6, Vector3::new(0.0, 0.0, 0.1), nalgebra::Matrix3::zeros()).unwrap();
    let (mut ws, mut ws2, mut g0, mut g1) = (arm.workspace(), loaded.workspace(), vec![0.0; 7], vec![0.0; 7]);
    arm.gravity_torque(&PANDA_A, &mut ws, &mut g0).unwrap();
    loaded.gravity_torque(&PANDA_A, &mut ws2, &mut g1).unwrap();
    let est = &with.log.tau_dis_hat[499 * 7..500 * 7];
    for i in 0..7 {
        let expect = g1[i] - g0[i];
        assert!((est[i] - expect).abs() < 1e-2 * (0.1 + expect.abs()), "joint {i}: {} vs {expect}", est[i]);
    }
    // known to the controller (a payload of the model): nothing left to estimate
    let known = panda_run(hand(ControlSpace::Task), Disturbances::default(), vec![load], JointLimits::default());
    assert!(known.summary.max_error_position < 5e-5, "{:?}", known.summary);
    assert!(known.log.tau_dis_hat[..500 * 7].iter().all(|x| x.abs() < 1e-9));
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn a_redundant_arm_keeps_its_reference_posture_in_the_null_space_and_free_axes_stay_free() {
    // a disturbance on the elbow only moves the arm in its null space and along the task; the
    // posture term pulls the joints back to the reference
    let offset = vec![0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0];
    let d = Disturbances { offset: offset.clone(), ..Default::default() };
    let no_posture = ControllerSettings { dob: false, posture_kp: 0.0, posture_kv: 5.0, ..hand(ControlSpace::Task) };
    let posture = ControllerSettings { dob: false, ..hand(ControlSpace::Task) };
    let a = panda_run(no_posture, d.clone(), vec![], JointLimits::default());
    let b = panda_run(posture, d, vec![], JointLimits::default());
    assert!(b.summary.max_error_joint < 0.5 * a.summary.max_error_joint, "{} vs {}", b.summary.max_error_joint, a.summary.max_error_joint);
    // yaw free about world z: the hand's error in the free axis is not corrected
    let free_yaw = ControllerSettings { axes: [1.0, 1.0, 1.0, 1.0, 1.0, 0.0], ..hand(ControlSpace::Task) };
    let r = panda_run(free_yaw, Disturbances::default(), vec![], JointLimits::default());
    assert!(r.summary.max_error_position < 1e-5, "{:?}", r.summary);
    assert!(r.summary.min_abs_det_j > 0.0 && r.summary.damped_ticks == 0);
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn limit_policies_saturate_log_or_stop() {
    // a 3 kg unknown load and weak limits: the demand exceeds them
    let d = Disturbances { payload: Some(Payload::point(3.0, [0.0; 3])), ..Default::default() };
    let torque = vec![30.0; 7];
    let run = |policy| panda_run(hand(ControlSpace::Task), d.clone(), vec![], JointLimits { torque: Some(torque.clone()), velocity: None, policy });
    let sat = run(LimitPolicy::Saturate);
    assert!(sat.summary.saturated_ticks > 0 && sat.summary.max_abs_tau.iter().all(|&t| t <= 30.0));
    let log = run(LimitPolicy::Log);
    assert!(log.summary.saturated_ticks == 0 && log.summary.max_abs_tau.iter().any(|&t| t > 30.0));
    assert!(log.limit_violation.is_some() && !log.summary.stopped_at_limit);
    let stop = run(LimitPolicy::Stop);
    assert!(stop.summary.stopped_at_limit && stop.log.n == stop.limit_violation.unwrap().tick + 1);
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn a_joint_reference_is_checked_before_the_run() {
    let arm = panda();
    let sim = Simulation::new(&arm, SimConfig { controller: hand(ControlSpace::Joint), ..Default::default() }).unwrap();
    let (f, l) = (&sim.controller.frame, &sim.limits);
    let (q, qd, qdd) = quintic(&PANDA_A, &PANDA_B, 1.0, 1e-3);
    let expect = |r: Result<_, ReferenceError>, what: &str| match r {
        Err(e) => assert!(e.to_string().contains(what), "{e}"),
        Ok(_) => panic!("accepted: {what}"),
    };
    // another robot's joint count
    expect(Reference::from_joints(&arm, f, l, vec![0.0; 12], vec![0.0; 14], vec![0.0; 14], 1e-3), "trajectory.q: expected rows of 7");
    // NaN
    let mut bad = q.clone();
    bad[7 * 3 + 2] = f64::NAN;
    match Reference::from_joints(&arm, f, l, bad, qd.clone(), qdd.clone(), 1e-3) {
        Err(ReferenceError::Input(Error::NonFinite { what, .. })) => assert_eq!(what, "trajectory.q row 3 (column 2)"),
        r => panic!("{:?}", r.err()),
    }
    // a jump: joint 1 moves 0.1 rad in one tick
    let mut jump = q.clone();
    for k in 500..jump.len() / 7 {
        jump[7 * k] += 0.1;
    }
    match Reference::from_joints(&arm, f, l, jump, qd.clone(), qdd.clone(), 1e-3) {
        Err(ReferenceError::Trajectory(m)) => assert!(m.contains("sample 500") && m.contains("panda_joint1") && m.contains("cannot follow"), "{m}"),
        r => panic!("{:?}", r.err()),
    }
    // outside the range, and over the velocity limits
    let mut out = q.clone();
    out[3] = -3.5;
    expect(Reference::from_joints(&arm, f, l, out, qd.clone(), qdd.clone(), 1e-3), "outside its range");
    let mut fast = qd.clone();
    fast[7 * 10 + 6] = 10.0;
    expect(Reference::from_joints(&arm, f, l, q.clone(), fast, qdd.clone(), 1e-3), "over its velocity limit");
    // a fine one: its torques within the limits, its frame commands the hand's poses
    let (r, check) = Reference::from_joints(&arm, f, l, q.clone(), qd, qdd, 1e-3).unwrap();
    assert!(check.torque_over.is_none() && check.max_torque_ratio > 0.0 && check.max_torque_ratio < 1.0);
    assert_eq!(r.len(), 1001);
    // an unknown frame is refused naming the link
    let e = Simulation::new(&arm, SimConfig { controller: ControllerSettings { frame: Some("flange".into()), ..Default::default() }, ..Default::default() });
    assert!(e.err().unwrap().to_string().contains("unknown link 'flange'"));
    let e = Simulation::new(&arm, SimConfig::default()).err().unwrap();
    assert!(e.to_string().contains("controller.frame"), "{e}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_plant_is_rk4_on_crba_and_cholesky_to_rounding() {
    // the plant's stages (the articulated-body algorithm on kinematics rotated by angle
    // addition, the friction's tanh in one exp) against a textbook RK4 step of
    // `Dynamics::forward_dynamics` (CRBA + RNEA + Cholesky) at the integrated configurations,
    // with the library's tanh: the same step up to rounding
    let arm = panda();
    let coulomb = [1.5, 1.5, 1.5, 1.5, 0.3, 0.3, 0.3];
    let (viscous, offset, fv) = ([1.0; 7], [0.8, -0.8, 0.6, -0.6, 0.15, -0.15, 0.1], 0.02);
    let disturbances = Disturbances {
        payload: Some(Payload::point(0.6, [0.0, 0.0, 0.1])),
        coulomb: coulomb.to_vec(),
        viscous: viscous.to_vec(),
        offset: offset.to_vec(),
        friction_velocity: fv,
    };
    let controller = hand(ControlSpace::Task);
    let mut sim = Simulation::new(&arm, SimConfig { controller, disturbances, ..Default::default() }).unwrap();
    let model = sim.plant.model().clone();
    let mut ws = model.workspace();
    let accel = |q: &[f64], v: &[f64], tau: &[f64], ws: &mut genplan_core::dynamics::DynWorkspace| {
        let t: Vec<f64> = (0..7).map(|i| tau[i] + offset[i] - coulomb[i] * (v[i] / fv).tanh() - viscous[i] * v[i]).collect();
        let mut a = vec![0.0; 7];
        model.forward_dynamics(q, v, &t, ws, &mut a).unwrap();
        a
    };
    let mut rng = StdRng::seed_from_u64(9);
    let mut worst = 0.0_f64;
    for k in 0..50 {
        let q: Vec<f64> = [0.0, -0.3, 0.0, -2.0, 0.0, 1.9, 0.8].iter().map(|c| c + rng.random_range(-0.5..0.5)).collect();
        // speeds from near rest (the friction's steep part) to fast
        let scale = [1e-4, 0.05, 1.5][k % 3];
        let v: Vec<f64> = (0..7).map(|_| scale * rng.random_range(-1.0..1.0)).collect();
        let tau: Vec<f64> = (0..7).map(|_| rng.random_range(-10.0..10.0)).collect();
        let h = 1e-3;
        let add = |a: &[f64], b: &[f64], f: f64| a.iter().zip(b).map(|(x, y)| x + f * y).collect::<Vec<f64>>();
        let k1 = accel(&q, &v, &tau, &mut ws);
        let v2 = add(&v, &k1, h / 2.0);
        let k2 = accel(&add(&q, &v, h / 2.0), &v2, &tau, &mut ws);
        let v3 = add(&v, &k2, h / 2.0);
        let k3 = accel(&add(&q, &v2, h / 2.0), &v3, &tau, &mut ws);
        let v4 = add(&v, &k3, h);
        let k4 = accel(&add(&q, &v3, h), &v4, &tau, &mut ws);
        let q_want: Vec<f64> = (0..7).map(|i| q[i] + h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i])).collect();
        let v_want: Vec<f64> = (0..7).map(|i| v[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])).collect();
        sim.plant.reset(&q).unwrap();
        sim.plant.v.copy_from_slice(&v);
        let mut qdd = vec![0.0; 7];
        sim.plant.step(&tau, h, k as u64, None, &mut qdd).unwrap();
        let kscale = 1.0 + k1.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        for i in 0..7 {
            worst = worst.max((sim.plant.q[i] - q_want[i]).abs());
            worst = worst.max((sim.plant.v[i] - v_want[i]).abs() / (1.0 + v_want[i].abs()));
            worst = worst.max((qdd[i] - k1[i]).abs() / kscale);
        }
    }
    assert!(worst < 1e-12, "the plant's step differs from RK4 on CRBA + Cholesky by {worst:e}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_plant_steps_the_same_from_the_controllers_kinematics() {
    // the controller's nominal model lacks the plant's payload, not its joints: the plant's
    // first RK4 stage may take the kinematics the controller measured, and steps bit for bit
    // as from its own
    let arm = panda();
    let controller = hand(ControlSpace::Task);
    let disturbances = Disturbances { payload: Some(Payload::point(0.6, [0.0, 0.0, 0.1])), coulomb: vec![1.0; 7], ..Default::default() };
    let mut sim = Simulation::new(&arm, SimConfig { controller, disturbances, substeps: 2, ..Default::default() }).unwrap();
    assert!(sim.plant.shares_kinematics_with(&sim.controller.nominal));
    let mut rng = StdRng::seed_from_u64(8);
    for k in 0..20 {
        let q: Vec<f64> = [0.0, -0.3, 0.0, -2.0, 0.0, 1.9, 0.8].iter().map(|c| c + rng.random_range(-0.5..0.5)).collect();
        let v: Vec<f64> = (0..7).map(|_| rng.random_range(-1.5..1.5)).collect();
        let tau: Vec<f64> = (0..7).map(|_| rng.random_range(-10.0..10.0)).collect();
        let mut results = vec![];
        for shared in [false, true] {
            sim.plant.reset(&q).unwrap();
            sim.plant.v.copy_from_slice(&v);
            sim.controller.measure(&q, &v);
            let start = if shared { Some(sim.controller.workspace()) } else { None };
            let mut qdd = vec![0.0; 7];
            sim.plant.step(&tau, 1e-3, k, start, &mut qdd).unwrap();
            results.push((sim.plant.q.clone(), sim.plant.v.clone(), qdd));
        }
        assert_eq!(results[0], results[1], "state {k}");
    }
    // another robot's geometry is not shared
    assert!(!sim.plant.shares_kinematics_with(&ur5()));
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn a_payload_on_the_frames_body_steps_the_plant_from_the_controllers_dynamics_as_its_own() {
    // the plant is the nominal model plus an unknown payload on the controller frame's body (its
    // centre of mass off the frame, an inertia of its own): the first RK stage from the
    // controller's mass matrix and bias plus the payload's terms equals the plant's own
    // articulated-body algorithm up to rounding (a redundant arm, a square one, continuous joints)
    let inertia = [[0.004, 0.0005, 0.0], [0.0005, 0.003, 0.0002], [0.0, 0.0002, 0.002]];
    for (robot, frame, link) in [("panda", "panda_hand", Some("panda_link7")), ("ur10", "tool0", None), ("kinova", "j2s6s200_end_effector", None)] {
        let arm = Dynamics::from_description(&preset(robot).unwrap()).unwrap();
        let nv = arm.nv;
        let payload = Payload { link: link.map(str::to_string), mass: 0.8, com: [0.02, -0.03, 0.12], inertia };
        let disturbances = Disturbances { payload: Some(payload), coulomb: vec![1.0; nv], viscous: vec![0.5; nv], offset: vec![0.3; nv], ..Default::default() };
        let controller = ControllerSettings { space: ControlSpace::Task, frame: Some(frame.into()), frame_offset: [0.0, 0.0, 0.05], ..Default::default() };
        let mut sim = Simulation::new(&arm, SimConfig { controller, disturbances: disturbances.clone(), ..Default::default() }).unwrap();
        assert!(sim.first_stage_from_controller(), "{robot}");
        let mut own = genplan_core::control::Plant::new(sim.plant.model().clone(), &disturbances, 1).unwrap();
        let mut rng = StdRng::seed_from_u64(11);
        let mut worst: f64 = 0.0;
        for k in 0..50 {
            let dq: Vec<f64> = (0..nv).map(|_| rng.random_range(-1.0..1.0)).collect();
            let mut q = arm.neutral();
            arm.integrate_scaled(&arm.neutral(), &dq, 1.0, &mut q);
            let v: Vec<f64> = (0..nv).map(|_| rng.random_range(-1.5..1.5)).collect();
            sim.reset(&q).unwrap();
            sim.plant.v.copy_from_slice(&v);
            sim.controller.measure(&q, &v);
            let cmd = TaskCommand::hold(sim.controller.pos + Vector3::new(0.01, -0.02, 0.01), sim.controller.rot);
            sim.tick(&cmd, None).unwrap();
            own.reset(&q).unwrap();
            own.v.copy_from_slice(&v);
            let mut qdd = vec![0.0; nv];
            own.step(&sim.tau, 1e-3, k, None, &mut qdd).unwrap();
            for (a, b) in sim.plant.q.iter().chain(&sim.plant.v).zip(own.q.iter().chain(&own.v)) {
                worst = worst.max((a - b).abs() / (1.0 + b.abs()));
            }
        }
        println!("{robot}: largest difference of a step's state {worst:.1e}");
        assert!(worst < 1e-12, "{robot}: largest difference {worst:e}");
    }
    // a payload elsewhere, or none: the plant's own first stage
    let arm = panda();
    for payload in [Some(Payload { link: Some("panda_link5".into()), ..Payload::point(0.5, [0.0; 3]) }), None] {
        let disturbances = Disturbances { payload, ..Default::default() };
        let sim = Simulation::new(&arm, SimConfig { controller: hand(ControlSpace::Task), disturbances, ..Default::default() }).unwrap();
        assert!(!sim.first_stage_from_controller());
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_avx2_build_of_the_tick_equals_the_baseline_build_bit_for_bit() {
    // the tick compiled for AVX2 and FMA (chosen where the processor has them) and the baseline
    // build run the same arithmetic: Rust never fuses a multiply and an add on its own (no
    // floating-point contraction) nor reorders a sum, so wider registers change the
    // instructions, not the results
    let arm = panda();
    for space in [ControlSpace::Task, ControlSpace::Joint] {
        let disturbances = Disturbances { payload: Some(Payload::point(0.6, [0.0, 0.0, 0.1])), coulomb: vec![1.0; 7], viscous: vec![0.5; 7], ..Default::default() };
        let config = SimConfig { controller: hand(space), disturbances, ..Default::default() };
        let (q, qd, qdd) = quintic(&PANDA_A, &PANDA_B, 1.0, 1e-3);
        let mut runs = vec![];
        for avx2 in [false, true] {
            let mut sim = Simulation::new(&arm, config.clone()).unwrap();
            let used = sim.set_avx2(avx2);
            assert!(avx2 || !used, "the baseline build is always available");
            let (reference, _) =
                Reference::from_joints(&sim.controller.nominal, &sim.controller.frame, &sim.limits, q.clone(), qd.clone(), qdd.clone(), 1e-3).unwrap();
            runs.push(sim.run_with(&reference, &PANDA_A, 200, None, false, false, &mut || false).unwrap());
        }
        let (a, b) = (&runs[0].log, &runs[1].log);
        assert_eq!(a.n, 1201);
        for (name, x, y) in [("q", &a.q, &b.q), ("v", &a.v, &b.v), ("tau", &a.tau, &b.tau), ("tau_dis_hat", &a.tau_dis_hat, &b.tau_dis_hat), ("pos", &a.pos, &b.pos), ("acc", &a.acc, &b.acc)] {
            assert_eq!(x, y, "{space:?} space: {name}");
        }
        assert_eq!(runs[0].summary.max_error_position, runs[1].summary.max_error_position);
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn continuous_joints_are_integrated_on_their_circle() {
    let arm = Dynamics::from_description(&preset("kinova").unwrap()).unwrap();
    assert!(arm.nq > arm.nv, "the Kinova has continuous joints");
    // integrate and difference are inverse, and keep [cos, sin] on the circle
    let mut rng = StdRng::seed_from_u64(5);
    let mut q = arm.neutral();
    let v: Vec<f64> = (0..arm.nv).map(|_| rng.random_range(-3.0..3.0)).collect();
    let mut q1 = q.clone();
    arm.integrate_scaled(&q, &v, 0.7, &mut q1);
    let mut d = vec![0.0; arm.nv];
    arm.difference(&q, &q1, &mut d);
    for k in 0..arm.nv {
        assert!((d[k] - 0.7 * v[k]).abs() < 1e-12, "{k}: {} vs {}", d[k], 0.7 * v[k]);
    }
    // the plant falls under gravity for 0.5 s: energy conserved (RK4's error, which substeps
    // shrink as h^4), circles kept
    q[arm.bodies[1].q_index] = 0.3_f64.cos();
    q[arm.bodies[1].q_index + 1] = 0.3_f64.sin();
    let energy = |q: &[f64], v: &[f64]| {
        let mut ws = arm.workspace();
        arm.update_kinematics_unchecked(q, Some(v), &mut ws);
        arm.kinetic_energy_from_kinematics(&ws) + arm.potential_energy_from_kinematics(&ws)
    };
    let fall = |substeps: usize| {
        let controller = ControllerSettings { space: ControlSpace::Joint, frame: Some(arm.link_names.last().unwrap().clone()), ..Default::default() };
        let mut sim = Simulation::new(&arm, SimConfig { controller, substeps, ..Default::default() }).unwrap();
        sim.reset(&q).unwrap();
        let e0 = energy(&sim.plant.q, &sim.plant.v);
        let mut qdd = vec![0.0; arm.nv];
        for k in 0..500 {
            sim.plant.step(&vec![0.0; arm.nv], 1e-3, k, None, &mut qdd).unwrap();
        }
        let (q, v) = (sim.plant.q.clone(), sim.plant.v.clone());
        (energy(&q, &v) - e0, q, v)
    };
    let (drift1, _, _) = fall(1);
    let (drift4, q, v) = fall(4);
    assert!(v.iter().map(|x| x.abs()).fold(0.0, f64::max) > 0.5, "it moved");
    assert!(drift1.abs() < 1e-3 && drift4.abs() < 1e-6 && drift4.abs() < drift1.abs() / 50.0, "energy drift {drift1} (1 step), {drift4} (4)");
    for b in arm.bodies.iter().filter(|b| b.kind == genplan_core::dynamics::JointKind::Continuous) {
        assert!((q[b.q_index].hypot(q[b.q_index + 1]) - 1.0).abs() < 1e-12);
    }
}

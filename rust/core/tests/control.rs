//! The spatula controller: conventions (phi, attitude), the pancake's stick/slip against closed
//! forms and the paper's cone criterion, and on the UR5 (needs example-robot-data: ignored by a
//! bare `cargo test`): reachability of the task region, input errors, the plant integrator's
//! accuracy, disturbance rejection by the DOB, singularity damping, slip verdicts, paced mode,
//! joint limits (the URDF's, checked every tick) and configuration errors naming the field.

use std::f64::consts::{FRAC_PI_2, PI};

use genplan_core::control::{
    attitude_matrix, phi, wrap_angle, Disturbances, JointLimits, LimitKind, Pancake, PancakeConfig, PancakeMode,
    PlanarMotion, SimConfig, Simulation,
};
use genplan_core::Error;
use genplan_core::dynamics::Dynamics;
use genplan_core::robot::preset;
use nalgebra::Vector3;
use rand::{rngs::StdRng, Rng, SeedableRng};

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
    let mut p = Pancake::new(PancakeConfig::default());
    p.step(&still(0.0), g, 1e-3);
    assert_eq!(p.mode, PancakeMode::Stuck);
    assert!((p.normal - G).abs() < 1e-12);
    let mut p = Pancake::new(PancakeConfig::default());
    for _ in 0..1000 {
        p.step(&still(0.7), g, 1e-3); // 40 deg < 45 deg = atan(1)
    }
    assert_eq!(p.mode, PancakeMode::Stuck);
    assert_eq!(p.s, 0.0);
    // 60 deg with mu = 0.5: slides down the blade (towards -s) with g (sin - mu cos)
    let cfg = PancakeConfig { mu_static: 0.5, mu_kinetic: 0.5, blade_half_length: 1.0 };
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
    let mut p = Pancake::new(PancakeConfig::default());
    p.step(&PlanarMotion { theta: 0.0, w: 0.0, dw: 0.0, a_y: 0.0, a_z: -1.5 * G }, g, 1e-3);
    assert_eq!(p.mode, PancakeMode::Off);
    // a level spatula jerked sideways: the pancake slides and, pulled long enough, falls off
    let mut p = Pancake::new(PancakeConfig::default());
    let mut n = 0;
    while p.mode != PancakeMode::Off && n < 10_000 {
        p.step(&PlanarMotion { theta: 0.0, w: 0.0, dw: 0.0, a_y: 2.0 * G, a_z: 0.0 }, g, 1e-3);
        n += 1;
    }
    assert_eq!(p.mode, PancakeMode::Off);
    assert!(p.s < -0.06 + 1e-3, "slid back along -y: s = {}", p.s);
    // sliding is decelerated by friction and sticks again once the spatula stops pulling
    let mut p = Pancake::new(PancakeConfig::default());
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
        let cfg = PancakeConfig { mu_static: mu, mu_kinetic: mu, blade_half_length: 1.0 };
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

// ------------------------------------------------------------------------------------- UR5

fn ur5() -> Dynamics {
    Dynamics::from_description(&preset("ur5").unwrap()).unwrap()
}

fn sim(config: SimConfig) -> Simulation {
    Simulation::new(&ur5(), config).unwrap()
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

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_papers_task_region_is_reachable_away_from_singularities() {
    // y, z in [-0.15, 0.15] (the paper: +-0.1), theta over [-pi, pi], from the start pose
    let mut s = sim(SimConfig::new(6));
    let (cmds, q0) = s.prepare(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
    assert_eq!(cmds.len(), 2);
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
    let singular = SimConfig::new(6).controller.singular_det;
    assert!(min_det > 20.0 * singular, "min |det J| = {min_det}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn bad_trajectories_are_refused_before_the_loop() {
    let mut s = sim(SimConfig::new(6));
    let e = s.run(&[0.0, 0.0, 0.0, 0.0, 0.0], None, false).unwrap_err().to_string();
    assert!(e.contains("rows [y, z, theta]"), "{e}");
    let mut traj = s_curve([0.0; 3], [0.05, 0.0, -0.3], 50);
    traj[3 * 17 + 2] = f64::NAN;
    let e = s.run(&traj, None, false).unwrap_err().to_string();
    assert!(e.contains("trajectory row 17 (column 2)") && e.contains("NaN"), "{e}");
    let traj = s_curve([0.0; 3], [1.0, 0.0, 0.0], 100); // 1 m sideways: out of reach
    let e = s.run(&traj, None, false).unwrap_err().to_string();
    assert!(e.contains("not reachable") && e.contains("trajectory row"), "{e}");
    assert_eq!(s.ticks, 0, "nothing ran");
    let e = s.run(&s_curve([0.0; 3], [0.0; 3], 10), Some(11), false).unwrap_err().to_string();
    assert!(e.contains("motion_len"), "{e}");
    // bad configuration values are refused by Simulation::new
    let mut c = SimConfig::new(6);
    c.controller.dob_cutoff_hz = -2.0;
    assert!(Simulation::new(&ur5(), c).err().unwrap().to_string().contains("dob_cutoff_hz"));
    let mut c = SimConfig::new(6);
    c.disturbances.coulomb = vec![1.0; 5];
    assert!(Simulation::new(&ur5(), c).err().unwrap().to_string().contains("disturbances.coulomb"));
    let panda = Dynamics::from_description(&preset("panda").unwrap()).unwrap();
    assert!(Simulation::new(&panda, SimConfig::new(7)).err().unwrap().to_string().contains("6-joint"));
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_plant_integrator_is_fourth_order_and_conserves_energy() {
    // the plant alone, no torque, no friction: the arm falls from the start pose
    let final_state = |substeps: usize, periods: usize| {
        let mut c = SimConfig::new(6);
        c.substeps = substeps;
        let mut s = sim(c);
        let (_, q0) = s.prepare(&[0.0; 6]).unwrap();
        s.reset(&q0).unwrap();
        let energy = |s: &Simulation| {
            let mut ws = s.plant.workspace();
            s.plant.update_kinematics_unchecked(&s.q, Some(&s.v), &mut ws);
            s.plant.kinetic_energy_from_kinematics(&ws) + s.plant.potential_energy_from_kinematics(&ws)
        };
        let e0 = energy(&s);
        for _ in 0..periods {
            s.integrate_plant(&nalgebra::Vector6::zeros()).unwrap();
        }
        (s.q, s.v, energy(&s) - e0)
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
    let run = |dob: bool, offset: f64| {
        let mut c = SimConfig::new(6);
        c.controller.dob = dob;
        c.settle_ticks = 1000;
        c.disturbances.offset = vec![2.0 * offset, -3.0 * offset, 1.5 * offset, 0.5 * offset, -0.5 * offset, 0.3 * offset];
        sim(c).run(&hold, None, false).unwrap()
    };
    let r = run(true, 0.0);
    assert!(r.summary.max_err_pos < 1e-9 && r.summary.max_err_rot < 1e-9, "{:?}", r.summary);
    assert!(r.log.tau_dis_hat.iter().all(|x| x.abs() < 1e-6));
    let with = run(true, 1.0);
    let without = run(false, 1.0);
    // without the DOB the offset leaves a steady error; with it the error vanishes
    assert!(without.summary.max_err_pos > 1e-3, "{:?}", without.summary);
    assert!(with.summary.max_err_pos < 1e-2 * without.summary.max_err_pos, "{:?}", with.summary);
    // and the estimate converges to minus the offset (tau - M qdd - h = -offset)
    let last = &with.log.tau_dis_hat[with.log.tau_dis_hat.len() - 6..];
    let offset = [2.0, -3.0, 1.5, 0.5, -0.5, 0.3];
    for i in 0..6 {
        assert!((last[i] + offset[i]).abs() < 1e-3, "{last:?}");
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn the_dob_improves_tracking_under_the_reference_disturbances() {
    let traj = s_curve([0.0; 3], [0.05, 0.03, -0.5], 500);
    let run = |dob: bool| {
        let mut c = SimConfig::new(6);
        c.controller.dob = dob;
        c.settle_ticks = 500;
        c.disturbances = Disturbances::reference();
        sim(c).run(&traj, None, false).unwrap().summary
    };
    let (with, without) = (run(true), run(false));
    assert!(without.max_err_pos > 1.5 * with.max_err_pos, "{with:?} {without:?}");
    assert!(without.max_err_rot > 1.5 * with.max_err_rot, "{with:?} {without:?}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn slip_verdicts_gentle_versus_too_fast() {
    let run = |traj: &[f64]| {
        let mut c = SimConfig::new(6);
        c.settle_ticks = 200;
        c.disturbances = Disturbances::reference();
        sim(c).run(traj, None, false).unwrap()
    };
    let gentle = run(&s_curve([0.0; 3], [0.06, 0.02, -0.4], 500));
    assert!(!gentle.summary.slipped && gentle.summary.max_abs_phi < 0.7, "{:?}", gentle.summary);
    assert!(gentle.log.pancake_mode.iter().all(|&m| m == 0));
    // the same move in 0.12 s: peak accelerations near 2 pi 0.06 / 0.12^2 = 26 m/s^2
    let fast = run(&s_curve([0.0; 3], [0.06, 0.02, -0.4], 120));
    assert!(fast.summary.slipped && fast.summary.max_abs_phi > PI / 4.0, "{:?}", fast.summary);
    let t = fast.summary.first_slip_time.unwrap();
    assert!(t >= 0.2, "slips during the motion, not the settle phase: {t}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn a_singular_jacobian_is_damped_and_reported() {
    // wrist 2 at 0: the UR5's wrist singularity (wrist 1 and wrist 3 axes parallel)
    let mut s = sim(SimConfig::new(6));
    let q_sing = [0.1, -1.5, 1.6, -0.2, 0.0, 0.3];
    assert!(s.jacobian_det(&q_sing).unwrap() < 1e-12);
    s.reset(&q_sing).unwrap();
    let (p, r) = s.spatula_pose(&q_sing).unwrap();
    let cmd = genplan_core::control::Command {
        pos: p + Vector3::new(0.0, 0.01, 0.0),
        rot: r,
        vel: nalgebra::Vector6::zeros(),
        acc: nalgebra::Vector6::zeros(),
        paper: [0.0; 3],
    };
    let mut damped = 0;
    for _ in 0..500 {
        let out = s.tick(&cmd).unwrap();
        damped += out.damped as usize;
        assert!(out.tau.iter().all(|x| x.is_finite()));
    }
    assert!(damped > 0);
    let (p_end, _) = s.spatula_pose(&s.q.clone()).unwrap();
    assert!((p_end - cmd.pos).norm() < 0.01, "still converges towards the command");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn paced_mode_ticks_on_the_wall_clock() {
    let mut c = SimConfig::new(6);
    c.settle_ticks = 0;
    let mut s = sim(c);
    let traj = s_curve([0.0; 3], [0.01, 0.0, -0.1], 60);
    let t0 = std::time::Instant::now();
    let r = s.run(&traj, None, true).unwrap();
    assert!(t0.elapsed().as_secs_f64() >= 0.059);
    assert_eq!(r.log.lateness.len(), 60);
    assert_eq!(r.log.compute.len(), 60);
    assert!(r.log.lateness.iter().all(|&x| x >= 0.0));
    // the same run unpaced gives the same trajectory (pacing does not change the physics)
    let mut s2 = sim(SimConfig::new(6));
    let r2 = s2.run(&traj, None, false).unwrap();
    assert_eq!(r.log.q, r2.log.q);
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn runs_are_checked_against_the_urdf_joint_limits() {
    let arm = ur5();
    assert_eq!(arm.effort_limit, vec![150.0, 150.0, 150.0, 28.0, 28.0, 28.0]);
    assert_eq!(arm.velocity_limit, vec![3.15, 3.15, 3.15, 3.2, 3.2, 3.2]);
    // a gentle move stays within them
    let mut s = sim(SimConfig::new(6));
    let r = s.run(&s_curve([0.0; 3], [0.06, 0.02, -0.4], 500), None, false).unwrap();
    assert!(r.summary.limit_violation.is_none() && r.summary.limit_ticks == 0);
    assert!(r.summary.max_abs_v.iter().zip(&arm.velocity_limit).all(|(v, l)| v < l));
    // a 30 cm jump of the command after 0.2 s: tens of thousands of N m at the jump
    let mut jump = vec![0.0; 3 * 400];
    for k in 200..400 {
        jump[3 * k] = 0.3;
    }
    let r = s.run(&jump, None, false).unwrap();
    let v = r.summary.limit_violation.expect("a violation");
    assert_eq!((v.tick, v.kind, v.unit), (200, LimitKind::Torque, "N m"));
    assert!((v.time - 0.2).abs() < 1e-12 && v.value.abs() > 1e4 && v.limit == 150.0);
    assert!(r.summary.limit_ticks > 1 && r.log.n == 400 && !r.summary.stopped_at_limit);
    let msg = v.describe(&arm.joint_names);
    assert!(msg.starts_with("joint 'shoulder_pan_joint' exceeds its torque limit at t = 0.200 s: |torque| = "), "{msg}");
    assert!(msg.ends_with(" N m > 150 N m"), "{msg}");
    // stop_at_limit: the run ends with the violating tick
    let r = s.run_with(&jump, None, false, true, &mut || false).unwrap();
    assert!(r.summary.stopped_at_limit && r.log.n == 201 && r.log.t.len() == 201 && r.summary.ticks == 201);
    assert_eq!(r.summary.limit_violation, Some(v));
    // limits of one's own: unchecked joints (inf) and a speed limit
    let mut c = SimConfig::new(6);
    c.limits = JointLimits { torque: Some(vec![f64::INFINITY; 6]), velocity: Some(vec![0.5; 6]) };
    let r = sim(c).run(&jump, None, false).unwrap();
    let v = r.summary.limit_violation.unwrap();
    assert_eq!((v.kind, v.unit, v.limit), (LimitKind::Velocity, "rad/s", 0.5));
    assert!(v.tick > 200);
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn bad_configuration_values_are_settings_errors_naming_the_field() {
    let cases: Vec<(fn(&mut SimConfig), &str)> = vec![
        (|c| c.controller.dt = 0.0, "controller.dt"),
        (|c| c.controller.dt = f64::NAN, "controller.dt"),
        (|c| c.controller.dob_cutoff_hz = 0.0, "controller.dob_cutoff_hz"),
        (|c| c.controller.gains.kvr = -1.0, "controller.gains.kvr"),
        (|c| c.controller.torque_limit = Some(vec![1.0, 1.0, 1.0, 1.0, 1.0, 0.0]), "controller.torque_limit"),
        (|c| c.disturbances.payload_mass = -1.0, "disturbances.payload_mass"),
        (|c| c.disturbances.payload_mass = 150.0, "disturbances.payload_mass"),
        (|c| c.disturbances.payload_com = [2.0, 0.0, 0.0], "disturbances.payload_com"),
        (|c| c.disturbances.viscous = vec![-1.0; 6], "disturbances.viscous"),
        (|c| c.setup.spatula_mass = 1e6, "setup.spatula_mass"),
        (|c| c.pancake.blade_half_length = f64::INFINITY, "pancake.blade_half_length"),
        (|c| c.limits.velocity = Some(vec![f64::NAN; 6]), "limits.velocity"),
        (|c| c.limits.torque = Some(vec![1.0; 5]), "limits.torque"),
        (|c| c.substeps = 0, "substeps"),
    ];
    for (change, field) in cases {
        let mut c = SimConfig::new(6);
        change(&mut c);
        match Simulation::new(&ur5(), c) {
            Err(Error::Settings { field: f, msg }) => assert_eq!(f, field, "{msg}"),
            Err(e) => panic!("{field}: {e}"),
            Ok(_) => panic!("{field}: accepted"),
        }
    }
}

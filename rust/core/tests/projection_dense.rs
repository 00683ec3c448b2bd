//! Dense paths on a manifold (`projection::densify`, `hold_chords`, `dense_path`) on the test
//! arm with its tool's origin kept on a horizontal plane: every step at most the resolution,
//! every state on the manifold, the input states kept in order; interpolation alone without a
//! projector (the counts and spacing exact); straying chords split until their midpoints are
//! within the chord tolerance; each failure kind returned with the path before the failing step;
//! bad settings refused naming the field.

use std::sync::Arc;

use genplan_core::kinematics::KinematicModel;
use genplan_core::projection::{dense_path, densify, hold_chords, DenseFailure, DenseSettings, Projector, Settings, Term, TermKind};
use genplan_core::Error;
use nalgebra::Vector3;

#[path = "common/arm.rs"]
mod arm;
use arm::model;

/// The tool's origin at `height` (m) within `tolerance`.
fn plane(m: &Arc<KinematicModel>, height: f64, tolerance: f64) -> Projector {
    let tool = m.link_index("tool").unwrap();
    let term = Term { name: "plane".into(), kind: TermKind::Plane { link: tool, normal: Vector3::z(), offset: height }, weight: 1.0, tolerance };
    Projector::new(m.clone(), vec![term], vec![], Settings::default()).unwrap()
}

fn settings(resolution: f64) -> DenseSettings {
    DenseSettings { resolution, max_jump: 3.0, max_rounds: 8, chord_rounds: 3, chord_fraction: 0.75 }
}

fn largest_step(path: &[f64], n: usize) -> f64 {
    path.chunks(n).zip(path.chunks(n).skip(1)).flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (y - x).abs())).fold(0.0, f64::max)
}

/// Two states on the plane 0.55 m high, far apart: the path between them (projected).
fn ends(p: &Projector) -> Vec<f64> {
    let mut q = Vec::new();
    for start in [[0.2, 0.3, -0.4, 0.05], [1.4, 0.1, 0.5, 0.02]] {
        let out = p.solve(&start, None).unwrap();
        assert!(out.success, "{out:?}");
        q.extend(out.q);
    }
    q
}

#[test]
fn a_dense_path_keeps_its_states_steps_within_the_resolution_on_the_manifold() {
    let m = model(false);
    let p = plane(&m, 0.55, 1e-6);
    let q = ends(&p);
    let d = densify(&q, 4, &settings(0.025), Some(&p)).unwrap();
    assert_eq!(d.failure, None);
    let rows = d.path.len() / 4;
    assert!(rows > 40, "{rows} states");
    assert!(largest_step(&d.path, 4) <= 0.025 * (1.0 + 1e-9));
    assert_eq!(&d.path[..4], &q[..4]);
    assert_eq!(&d.path[d.path.len() - 4..], &q[4..]);
    // every state on the manifold (the projector's residual, no step)
    let sizes = p.try_residual_sizes(&d.path, false).unwrap();
    assert!(sizes.iter().all(|&s| s < 1e-6), "{:?}", sizes.iter().copied().fold(0.0, f64::max));
    // the same through dense_path, and the chords held: every midpoint within 3/4 of a looser tolerance
    let loose = plane(&m, 0.55, 1e-5);
    let held = dense_path(&q, 4, &settings(0.025), Some(&p), Some(&loose), true).unwrap();
    assert_eq!(held.failure, None);
    assert!(held.path.len() >= d.path.len());
    let mids: Vec<f64> = held.path.chunks(4).zip(held.path.chunks(4).skip(1)).flat_map(|(a, b)| (0..4).map(move |k| 0.5 * (a[k] + b[k]))).collect();
    let sizes = loose.try_residual_sizes(&mids, false).unwrap();
    assert!(sizes.iter().all(|&s| s <= 0.75 * 1e-5), "{:?}", sizes.iter().copied().fold(0.0, f64::max));
}

#[test]
fn without_a_projector_the_steps_are_cut_evenly() {
    // steps of 0.1 (joint 0) and 0.02: the first cut in 4 (3 states added), the second kept
    let q = [0.0, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.1, 0.02, 0.0, 0.0];
    let d = densify(&q, 4, &settings(0.025), None).unwrap();
    assert_eq!(d.failure, None);
    assert_eq!(d.path.len() / 4, 6);
    let firsts: Vec<f64> = d.path.chunks(4).map(|r| r[0]).collect();
    assert_eq!(firsts, vec![0.0, 0.025, 0.05, 0.07500000000000001, 0.1, 0.1]);
    // one state: nothing to do
    assert_eq!(densify(&q[..4], 4, &settings(0.025), None).unwrap().path, q[..4].to_vec());
}

#[test]
fn straying_chords_are_split_at_their_projected_midpoints() {
    let m = model(false);
    let p = plane(&m, 0.55, 1e-7);
    let q = ends(&p);
    // a coarse path (steps of 0.2) on the manifold, whose chords leave a tight tolerance
    let coarse = densify(&q, 4, &settings(0.2), Some(&p)).unwrap();
    let tight = plane(&m, 0.55, 1e-5);
    let before = coarse.path.len() / 4;
    let held = hold_chords(&coarse.path, 4, &settings(0.2), &p, &tight).unwrap();
    assert_eq!(held.failure, None);
    assert!(held.path.len() / 4 > before, "no chord split ({before} states)");
    // the original states are all still there, in order
    let mut it = held.path.chunks(4);
    for s in coarse.path.chunks(4) {
        assert!(it.any(|r| r == s), "state {s:?} lost");
    }
}

#[test]
fn failures_return_the_path_before_the_failing_step() {
    let m = model(false);
    let p = plane(&m, 0.55, 1e-6);
    let q = ends(&p);
    // a plane out of the arm's reach: no interpolated state can be projected
    let far = plane(&m, 5.0, 1e-6);
    let d = densify(&q, 4, &settings(0.025), Some(&far)).unwrap();
    assert_eq!((d.failure, d.path.as_slice()), (Some(DenseFailure::Projection), q.as_slice()));
    assert_eq!(d.failure.unwrap().parts().0, "projection");
    // a jump bound below what the projection moves the interpolations
    let jumpy = DenseSettings { max_jump: 1e-9, ..settings(0.025) };
    match densify(&q, 4, &jumpy, Some(&p)).unwrap().failure {
        Some(DenseFailure::Jump(v)) => assert!(v > 1e-9 * 0.025 && v.is_finite(), "{v}"),
        other => panic!("expected a jump, got {other:?}"),
    }
    // a path that would need more than MAX_DENSE_STATES states is refused before allocating them
    let huge = [0.0, 0.0, 0.0, 0.0, 1e5, 0.0, 0.0, 0.0];
    assert_eq!(densify(&huge, 4, &settings(0.01), None).unwrap().failure, Some(DenseFailure::Steps(1e5)));
    // no rounds: the steps are what they were
    let none = DenseSettings { max_rounds: 0, ..settings(0.025) };
    assert!(matches!(densify(&q, 4, &none, Some(&p)).unwrap().failure, Some(DenseFailure::Steps(_))));
    // a non-finite row ends as a failure, not a panic
    let nan = [0.0, 0.0, 0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0];
    assert!(densify(&nan, 4, &settings(0.025), Some(&p)).unwrap().failure.is_some());
}

#[test]
fn bad_settings_and_shapes_are_refused_naming_them() {
    let m = model(false);
    let p = plane(&m, 0.55, 1e-6);
    for (bad, field) in [
        (DenseSettings { resolution: 0.0, ..settings(0.025) }, "resolution"),
        (DenseSettings { max_jump: f64::NAN, ..settings(0.025) }, "max_jump"),
        (DenseSettings { chord_fraction: -1.0, ..settings(0.025) }, "chord_fraction"),
    ] {
        match densify(&[0.0; 8], 4, &bad, None) {
            Err(genplan_core::projection::SolveError::Input(Error::Settings { field: f, .. })) => assert_eq!(f, field),
            other => panic!("expected a settings error on {field}, got {other:?}"),
        }
    }
    let e = densify(&[0.0; 7], 4, &settings(0.025), None).unwrap_err().to_string();
    assert!(e.contains("7 numbers are not rows of 4"), "{e}");
    let e = densify(&[0.0; 6], 3, &settings(0.025), Some(&p)).unwrap_err().to_string();
    assert!(e.contains("robot has 4 joints"), "{e}");
}

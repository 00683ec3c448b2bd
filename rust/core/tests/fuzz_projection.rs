//! Property tests of the projector's settings and solves: `Settings::validate` never panics and
//! accepts exactly the documented ranges (`mu`, `mu_bar`, `secondary_slack` finite and >= 0;
//! `armijo_c1`, `backtrack` in (0, 1); any counts and flag), naming a bad field; a projector
//! built with accepted settings and terms solves from any configuration with `Ok` or `Err`,
//! never a panic, and an `Ok` is finite, within the limits when clipping, and a success meets
//! every tolerance.

#[path = "common/fuzz.rs"]
mod fuzz;

use std::sync::Arc;

use fuzz::{any_f64, any_usize, config};
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::projection::{Projector, Settings, Term, TermKind};
use genplan_core::urdf::Urdf;
use genplan_core::Error;
use nalgebra::Vector3;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// A revolute, a prismatic and a continuous joint (nq 4, nv 3).
const ARM: &str = r#"<robot name="arm"><link name="base"/><link name="l1"/><link name="l2"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/>
    <axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="tool"/><origin xyz="0 0 0.2"/>
    <axis xyz="0 1 0"/></joint></robot>"#;

fn model() -> Arc<KinematicModel> {
    Arc::new(KinematicModel::from_urdf(&Urdf::parse(ARM).unwrap(), &ModelOptions::default()).unwrap())
}

/// The documented range of each field: the fields out of range.
fn out_of_range(s: &Settings) -> Vec<&'static str> {
    let nonneg = |v: f64| v.is_finite() && v >= 0.0;
    let unit = |v: f64| v > 0.0 && v < 1.0;
    [
        ("mu", nonneg(s.mu)),
        ("mu_bar", nonneg(s.mu_bar)),
        ("secondary_slack", nonneg(s.secondary_slack)),
        ("armijo_c1", unit(s.armijo_c1)),
        ("backtrack", unit(s.backtrack)),
    ]
    .into_iter()
    .filter(|(_, ok)| !ok)
    .map(|(f, _)| f)
    .collect()
}

fn settings(counts: impl Strategy<Value = usize> + Clone, unit: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = Settings> {
    (counts.clone(), any_f64(), any_f64(), unit.clone(), unit, counts.clone(), any::<bool>(), counts, any_f64()).prop_map(
        |(max_iterations, mu, mu_bar, armijo_c1, backtrack, max_backtracks, clip_to_limits, secondary_backtracks, secondary_slack)| Settings {
            max_iterations,
            mu,
            mu_bar,
            armijo_c1,
            backtrack,
            max_backtracks,
            clip_to_limits,
            secondary_backtracks,
            secondary_slack,
        },
    )
}

/// A primary position term for the tool, joint limits, and a posture secondary, with the given
/// weights, tolerances, target and mask.
fn terms(w: [f64; 3], tol: [f64; 2], target: [f64; 3], mask: [f64; 3], margin: f64) -> (Vec<Term>, Vec<Term>) {
    let m = model();
    let tool = m.link_index("tool").unwrap();
    let primary = vec![
        Term { name: "tool".into(), kind: TermKind::FramePosition { link: tool, target: Vector3::from(target), mask }, weight: w[0], tolerance: tol[0] },
        Term { name: "limits".into(), kind: TermKind::JointLimits { margin }, weight: w[1], tolerance: tol[1] },
    ];
    let secondary = vec![Term {
        name: "posture".into(),
        kind: TermKind::Posture { q_nom: None, weights: vec![1.0; m.nv], overrides: Vec::new() },
        weight: w[2],
        tolerance: 1.0,
    }];
    (primary, secondary)
}

/// Solve from `q` (and `q_nom`): Err exactly for malformed input; an Ok is finite, clipped and
/// honest about success.
fn check_solve(p: &Projector, q: &[f64], q_nom: Option<&[f64]>) -> Result<(), TestCaseError> {
    let nq = p.model.nq;
    let malformed = q.len() != nq || q.iter().any(|x| !x.is_finite()) || q_nom.is_some_and(|n| n.len() != nq || n.iter().any(|x| !x.is_finite()));
    match p.solve(q, q_nom) {
        Err(e) => prop_assert!(malformed, "a well-formed q {:?} was refused: {}", q, e),
        Ok(out) => {
            prop_assert!(!malformed, "a malformed q {:?} / q_nom {:?} was accepted", q, q_nom);
            prop_assert!(out.q.len() == nq && out.q.iter().all(|x| x.is_finite()), "non-finite answer {:?} from q {:?}", out.q, q);
            prop_assert!(out.residuals.iter().all(|r| !r.is_nan()), "NaN residuals {:?}", out.residuals);
            if out.success {
                for (t, r) in p.primary.iter().zip(&out.residuals) {
                    prop_assert!(*r < t.tolerance, "success with residual {} >= tolerance {}", r, t.tolerance);
                }
            }
            if p.settings.clip_to_limits {
                for i in [0usize, 1] {
                    prop_assert!(p.model.lower[i] <= out.q[i] && out.q[i] <= p.model.upper[i], "q[{}] = {} outside its limits", i, out.q[i]);
                }
            }
        }
    }
    Ok(())
}

fn config_vector() -> impl Strategy<Value = Vec<f64>> {
    prop_oneof![
        4 => (-3.0..3.0f64, -0.5..0.5f64, -3.2..3.2f64).prop_map(|(a, b, c)| vec![a, b, c.cos(), c.sin()]),
        2 => proptest::collection::vec(any_f64(), 4),
        1 => proptest::collection::vec(any_f64(), 0..7),
    ]
}

proptest! {
    #![proptest_config(config(256))]

    /// validate() accepts exactly the documented ranges, and a refusal names a field out of range.
    #[test]
    fn validate_accepts_exactly_the_documented_ranges(s in settings(any_usize(), any_f64())) {
        let bad = out_of_range(&s);
        match s.validate() {
            Ok(()) => prop_assert!(bad.is_empty(), "accepted with {:?} out of range: {:?}", bad, s),
            Err(Error::Settings { field, msg }) => prop_assert!(bad.contains(&field), "refused naming {} ({}), out of range: {:?}", field, msg, bad),
            Err(other) => prop_assert!(false, "refused with another error: {}", other),
        }
    }

    /// Projectors with any settings and terms: built exactly when they are valid, and their
    /// solves from any configuration answer (small counts, so that a solve ends quickly).
    #[test]
    fn solves_answer(
        s in settings(0usize..30, prop_oneof![0.01..0.99f64, any_f64()]),
        w in proptest::array::uniform3(prop_oneof![3 => 0.1..50.0f64, 1 => any_f64()]),
        tol in proptest::array::uniform2(prop_oneof![3 => 1e-6..1e-2f64, 1 => any_f64()]),
        target in proptest::array::uniform3(prop_oneof![3 => -1.0..1.0f64, 1 => any_f64()]),
        mask in proptest::array::uniform3(prop_oneof![Just(1.0), Just(0.0), any_f64()]),
        margin in prop_oneof![Just(1e-3), any_f64()],
        q in config_vector(),
        q_nom in proptest::option::of(config_vector()),
    ) {
        let (primary, secondary) = terms(w, tol, target, mask, margin);
        let terms_ok = w.iter().chain(&tol).all(|x| x.is_finite() && *x > 0.0);
        let finite_data = target.iter().chain(&mask).chain([&margin]).all(|x| x.is_finite());
        // finding PROJ-1: targets, masks and margins are not checked; absurd ones give NaN answers
        let sane_data = target.iter().chain(&mask).chain([&margin]).all(|x| x.abs() <= 1e100);
        match Projector::new(model(), primary, secondary, s.clone()) {
            Err(e) => prop_assert!(!(out_of_range(&s).is_empty() && terms_ok && finite_data), "refused valid settings and terms: {}", e),
            Ok(p) => {
                prop_assert!(out_of_range(&s).is_empty() && terms_ok, "accepted bad settings or terms");
                if sane_data {
                    check_solve(&p, &q, q_nom.as_deref())?;
                } else {
                    let _ = p.solve(&q, q_nom.as_deref()); // answers, whatever it says
                }
            }
        }
    }
}

/// PROJ-1: a term's target, mask or margin may be NaN, inf or absurd: `Projector::new` checks
/// weights and tolerances but not these (`Projector::retargeted` does check its target).
#[test]
#[should_panic(expected = "accepted a non-finite target")]
fn finding_proj_1_a_non_finite_target_is_accepted() {
    let (primary, secondary) = terms([1.0; 3], [1e-3; 2], [f64::NAN, 0.0, 0.5], [1.0; 3], 1e-3);
    if Projector::new(model(), primary, secondary, Settings::default()).is_ok() {
        panic!("Projector::new accepted a non-finite target");
    }
}

/// PROJ-1: ... and a huge but finite mask (f64::MAX) overflows: the solve answers Ok with an
/// all-NaN q (found by `solves_answer`, shrunk).
#[test]
#[should_panic(expected = "non-finite answer [NaN, NaN, NaN, NaN]")]
fn finding_proj_1_a_huge_mask_gives_a_nan_answer() {
    let (primary, secondary) = terms([0.1; 3], [1e-6; 2], [0.0, 0.0, -0.35], [1.0, 1.0, f64::MAX], 1e-3);
    let s = Settings { max_iterations: 1, max_backtracks: 1, clip_to_limits: false, ..Settings::default() };
    let p = Projector::new(model(), primary, secondary, s).expect("accepted");
    check_solve(&p, &[0.0, 0.0, 1.0, 0.0], None).unwrap();
}

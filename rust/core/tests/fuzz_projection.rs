//! Property tests of the projector's settings and solves: `Settings::validate` never panics and
//! accepts exactly the documented ranges (`mu`, `mu_bar`, `secondary_slack` in [0, 1e6];
//! `armijo_c1`, `backtrack` in (0, 1); any counts and flag), naming a bad field; a projector is
//! built exactly when its settings and terms are in range (weights and tolerances in (0, 1e6],
//! targets and masks finite and within 1e6, margins in [0, 1e6]); it solves from any
//! configuration with `Ok` or `Err`, never a panic, and an `Ok` is finite, within the limits
//! when clipping, and a success meets every tolerance.

#[path = "common/fuzz.rs"]
mod fuzz;

use std::sync::Arc;

use fuzz::{any_f64, any_usize, config};
use genplan_core::kinematics::{KinematicModel, ModelOptions, Motion};
use genplan_core::projection::{Projector, Settings, Term, TermKind, MAX_MAGNITUDE};
use genplan_core::urdf::{Urdf, MAX_JOINT_POSITION};
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
    let nonneg = |v: f64| v.is_finite() && (0.0..=1e6).contains(&v);
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
    (counts.clone(), any_f64(), any_f64(), unit.clone(), unit, counts.clone(), any::<bool>(), any::<bool>(), counts, any_f64()).prop_map(
        |(max_iterations, mu, mu_bar, armijo_c1, backtrack, max_backtracks, clip_to_limits, active_set, secondary_backtracks, secondary_slack)| Settings {
            max_iterations,
            mu,
            mu_bar,
            armijo_c1,
            backtrack,
            max_backtracks,
            clip_to_limits,
            active_set,
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
    // a revolute or prismatic value beyond MAX_JOINT_POSITION is refused (finding URDF-7)
    let beyond = |q: &[f64]| {
        p.model.joints.iter().any(|j| {
            matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. })
                && q.get(j.q_index).is_some_and(|x| x.abs() > MAX_JOINT_POSITION)
        })
    };
    let malformed = q.len() != nq
        || q.iter().any(|x| !x.is_finite())
        || beyond(q)
        || q_nom.is_some_and(|n| n.len() != nq || n.iter().any(|x| !x.is_finite()) || beyond(n));
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

/// The documented ranges of the terms' numbers ([`terms`]): weights and tolerances in (0, 1e6],
/// targets and masks finite and at most 1e6 in absolute value, the margin in [0, 1e6].
fn terms_in_range(w: [f64; 3], tol: [f64; 2], target: [f64; 3], mask: [f64; 3], margin: f64) -> bool {
    let positive = |x: &f64| x.is_finite() && *x > 0.0 && *x <= 1e6;
    let bounded = |x: &f64| x.is_finite() && x.abs() <= 1e6;
    w.iter().chain(&tol).all(positive) && target.iter().chain(&mask).all(bounded) && bounded(&margin) && margin >= 0.0
}

/// At the bound on a term's numbers, or just beyond it.
fn bounds() -> impl Strategy<Value = f64> + Clone {
    let m = MAX_MAGNITUDE;
    prop::sample::select(vec![m, -m, m * (1.0 + 1e-15), -m * (1.0 + 1e-15)])
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
        w in proptest::array::uniform3(prop_oneof![6 => 0.1..50.0f64, 2 => any_f64(), 1 => bounds()]),
        tol in proptest::array::uniform2(prop_oneof![6 => 1e-6..1e-2f64, 2 => any_f64(), 1 => bounds()]),
        target in proptest::array::uniform3(prop_oneof![6 => -1.0..1.0f64, 2 => any_f64(), 1 => bounds()]),
        mask in proptest::array::uniform3(prop_oneof![Just(1.0), Just(0.0), any_f64(), bounds()]),
        margin in prop_oneof![Just(1e-3), any_f64(), bounds()],
        q in config_vector(),
        q_nom in proptest::option::of(config_vector()),
    ) {
        let (primary, secondary) = terms(w, tol, target, mask, margin);
        // finding PROJ-1 (fixed): every number of a term is checked
        let terms_ok = terms_in_range(w, tol, target, mask, margin);
        match Projector::new(model(), primary, secondary, s.clone()) {
            Err(e) => prop_assert!(!(out_of_range(&s).is_empty() && terms_ok), "refused valid settings and terms: {}", e),
            Ok(p) => {
                prop_assert!(out_of_range(&s).is_empty() && terms_ok, "accepted bad settings or terms");
                check_solve(&p, &q, q_nom.as_deref())?;
            }
        }
    }
}

/// The error of building the projector of [`terms`] with these numbers (default settings).
fn refusal(w: [f64; 3], tol: [f64; 2], target: [f64; 3], mask: [f64; 3], margin: f64) -> String {
    let (primary, secondary) = terms(w, tol, target, mask, margin);
    match Projector::new(model(), primary, secondary, Settings::default()) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted w {w:?}, tol {tol:?}, target {target:?}, mask {mask:?}, margin {margin}"),
    }
}

/// PROJ-1 (fixed): a term's target, mask or margin could be NaN, inf or absurd: `Projector::new`
/// checked weights and tolerances but not these. Now every number of a term is finite and at
/// most `MAX_MAGNITUDE` (1e6) in absolute value, refused naming the term and the field.
#[test]
fn finding_proj_1_a_non_finite_target_is_refused() {
    let ok = ([1.0; 3], [1e-3; 2], [0.0, 0.0, 0.5], [1.0; 3], 1e-3);
    assert!(terms_in_range(ok.0, ok.1, ok.2, ok.3, ok.4));
    let (primary, secondary) = terms(ok.0, ok.1, ok.2, ok.3, ok.4);
    assert!(Projector::new(model(), primary, secondary, Settings::default()).is_ok());
    assert_eq!(refusal(ok.0, ok.1, [f64::NAN, 0.0, 0.5], ok.3, ok.4), "term 'tool' target: element 0 is not finite (NaN)");
    assert_eq!(refusal(ok.0, ok.1, [0.0, f64::INFINITY, 0.5], ok.3, ok.4), "term 'tool' target: element 1 is not finite (inf)");
    assert_eq!(
        refusal(ok.0, ok.1, [0.0, 0.0, 1.7976931348623157e308], ok.3, ok.4),
        "term 'tool': target element 2 is 1.7976931348623157e308, beyond the bound 1e6 on a term's numbers"
    );
    assert_eq!(refusal(ok.0, ok.1, ok.2, [1.0, f64::NEG_INFINITY, 1.0], ok.4), "term 'tool' mask: element 1 is not finite (-inf)");
    assert_eq!(refusal(ok.0, ok.1, ok.2, ok.3, f64::NAN), "term 'limits': margin must be in [0, 1e6], got NaN");
    assert_eq!(refusal(ok.0, ok.1, ok.2, ok.3, -1e-3), "term 'limits': margin must be in [0, 1e6], got -0.001");
    assert_eq!(refusal(ok.0, ok.1, ok.2, ok.3, 1e300), "term 'limits': margin must be in [0, 1e6], got 1e300");
    assert_eq!(refusal([1.0, 1e7, 1.0], ok.1, ok.2, ok.3, ok.4), "term 'limits': weight must be in (0, 1e6], got 10000000.0");
    assert_eq!(refusal(ok.0, [1e-3, 1e300], ok.2, ok.3, ok.4), "term 'limits': tolerance must be in (0, 1e6], got 1e300");
    assert_eq!(refusal([1.0, 1.0, -2.0], ok.1, ok.2, ok.3, ok.4), "term 'posture': weight must be in (0, 1e6], got -2.0");
    // the bounds themselves are accepted
    let (primary, secondary) = terms([MAX_MAGNITUDE; 3], [MAX_MAGNITUDE; 2], [-MAX_MAGNITUDE; 3], [MAX_MAGNITUDE; 3], MAX_MAGNITUDE);
    let p = Projector::new(model(), primary, secondary, Settings::default()).unwrap();
    check_solve(&p, &[0.0, 0.0, 1.0, 0.0], None).unwrap();
}

/// PROJ-1 (fixed): ... and a huge but finite mask (f64::MAX) overflowed: the solve answered Ok
/// with an all-NaN q (found by `solves_answer`, shrunk). Now the mask is refused; and the solver
/// never answers a non-finite q (it stops at the last finite iterate, unsuccessful).
#[test]
fn finding_proj_1_a_huge_mask_is_refused() {
    assert_eq!(
        refusal([0.1; 3], [1e-6; 2], [0.0, 0.0, -0.35], [1.0, 1.0, f64::MAX], 1e-3),
        "term 'tool': mask element 2 is 1.7976931348623157e308, beyond the bound 1e6 on a term's numbers"
    );
    // the largest mask, with the finding's settings: a finite answer
    let (primary, secondary) = terms([0.1; 3], [1e-6; 2], [0.0, 0.0, -0.35], [1.0, 1.0, MAX_MAGNITUDE], 1e-3);
    let s = Settings { max_iterations: 1, max_backtracks: 1, clip_to_limits: false, ..Settings::default() };
    let p = Projector::new(model(), primary, secondary, s).expect("accepted");
    check_solve(&p, &[0.0, 0.0, 1.0, 0.0], None).unwrap();
    // a start whose arithmetic would overflow (a prismatic joint at 1e300, not clipped) is
    // refused since finding URDF-7 (joint values at most MAX_JOINT_POSITION); at the bound the
    // solve answers finitely
    let (primary, secondary) = terms([1.0; 3], [1e-3; 2], [0.0, 0.0, 0.5], [1.0; 3], 1e-3);
    let s = Settings { clip_to_limits: false, ..Settings::default() };
    let p = Projector::new(model(), primary, secondary, s).unwrap();
    for q0 in [[0.0, 1e300, 1.0, 0.0], [0.0, f64::MAX, 1.0, 0.0], [1e300, -1e300, 1e300, -1e300]] {
        let e = p.solve(&q0, None).unwrap_err().to_string();
        assert!(e.contains("beyond 1e16 in magnitude"), "{q0:?}: {e}");
        check_solve(&p, &q0, None).unwrap();
    }
    for q0 in [[0.0, MAX_JOINT_POSITION, 1.0, 0.0], [-MAX_JOINT_POSITION, -MAX_JOINT_POSITION, 0.6, 0.8]] {
        let out = p.solve(&q0, None).unwrap();
        assert!(out.q.iter().all(|x| x.is_finite()) && !out.success, "{q0:?}: {out:?}");
        assert!(out.residuals.iter().all(|r| !r.is_nan()), "{q0:?}: {out:?}");
        check_solve(&p, &q0, None).unwrap();
    }
    // a start and a nominal posture so far apart that a step overflows to NaN (this answered an
    // all-NaN q before the solver checked its iterates)
    let (primary, secondary) = terms([1e6, 1.0, 1e6], [1e-3; 2], [1e6, 0.0, 0.5], [1e6, 1.0, 1.0], 0.0);
    let s = Settings { clip_to_limits: false, mu: 1e6, mu_bar: 0.0, ..Settings::default() };
    let p = Projector::new(model(), primary, secondary, s).unwrap();
    let (q0, q_nom) = ([0.0, MAX_JOINT_POSITION, 0.0, 1e150], [-MAX_JOINT_POSITION, MAX_JOINT_POSITION, -1e300, 1e300]);
    let out = p.solve(&q0, Some(&q_nom)).unwrap();
    assert!(out.q.iter().all(|x| x.is_finite()) && !out.success, "{out:?}");
    check_solve(&p, &q0, Some(&q_nom)).unwrap();
}

/// PROJ-1 (fixed), the bindings' `solve_batch(targets=...)`: each row's target goes through
/// `Projector::retargeted`, which checks it like `new` (1.8e308 gave an all-NaN answer).
#[test]
fn finding_proj_1_a_huge_target_row_is_refused() {
    let (primary, secondary) = terms([1.0; 3], [1e-3; 2], [0.0, 0.0, 0.5], [1.0; 3], 1e-3);
    let p = Projector::new(model(), primary, secondary, Settings::default()).unwrap();
    let e = p.retargeted(0, &[1.7976931348623157e308; 3]).unwrap_err();
    assert!(matches!(e, Error::Invalid(_)));
    assert_eq!(e.to_string(), "term 'tool': target element 0 is 1.7976931348623157e308, beyond the bound 1e6 on a term's numbers");
    assert!(matches!(p.retargeted(0, &[0.0, f64::NAN, 0.0]), Err(Error::NonFinite { .. })));
    let far = p.retargeted(0, &[1e6, -1e6, 1e6]).unwrap();
    let out = far.solve(&[0.0, 0.0, 1.0, 0.0], None).unwrap();
    assert!(out.q.iter().all(|x| x.is_finite()) && !out.success);
}

//! Terms of the caller's own (`projection::CustomTerm`, `TermKind::Custom`): a Rust
//! re-implementation of FramePosition solves exactly like the built-in one (primary and
//! secondary, fixed and free-flyer base, `primary_residuals` too); a term's error stops the solve
//! and comes back intact from `try_solve` (named in `solve`'s error, an unsuccessful outcome from
//! `solve_unchecked`); non-finite outputs and a zero-sized term are refused with the term's name.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use genplan_core::kinematics::KinematicModel;
use genplan_core::projection::{CustomTerm, Projector, Settings, SolveError, Term, TermError, TermKind};
use genplan_core::Error;
use nalgebra::{DMatrix, Vector3};

#[path = "common/arm.rs"]
mod arm;
use arm::model;

/// Starts: the joints of `rust/core/tests/projection.rs`, a free-flyer base moved and turned.
fn starts(m: &KinematicModel) -> Vec<Vec<f64>> {
    [[0.3, -0.7, 1.1, 0.04], [-2.0, 1.5, -0.4, 0.09], [0.0, 0.1, 0.0, 0.0]]
        .iter()
        .map(|j| {
            let mut q = Vec::new();
            if m.floating_base {
                let r = nalgebra::UnitQuaternion::from_euler_angles(0.4, -0.3, 1.2);
                q.extend([0.1, -0.2, 0.3, r.i, r.j, r.k, r.w]);
            }
            q.extend(j);
            q
        })
        .collect()
}

/// FramePosition written as a custom term: r = mask * (p(q) - target), J = mask * R J_local[0..3].
#[derive(Debug)]
struct Position {
    model: Arc<KinematicModel>,
    link: usize,
    target: Vector3<f64>,
    mask: [f64; 3],
    calls: AtomicUsize,
}

impl CustomTerm for Position {
    fn dim(&self) -> usize {
        3
    }

    fn evaluate(&self, q: &[f64], residual: &mut [f64], jacobian: Option<&mut [f64]>) -> Result<(), TermError> {
        self.calls.fetch_add(1, Ordering::Relaxed);
        let mut poses = Vec::new();
        self.model.forward_kinematics(q, &mut poses)?;
        let pose = poses[self.link];
        let d = pose.translation.vector - self.target;
        for k in 0..3 {
            residual[k] = self.mask[k] * d[k];
        }
        if let Some(out) = jacobian {
            let nv = self.model.nv;
            let mut local = DMatrix::zeros(6, nv);
            self.model.frame_jacobian_local(&poses, self.link, &mut local);
            let rot = pose.rotation.to_rotation_matrix().into_inner();
            let rot = DMatrix::from_fn(3, 3, |r, c| rot[(r, c)] * self.mask[r]);
            let j = rot * local.rows(0, 3);
            for r in 0..3 {
                for c in 0..nv {
                    out[r * nv + c] = j[(r, c)];
                }
            }
        }
        Ok(())
    }
}

fn tool_target(m: &KinematicModel) -> (usize, Vector3<f64>) {
    let tool = m.link_index("tool").unwrap();
    let mut poses = Vec::new();
    let mut q = starts(m)[0].clone();
    let n = q.len();
    q[n - 4..].copy_from_slice(&[0.8, -0.5, 0.7, 0.05]);
    m.forward_kinematics(&q, &mut poses).unwrap();
    (tool, poses[tool].translation.vector)
}

fn built_in(name: &str, link: usize, target: Vector3<f64>, weight: f64) -> Term {
    Term { name: name.into(), kind: TermKind::FramePosition { link, target, mask: [1.0, 0.5, 1.0] }, weight, tolerance: 1e-6 }
}

fn custom(m: &Arc<KinematicModel>, name: &str, link: usize, target: Vector3<f64>, weight: f64) -> (Term, Arc<Position>) {
    let c = Arc::new(Position { model: m.clone(), link, target, mask: [1.0, 0.5, 1.0], calls: AtomicUsize::new(0) });
    (Term { name: name.into(), kind: TermKind::Custom(c.clone()), weight, tolerance: 1e-6 }, c)
}

fn limits() -> Term {
    Term { name: "limits".into(), kind: TermKind::JointLimits { margin: 1e-3 }, weight: 10.0, tolerance: 1e-6 }
}

fn posture(nv: usize) -> Term {
    Term { name: "posture".into(), kind: TermKind::Posture { q_nom: None, weights: vec![1.0; nv], overrides: vec![] }, weight: 1.0, tolerance: 1.0 }
}

#[test]
fn custom_frame_position_solves_exactly_like_the_built_in_one() {
    for floating in [false, true] {
        let m = model(floating);
        let (tool, goal) = tool_target(&m);
        let reference = Projector::new(m.clone(), vec![built_in("tool", tool, goal, 10.0), limits()], vec![posture(m.nv)], Settings::default()).unwrap();
        let (term, calls) = custom(&m, "tool", tool, goal, 10.0);
        let mine = Projector::new(m.clone(), vec![term, limits()], vec![posture(m.nv)], Settings::default()).unwrap();
        assert_eq!(mine.primary_dim(), reference.primary_dim());
        let mut successes = 0;
        for q0 in starts(&m) {
            let a = reference.solve(&q0, None).unwrap();
            let b = mine.try_solve(&q0, None).unwrap();
            assert_eq!((a.success, a.iterations), (b.success, b.iterations), "floating {floating}, q0 {q0:?}");
            let dq = a.q.iter().zip(&b.q).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
            assert!(dq <= 1e-12, "floating {floating}: solutions differ by {dq}");
            for (x, y) in a.residuals.iter().zip(&b.residuals) {
                assert!((x - y).abs() <= 1e-12, "{:?} vs {:?}", a.residuals, b.residuals);
            }
            successes += usize::from(b.success);
            // the weighted residuals and Jacobian the GAN's costs use agree too
            let (ra, ja) = reference.primary_residuals(&q0, true).unwrap();
            let (rb, jb) = mine.try_primary_residuals(&q0, true).unwrap();
            assert!((ra - rb).amax() <= 1e-12);
            assert!((ja.unwrap() - jb.unwrap()).amax() <= 1e-12);
        }
        assert!(successes >= 2, "floating {floating}: the reachable target is reached from most starts");
        assert!(calls.calls.load(Ordering::Relaxed) > 0, "the custom term was evaluated");
    }
}

#[test]
fn custom_term_in_the_secondary_task_solves_like_the_built_in_one() {
    let m = model(false);
    let (tool, goal) = tool_target(&m);
    // not clipped at the start: out of the limits, the primary task iterates and the secondary
    // steps are tried
    let st = Settings { clip_to_limits: false, ..Settings::default() };
    let reference = Projector::new(m.clone(), vec![limits()], vec![built_in("reach", tool, goal, 1.0)], st.clone()).unwrap();
    let (term, calls) = custom(&m, "reach", tool, goal, 1.0);
    let mine = Projector::new(m.clone(), vec![limits()], vec![term], st).unwrap();
    let q0 = [3.5, 0.4, -0.5, 0.05];
    let a = reference.solve(&q0, None).unwrap();
    let b = mine.solve(&q0, None).unwrap();
    assert_eq!(a.iterations, b.iterations);
    assert!(a.iterations >= 1 && calls.calls.load(Ordering::Relaxed) >= 1);
    assert_eq!(a.q, b.q);
}

/// Fails on its `fail_at`-th evaluation with its own error type; or writes a NaN.
#[derive(Debug)]
struct Flaky {
    fail_at: usize,
    nan_in_jacobian: bool,
    dim: usize,
    calls: AtomicUsize,
}

#[derive(Debug, thiserror::Error)]
#[error("flaky term gave up at call {0}")]
struct GaveUp(usize);

impl CustomTerm for Flaky {
    fn dim(&self) -> usize {
        self.dim
    }

    fn evaluate(&self, q: &[f64], residual: &mut [f64], jacobian: Option<&mut [f64]>) -> Result<(), TermError> {
        let call = self.calls.fetch_add(1, Ordering::Relaxed) + 1;
        if call == self.fail_at {
            return Err(Box::new(GaveUp(call)));
        }
        residual[0] = q[0] - 0.5;
        if let Some(j) = jacobian {
            j.fill(0.0);
            j[0] = if self.nan_in_jacobian { f64::NAN } else { 1.0 };
        }
        Ok(())
    }
}

fn flaky(m: &Arc<KinematicModel>, fail_at: usize, nan_in_jacobian: bool) -> Projector {
    let term = Term {
        name: "flaky".into(),
        kind: TermKind::Custom(Arc::new(Flaky { fail_at, nan_in_jacobian, dim: 1, calls: AtomicUsize::new(0) })),
        weight: 1.0,
        tolerance: 1e-6,
    };
    Projector::new(m.clone(), vec![term], vec![posture(m.nv)], Settings::default()).unwrap()
}

#[test]
fn a_custom_terms_error_stops_the_solve_and_comes_back_intact() {
    let m = model(false);
    let q0 = [0.0, 0.1, 0.0, 0.0];
    // never fails: solves q[0] = 0.5
    let out = flaky(&m, usize::MAX, false).solve(&q0, None).unwrap();
    assert!(out.success && (out.q[0] - 0.5).abs() < 1e-6, "{out:?}");
    // fails at the first call (the residual at q0) and at a later one (inside the iterations)
    for fail_at in [1, 3] {
        match flaky(&m, fail_at, false).try_solve(&q0, None) {
            Err(SolveError::Term(f)) => {
                assert_eq!(f.term, "flaky");
                let e = f.source.downcast::<GaveUp>().expect("the term's own error type");
                assert_eq!(e.0, fail_at);
            }
            other => panic!("expected the term's failure, got {other:?}"),
        }
        let e = flaky(&m, fail_at, false).solve(&q0, None).unwrap_err();
        assert!(matches!(e, Error::Invalid(_)), "{e:?}");
        assert_eq!(e.to_string(), format!("term 'flaky': flaky term gave up at call {fail_at}"));
        let out = flaky(&m, fail_at, false).solve_unchecked(&q0, None);
        assert!(!out.success && out.residuals == vec![f64::INFINITY] && out.q == q0.to_vec(), "{out:?}");
        assert!(flaky(&m, fail_at, false).try_solve_unchecked(&q0, None).is_err());
        assert!(flaky(&m, fail_at, false).try_primary_residuals(&q0, false).is_err() == (fail_at == 1));
    }
    // bad input is still an input error, before the term runs
    assert!(matches!(flaky(&m, 1, false).try_solve(&[0.0; 3], None), Err(SolveError::Input(Error::Shape { .. }))));
}

#[test]
fn non_finite_outputs_and_empty_terms_are_refused_naming_the_term() {
    let m = model(false);
    let e = flaky(&m, usize::MAX, true).solve(&[0.0, 0.1, 0.0, 0.0], None).unwrap_err();
    match &e {
        Error::NonFinite { what, index, value } => {
            assert_eq!(what, "term 'flaky' Jacobian (row-major)");
            assert_eq!(*index, 0);
            assert!(value.is_nan());
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
    let empty = Term {
        name: "empty".into(),
        kind: TermKind::Custom(Arc::new(Flaky { fail_at: 0, nan_in_jacobian: false, dim: 0, calls: AtomicUsize::new(0) })),
        weight: 1.0,
        tolerance: 1e-3,
    };
    let e = Projector::new(m.clone(), vec![empty], vec![], Settings::default()).unwrap_err().to_string();
    assert!(e.contains("term 'empty'") && e.contains("dim >= 1"), "{e}");
    // a custom term takes no target
    let p = flaky(&m, usize::MAX, false);
    let e = p.retargeted(0, &[1.0, 2.0, 3.0]).unwrap_err().to_string();
    assert!(e.contains("term 'flaky' takes no target"), "{e}");
}

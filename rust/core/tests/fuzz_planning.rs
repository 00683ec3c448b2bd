//! Property tests of the planner's settings and of plans made with them: `Settings::validate`
//! never panics and accepts exactly the documented ranges (`step`, `max_jump`, `goal_tolerance`
//! positive, finite and at most `Settings::MAX_LENGTH`; `edge_resolution` 0 or in
//! [`MIN_EDGE_RESOLUTION`, `MAX_LENGTH`] and at least `step * max_jump / MAX_EDGE_STATES`;
//! `max_increments`, `max_extensions`, `sample_batch`, `max_empty_batches` >= 1, `sample_batch`
//! at most `MAX_SAMPLE_BATCH`; any `retries`, flags and index), naming a bad field;
//! `Planner::new` agrees with it; and a plan with accepted settings, from any start to any
//! goals, answers `Ok` or `Err`, never a panic, and a success is a path that passes its own
//! checks (finite, from the start to the goal, every state on the manifold and valid).

#[path = "common/fixtures.rs"]
#[allow(dead_code)] // the Panda task is the planning tests'
mod fixtures;
#[path = "common/fuzz.rs"]
mod fuzz;

use std::sync::Arc;

use fixtures::{no_interrupt, Band, CubeSampler, SphereProjector};
use fuzz::{any_f64, any_usize, config, finite};
use genplan_core::planning::{Algorithm, Components, EuclideanSpace, NeighborIndex, PlanError, Planner, Settings};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use rand::rngs::StdRng;
use rand::SeedableRng;

/// The documented range of each field: the fields out of range.
fn out_of_range(s: &Settings) -> Vec<&'static str> {
    let pos = |v: f64| v.is_finite() && v > 0.0 && v <= 1e6;
    let er = s.edge_resolution;
    // findings PLAN-1 (fixed): a bounded resolution, at most 2^20 states on a tree edge
    let er_ok = er == 0.0
        || (er.is_finite() && (1e-6..=1e6).contains(&er) && !(pos(s.step) && pos(s.max_jump) && s.step * s.max_jump / er > (1 << 20) as f64));
    let mut bad = Vec::new();
    for (field, ok) in [
        ("step", pos(s.step)),
        ("max_jump", pos(s.max_jump)),
        ("goal_tolerance", pos(s.goal_tolerance)),
        ("edge_resolution", er_ok),
        ("max_increments", s.max_increments >= 1),
        ("max_extensions", s.max_extensions >= 1),
        // finding PLAN-2 (fixed): at most 2^16 samples per batch
        ("sample_batch", (1..=1 << 16).contains(&s.sample_batch)),
        ("max_empty_batches", s.max_empty_batches >= 1),
    ] {
        if !ok {
            bad.push(field);
        }
    }
    bad
}

fn neighbors() -> impl Strategy<Value = NeighborIndex> {
    prop_oneof![Just(NeighborIndex::Linear), Just(NeighborIndex::KdForest), Just(NeighborIndex::Auto)]
}

type Floats = (f64, usize, f64, f64, usize, usize);
type Rest = (bool, usize, f64, bool, bool, NeighborIndex, usize);

/// Settings from the strategies' tuples (in the order of the fields).
fn settings_of(((step, max_increments, max_jump, goal_tolerance, max_extensions, retries), rest): (Floats, Rest)) -> Settings {
    let (project_samples, sample_batch, edge_resolution, lazy_edges, simplify, neighbors, max_empty_batches) = rest;
    Settings {
        step,
        max_increments,
        max_jump,
        goal_tolerance,
        max_extensions,
        retries,
        project_samples,
        sample_batch,
        edge_resolution,
        lazy_edges,
        simplify,
        neighbors,
        max_empty_batches,
        ..Settings::default()
    }
}

/// Any f64, sometimes at a bound of the ranges or just beyond it.
fn any_length() -> BoxedStrategy<f64> {
    prop_oneof![4 => any_f64(), 1 => prop::sample::select(vec![1e6, 1e6 * (1.0 + 1e-15), 1e-6, 1e-6 * (1.0 - 1e-15), 1.0, 0.3])].boxed()
}

/// Any usize, sometimes at the bound of `sample_batch` or just beyond it.
fn any_count() -> BoxedStrategy<usize> {
    prop_oneof![4 => any_usize(), 1 => prop::sample::select(vec![1usize << 16, (1 << 16) + 1, 1 << 40])].boxed()
}

/// Settings with any value in every field.
fn any_settings() -> impl Strategy<Value = Settings> {
    (
        (any_length(), any_count(), any_length(), any_length(), any_count(), any_usize()),
        (any::<bool>(), any_count(), any_length(), any::<bool>(), any::<bool>(), neighbors(), any_count()),
    )
        .prop_map(settings_of)
}

/// Accepted settings with a small budget (so that a plan ends quickly) and numbers of every
/// magnitude the ranges allow (the smallest and largest included), for either algorithm.
fn small_budget_settings() -> impl Strategy<Value = Settings> {
    let positive = || {
        prop_oneof![
            finite().prop_map(f64::abs).prop_filter("in range", |x| *x > 0.0 && *x <= 1e6),
            0.01..2.0f64,
            Just(1e6),
            (-300.0..6.0f64).prop_map(|e| 10f64.powf(e)),
        ]
    };
    let resolution = prop_oneof![Just(0.0), 1e-4..1.0f64, Just(1e-6), Just(1e6), (-6.0..6.0f64).prop_map(|e| 10f64.powf(e))];
    (
        (positive(), 1usize..8, positive(), positive(), 1usize..40, 0usize..3),
        (any::<bool>(), prop_oneof![1usize..32, Just(1 << 16)], resolution, any::<bool>(), any::<bool>(), neighbors(), 1usize..4),
    )
        .prop_map(settings_of)
        .prop_filter("accepted (edge_resolution >= step * max_jump / 2^20)", |s| s.validate().is_ok())
        .prop_flat_map(|s| (Just(s), any::<bool>()))
        .prop_map(|(s, connect)| Settings { algorithm: if connect { Algorithm::RrtConnect } else { Algorithm::Crrt }, ..s })
}

/// OMPL's sphere demo (the unit sphere in R^3, a band blocked but for a door) with `settings`,
/// from `start` to `goals`: Ok or Err, and a success passes its own checks.
fn plan_on_the_sphere(settings: Settings, start: &[f64], goals: &[f64], seed: u64) -> Result<(), TestCaseError> {
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), settings.clone()).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(seed) };
    let mut projector = SphereProjector { radius: 1.0 };
    let mut checker = Band;
    let mut interrupt = no_interrupt;
    let mut c = Components { sampler: &mut sampler, projector: Some(&mut projector), checker: &mut checker, interrupt: &mut interrupt };
    let finite_input = start.len() == 3 && goals.len() % 3 == 0 && !goals.is_empty() && start.iter().chain(goals).all(|x| x.is_finite());
    match planner.plan(start, goals, &mut c) {
        Err(PlanError::Internal(m)) => return Err(TestCaseError::fail(format!("internal error: {m}"))),
        Err(e) => {
            if !finite_input {
                prop_assert!(matches!(e, PlanError::InvalidStart(_) | PlanError::InvalidGoal(_)), "bad input, not named: {e}");
            }
        }
        Ok(sol) => {
            prop_assert!(finite_input, "a plan from a malformed input succeeded or answered");
            if sol.success {
                let p = &sol.path;
                prop_assert!(p.len() >= 3 && p.len() % 3 == 0 && p.iter().all(|x| x.is_finite()), "a bad path");
                // the start and the goal are replaced by their projections, which move them by at
                // most goal_tolerance (Planner::plan)
                let tol = 2.0 * settings.goal_tolerance.max(1e-9);
                prop_assert!(dist(&p[..3], start) <= tol, "the path begins {} from the start", dist(&p[..3], start));
                let g = sol.goal_index.expect("a success names its goal");
                let d = dist(&p[p.len() - 3..], &goals[3 * g..3 * g + 3]);
                prop_assert!(d <= tol, "the path ends {d} from its goal");
                for q in p.chunks(3) {
                    let r = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                    prop_assert!((r - 1.0).abs() < 1e-9, "a path state off the sphere: {q:?}");
                    prop_assert!(Band::ok(q), "a path state in the band: {q:?}");
                }
            } else {
                prop_assert!(sol.path.is_empty() && sol.goal_index.is_none());
            }
        }
    }
    Ok(())
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

/// Points on or near the unit sphere, off it, malformed.
fn point() -> impl Strategy<Value = Vec<f64>> {
    prop_oneof![
        6 => (-1.0..1.0f64, -1.0..1.0f64, prop_oneof![Just(1.0), Just(-1.0)]).prop_map(|(x, y, s)| {
            let z = s * (1.0 - (x * x + y * y).min(1.0)).sqrt();
            vec![x, y, z]
        }),
        1 => Just(vec![0.0, 0.0, -1.0]),
        1 => Just(vec![0.0, 0.0, 1.0]),
        2 => proptest::collection::vec(any_f64(), 3),
        1 => proptest::collection::vec(any_f64(), 0..5),
    ]
}

proptest! {
    #![proptest_config(config(256))]

    /// validate() accepts exactly the documented ranges, and a refusal names a field out of range.
    #[test]
    fn validate_accepts_exactly_the_documented_ranges(s in any_settings()) {
        let bad = out_of_range(&s);
        match s.validate() {
            Ok(()) => prop_assert!(bad.is_empty(), "accepted with {:?} out of range: {:?}", bad, s),
            Err(PlanError::Settings { field, msg }) => {
                prop_assert!(bad.contains(&field), "refused naming {} ({}), out of range: {:?}", field, msg, bad);
                prop_assert!(!msg.is_empty());
            }
            Err(other) => prop_assert!(false, "refused with another error: {}", other),
        }
        prop_assert_eq!(Planner::new(Arc::new(EuclideanSpace(3)), s.clone()).is_ok(), bad.is_empty());
    }

    /// Plans with accepted settings and any start and goals (on the manifold or not, malformed).
    #[test]
    fn plans_with_accepted_settings_answer(
        s in small_budget_settings(),
        start in point(),
        goals in proptest::collection::vec(point(), 0..3),
        seed in 0u64..1000,
    ) {
        prop_assert!(s.validate().is_ok());
        plan_on_the_sphere(s, &start, &goals.concat(), seed)?;
    }
}

#[test]
fn the_default_settings_plan_through_the_door() {
    plan_on_the_sphere(Settings::default(), &[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], 0).unwrap();
}

/// The refusal of `s`: the field named and the message.
fn refusal(s: &Settings) -> (&'static str, String) {
    assert!(Planner::new(Arc::new(EuclideanSpace(3)), s.clone()).is_err(), "Planner::new accepted {s:?}");
    match s.validate() {
        Err(e @ PlanError::Settings { .. }) => {
            let text = e.to_string();
            let PlanError::Settings { field, .. } = e else { unreachable!() };
            (field, text)
        }
        other => panic!("expected a settings error, got {other:?}"),
    }
}

/// PLAN-1 (fixed): `validate` accepted any finite `edge_resolution` > 0, but validating an edge
/// allocates (distance / edge_resolution) states: 1e-300 overflowed the state count (a panic,
/// "attempt to multiply with overflow" here, "capacity overflow" in a release build, i.e. a
/// PanicException in Python), and 1e-9 asked for tens of GB (an abort when the allocation
/// failed). Now the resolution is 0 or in [1e-6, 1e6], and fine enough for at most 2^20 states
/// on a tree edge (max_jump * step long), refused with a settings error naming it.
#[test]
fn finding_plan_1_a_tiny_edge_resolution_is_refused() {
    for er in [1e-300, 5e-324, 1e-9, 9.9e-7] {
        let (field, msg) = refusal(&Settings { edge_resolution: er, ..Settings::default() });
        assert_eq!(field, "edge_resolution");
        assert_eq!(msg, format!("settings: edge_resolution must be 0 (no edge validation) or at least 1e-6, got {er:?}"));
    }
    for er in [1.000001e6, 1e300, f64::MAX] {
        let (field, msg) = refusal(&Settings { edge_resolution: er, ..Settings::default() });
        assert_eq!(field, "edge_resolution");
        assert_eq!(msg, format!("settings: edge_resolution must be at most 1e6, got {er:?}"));
    }
    for er in [-1e-3, f64::NAN, f64::INFINITY] {
        let (field, msg) = refusal(&Settings { edge_resolution: er, ..Settings::default() });
        assert_eq!(field, "edge_resolution");
        assert_eq!(msg, format!("settings: edge_resolution must be >= 0, got {er}"));
    }
    // the smallest resolution with the default step and jump: 900000 states on the longest edge
    let s = Settings { edge_resolution: 1e-6, ..Settings::default() };
    assert!(s.validate().is_ok());
    // ... but not with longer steps: 3e6 states
    let (field, msg) = refusal(&Settings { step: 1.0, ..s.clone() });
    assert_eq!(field, "edge_resolution");
    assert_eq!(
        msg,
        "settings: edge_resolution must be at least step * max_jump / 1048576 = 2.86102294921875e-6 \
         (at most 1048576 states on a tree edge of up to step * max_jump = 3.0 long), got 1e-6"
    );
    // the plan of the finding now answers (0 disables edge validation, as before)
    plan_on_the_sphere(Settings { edge_resolution: 0.0, ..Settings::default() }, &[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], 0).unwrap();
}

/// The lengths are bounded too (their products, `step * max_jump`, stay finite).
#[test]
fn huge_lengths_are_refused() {
    for (field, s) in [
        ("step", Settings { step: 1e300, ..Settings::default() }),
        ("max_jump", Settings { max_jump: f64::MAX, ..Settings::default() }),
        ("goal_tolerance", Settings { goal_tolerance: 1.000001e6, ..Settings::default() }),
    ] {
        let (f, msg) = refusal(&s);
        assert_eq!(f, field);
        assert!(msg.starts_with(&format!("settings: {field} must be at most 1e6, got ")), "{msg}");
    }
}

/// PLAN-2 (fixed): `validate` accepted any `sample_batch` >= 1, but the planner allocates
/// sample_batch x nq numbers per batch: usize::MAX overflowed (a panic), and 2^40 asked for
/// terabytes (an abort). Now sample_batch is at most 2^16, refused with a settings error.
#[test]
fn finding_plan_2_a_huge_sample_batch_is_refused() {
    for n in [usize::MAX, 1 << 40, (1 << 16) + 1] {
        let (field, msg) = refusal(&Settings { sample_batch: n, ..Settings::default() });
        assert_eq!(field, "sample_batch");
        assert_eq!(msg, format!("settings: sample_batch must be in [1, 65536], got {n}"));
    }
    let s = Settings { sample_batch: 1 << 16, max_extensions: 3, ..Settings::default() };
    assert!(s.validate().is_ok());
    plan_on_the_sphere(s, &[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], 0).unwrap();
}

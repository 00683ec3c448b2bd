//! Property tests of the planner's settings and of plans made with them: `Settings::validate`
//! never panics and accepts exactly the documented ranges (`step`, `max_jump`, `goal_tolerance`
//! positive and finite; `edge_resolution` finite and >= 0; `max_increments`, `max_extensions`,
//! `sample_batch`, `max_empty_batches` >= 1; any `retries`, flags and index), naming a bad
//! field; `Planner::new` agrees with it; and a plan with accepted settings, from any start to any
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
use genplan_core::planning::{Components, EuclideanSpace, NeighborIndex, PlanError, Planner, Settings};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use rand::rngs::StdRng;
use rand::SeedableRng;

/// The documented range of each field: the first field out of range, or None.
fn out_of_range(s: &Settings) -> Vec<&'static str> {
    let pos = |v: f64| v.is_finite() && v > 0.0;
    let mut bad = Vec::new();
    for (field, ok) in [
        ("step", pos(s.step)),
        ("max_jump", pos(s.max_jump)),
        ("goal_tolerance", pos(s.goal_tolerance)),
        ("edge_resolution", s.edge_resolution.is_finite() && s.edge_resolution >= 0.0),
        ("max_increments", s.max_increments >= 1),
        ("max_extensions", s.max_extensions >= 1),
        ("sample_batch", s.sample_batch >= 1),
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

/// Settings with any value in every field.
fn any_settings() -> impl Strategy<Value = Settings> {
    (
        (any_f64(), any_usize(), any_f64(), any_f64(), any_usize(), any_usize()),
        (any::<bool>(), any_usize(), any_f64(), any::<bool>(), any::<bool>(), neighbors(), any_usize()),
    )
        .prop_map(settings_of)
}

/// Accepted settings with a small budget (so that a plan ends quickly) and numbers of every
/// magnitude; `edge_resolution` is 0 or at least 1e-4 (finding PLAN-1: smaller ones make a plan
/// allocate beyond memory).
fn small_budget_settings() -> impl Strategy<Value = Settings> {
    let positive = || prop_oneof![finite().prop_map(f64::abs).prop_filter("positive", |x| *x > 0.0), 0.01..2.0f64];
    (
        (positive(), 1usize..8, positive(), positive(), 1usize..40, 0usize..3),
        (any::<bool>(), 1usize..32, prop_oneof![Just(0.0), 1e-4..1.0f64, Just(1e300)], any::<bool>(), any::<bool>(), neighbors(), 1usize..4),
    )
        .prop_map(settings_of)
}

/// OMPL's sphere demo (the unit sphere in R^3, a band blocked but for a door) with `settings`,
/// from `start` to `goals`: Ok or Err, and a success passes its own checks.
fn plan_on_the_sphere(settings: Settings, start: &[f64], goals: &[f64], seed: u64) -> Result<(), TestCaseError> {
    let planner = Planner::new(Arc::new(EuclideanSpace(3)), settings.clone()).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let mut sampler = CubeSampler { dim: 3, half: 1.0, rng: StdRng::seed_from_u64(seed) };
    let mut projector = SphereProjector { radius: 1.0 };
    let mut checker = Band;
    let mut interrupt = no_interrupt;
    let mut c = Components { sampler: &mut sampler, projector: &mut projector, checker: &mut checker, interrupt: &mut interrupt };
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

/// PLAN-1: `validate` accepts any finite `edge_resolution` > 0, but validating an edge
/// allocates (distance / edge_resolution) states: 1e-300 overflows the state count (a panic,
/// "attempt to multiply with overflow" here, "capacity overflow" in a release build, i.e. a
/// PanicException in Python), and 1e-9 asks for tens of GB (an abort when the allocation fails).
/// The range should be bounded below (or the count checked) with a SettingsError.
#[test]
#[should_panic(expected = "overflow")]
fn finding_plan_1_a_tiny_edge_resolution_overflows_the_edge_states() {
    let s = Settings { edge_resolution: 1e-300, ..Settings::default() };
    assert!(s.validate().is_ok());
    let _ = plan_on_the_sphere(s, &[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], 0);
}

/// PLAN-2: `validate` accepts any `sample_batch` >= 1, but the planner allocates sample_batch x nq
/// numbers per batch: usize::MAX overflows (a panic), and ~1e12 asks for terabytes (an abort).
#[test]
#[should_panic(expected = "overflow")]
fn finding_plan_2_a_huge_sample_batch_overflows_the_sample_buffer() {
    let s = Settings { sample_batch: usize::MAX, ..Settings::default() };
    assert!(s.validate().is_ok());
    let _ = plan_on_the_sphere(s, &[0.0, 0.0, -1.0], &[0.0, 0.0, 1.0], 0);
}

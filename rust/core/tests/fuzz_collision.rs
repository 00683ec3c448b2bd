//! Property tests of the kinematic model and the collision world on random configurations and
//! obstacles, NaN, inf and extreme magnitudes included: every query answers `Ok` or `Err`, never
//! a panic; `Err` exactly for a malformed input (wrong length, not finite, a zero base
//! quaternion, a revolute or prismatic joint beyond `MAX_JOINT_POSITION`, a bad obstacle: sizes and coordinates beyond `MAX_OBSTACLE_EXTENT`, a rotation
//! that is not a unit quaternion, a zero normal); an `Ok` is finite (poses rigid, distances not
//! NaN) and the answers agree with each other (the filtered collision check with the exhaustive
//! one, the signed distance with the collision check, close pairs with the margin), whatever
//! obstacles were accepted.

#[path = "common/fuzz.rs"]
mod fuzz;

use std::sync::Arc;

use fuzz::{any_f64, config, finite, rigid_and_finite};
use genplan_core::collision::{CollisionWorld, MAX_OBSTACLE_EXTENT};
use genplan_core::kinematics::{KinematicModel, ModelOptions, Motion};
use genplan_core::urdf::{Urdf, MAX_JOINT_POSITION};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// An arm with every primitive shape, a prismatic and a continuous joint, and a second branch
/// that can reach the first.
const SHAPES: &str = r#"<robot name="shapes">
  <link name="base"><collision><geometry><box size="0.4 0.4 0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.2" rpy="0 0.1 0"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></collision></link>
  <link name="l2"><collision><geometry><capsule radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="tool"><collision><geometry><sphere radius="0.05"/></geometry></collision>
    <collision><origin xyz="0.1 0 0"/><geometry><box size="0.05 0.05 0.05"/></geometry></collision></link>
  <link name="other"><collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.1"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/>
    <axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="tool"/><origin xyz="0 0 0.2" rpy="0.3 0 0"/>
    <axis xyz="0 1 0"/></joint>
  <joint name="j4" type="revolute"><parent link="base"/><child link="other"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
</robot>"#;

fn world(floating_base: bool) -> CollisionWorld {
    let urdf = Urdf::parse(SHAPES).unwrap();
    let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions { floating_base, ..Default::default() }).unwrap());
    CollisionWorld::from_urdf(model, &urdf, &[], None).unwrap()
}

/// An obstacle to add: its kind and numbers (any).
#[derive(Debug, Clone)]
enum Obstacle {
    Box { half: [f64; 3], center: [f64; 3], quat: [f64; 4] },
    Sphere { radius: f64, center: [f64; 3] },
    Halfspace { normal: [f64; 3], offset: f64 },
}

/// Mostly sane numbers, sometimes anything, sometimes at the bound `MAX_OBSTACLE_EXTENT` or just
/// beyond it.
fn number(sane: std::ops::Range<f64>) -> BoxedStrategy<f64> {
    let m = MAX_OBSTACLE_EXTENT;
    prop_oneof![8 => sane, 2 => any_f64(), 1 => prop::sample::select(vec![m, -m, m * (1.0 + 1e-15), -m * (1.0 + 1e-15), m - 1.0])].boxed()
}

fn obstacle() -> BoxedStrategy<Obstacle> {
    let v3 = |r: std::ops::Range<f64>| proptest::array::uniform3(number(r));
    prop_oneof![
        (v3(0.01..0.5), v3(-1.0..1.0), proptest::array::uniform4(number(-1.0..1.0)))
            .prop_map(|(half, center, quat)| Obstacle::Box { half, center, quat }),
        (number(0.01..0.5), v3(-1.0..1.0)).prop_map(|(radius, center)| Obstacle::Sphere { radius, center }),
        (v3(-1.0..1.0), number(-1.0..0.2)).prop_map(|(normal, offset)| Obstacle::Halfspace { normal, offset }),
    ]
    .boxed()
}

/// Add it; Err exactly when its numbers are bad (as documented per kind: finite, sizes positive
/// and at most `MAX_OBSTACLE_EXTENT`, coordinates within it, a unit rotation, a normal longer
/// than 1e-12 -- findings COL-2 and COL-3, fixed).
fn add(w: &mut CollisionWorld, name: &str, o: &Obstacle) -> Result<(), TestCaseError> {
    let fin = |v: &[f64]| v.iter().all(|x| x.is_finite());
    let within = |v: &[f64]| v.iter().all(|x| x.abs() <= MAX_OBSTACLE_EXTENT);
    let size = |v: &[f64]| v.iter().all(|x| *x > 0.0 && *x <= MAX_OBSTACLE_EXTENT);
    let (result, ok) = match o {
        Obstacle::Box { half, center, quat } => {
            let q = Quaternion::new(quat[3], quat[0], quat[1], quat[2]);
            let rot = UnitQuaternion::from_quaternion(q);
            let pose = Isometry3::from_parts(Translation3::new(center[0], center[1], center[2]), rot);
            let r = rot.coords;
            // a quaternion whose norm overflows or underflows does not normalise to a unit one
            let pose_ok = fin(center) && within(center) && r.iter().all(|x| x.is_finite()) && (r.norm() - 1.0).abs() <= 1e-6;
            (w.add_box(name, *half, pose), fin(half) && size(half) && pose_ok)
        }
        Obstacle::Sphere { radius, center } => (w.add_sphere(name, *radius, *center), fin(center) && within(center) && size(&[*radius])),
        Obstacle::Halfspace { normal, offset } => {
            let norm = normal[0].hypot(normal[1]).hypot(normal[2]); // without overflow
            (w.add_halfspace(name, *normal, *offset), fin(normal) && offset.is_finite() && within(&[*offset]) && norm > 1e-12)
        }
    };
    prop_assert_eq!(result.is_ok(), ok, "add {:?}: {:?}", o, result.err().map(|e| e.to_string()));
    Ok(())
}

/// A configuration for the world: in range, any numbers, huge, at `MAX_JOINT_POSITION` or just
/// beyond it, or malformed.
fn configuration(nq: usize) -> BoxedStrategy<Vec<f64>> {
    let m = MAX_JOINT_POSITION;
    let at_bound = prop_oneof![3 => -3.0..3.0f64, 1 => prop::sample::select(vec![m, -m, m * (1.0 + 1e-15), -m * (1.0 + 1e-15)])];
    prop_oneof![
        4 => proptest::collection::vec(-3.0..3.0f64, nq),
        2 => proptest::collection::vec(finite(), nq),
        1 => proptest::collection::vec(at_bound, nq),
        2 => proptest::collection::vec(any_f64(), nq),
        1 => proptest::collection::vec(any_f64(), 0..nq + 3),
    ]
    .boxed()
}

/// Every query on `q` (see the module doc).
fn check_queries(w: &CollisionWorld, q: &[f64], margin: f64) -> Result<(), TestCaseError> {
    let m = &w.model;
    let mut malformed = q.len() != m.nq || q.iter().any(|x| !x.is_finite());
    if !malformed && m.floating_base {
        malformed = q[3..7].iter().map(|x| x * x).sum::<f64>().sqrt() < 1e-9;
    }
    // a revolute or prismatic joint's value beyond MAX_JOINT_POSITION (finding URDF-7, fixed: a
    // prismatic one put links past what an f64 holds); a continuous joint's (cos, sin) and the
    // free-flyer base take any finite values (a huge base quaternion is normalised: URDF-3)
    malformed |= m.joints.iter().any(|j| {
        matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. })
            && q.get(j.q_index).is_some_and(|x| x.abs() > MAX_JOINT_POSITION)
    });
    let mut poses = Vec::new();
    let fk = m.forward_kinematics(q, &mut poses);
    prop_assert_eq!(fk.is_err(), malformed, "FK on {:?}: {:?}", q, fk.err().map(|e| e.to_string()));
    if fk.is_ok() {
        rigid_and_finite(&poses).map_err(|e| TestCaseError::fail(format!("FK at {q:?}: {e}")))?;
    }
    let hit = w.in_collision(q);
    prop_assert_eq!(hit.is_err(), malformed);
    let exhaustive = w.in_collision_exhaustive(q);
    prop_assert_eq!(exhaustive.is_err(), malformed);
    let d = w.min_distance(q);
    prop_assert_eq!(d.is_err(), malformed);
    let pairs = w.close_pairs(q, margin);
    prop_assert_eq!(pairs.is_err(), malformed || !margin.is_finite());
    if malformed {
        return Ok(());
    }
    let (hit, exhaustive, d) = (hit.unwrap(), exhaustive.unwrap(), d.unwrap());
    prop_assert_eq!(hit, exhaustive, "the filtered check disagrees with the exhaustive one at {:?}", q);
    prop_assert!(!d.is_nan(), "min_distance is NaN at {:?}", q);
    if hit {
        prop_assert!(d <= 1e-9, "in collision, but min_distance {} at {:?}", d, q);
    } else {
        prop_assert!(d >= -1e-9, "not in collision, but min_distance {} at {:?}", d, q);
    }
    if let Ok(pairs) = pairs {
        for (k, p) in pairs.iter().enumerate() {
            prop_assert!(p.distance < margin && !p.distance.is_nan(), "close pair {:?} beyond the margin {}", p, margin);
            prop_assert!(k == 0 || pairs[k - 1].distance <= p.distance, "close pairs not sorted");
        }
        if let Some(first) = pairs.first() {
            prop_assert!((first.distance - d).abs() < 1e-6, "closest pair {} != min_distance {}", first.distance, d);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(256))]

    /// Fixed-base world with random obstacles, random configurations.
    #[test]
    fn fixed_base_queries_answer(
        obstacles in proptest::collection::vec(obstacle(), 0..4),
        qs in proptest::collection::vec(configuration(5), 1..4),
        margin in prop_oneof![4 => 0.0..0.5f64, 1 => any_f64()],
        check_self in any::<bool>(),
    ) {
        {
            let mut w = world(false);
            w.check_self = check_self;
            for (i, o) in obstacles.iter().enumerate() {
                add(&mut w, &format!("o{i}"), o)?;
            }
            if !w.obstacles.is_empty() {
                prop_assert!(w.add_sphere(&w.obstacles[0].name.clone(), 0.1, [0.0; 3]).is_err(), "a second obstacle of the same name");
            }
            for q in &qs {
                check_queries(&w, q, margin)?;
            }
        }
    }

    /// Free-flyer world: the base anywhere, any orientation (a zero quaternion is refused).
    #[test]
    fn floating_base_queries_answer(
        obstacles in proptest::collection::vec(obstacle(), 0..3),
        qs in proptest::collection::vec(configuration(12), 1..4),
        margin in 0.0..0.5f64,
    ) {
        {
            let mut w = world(true);
            for (i, o) in obstacles.iter().enumerate() {
                add(&mut w, &format!("o{i}"), o)?;
            }
            for q in &qs {
                check_queries(&w, q, margin)?;
            }
        }
    }
}

/// COL-1 (fixed): `min_distance` under-reported penetration: once a penetrating pair was found
/// (best < 0), every later pair whose bounding boxes overlap was skipped, because its box gap (0)
/// bounds only a separated pair's distance. Here the capsule of l2 sinks 0.04 into the tool's
/// sphere; min_distance answered -0.0012 (the base box and l1's cylinder, found first).
#[test]
fn min_distance_is_the_deepest_penetration() {
    let w = world(false);
    check_queries(&w, &[0.0, -0.08423396814923613, 0.0, 0.0, 0.0], 0.0).unwrap();
}

/// COL-2 (fixed): a half-space normal whose squared norm overflows (`[0, 0, 1e300]`) was
/// normalised to the zero vector; the world then held a degenerate half-space: min_distance
/// answered 0 where the plane z = 0 cuts the base box 0.05 deep. Now the norm is computed on the
/// normal scaled by its largest component: any finite normal longer than 1e-12 is normalised
/// right, a shorter one is refused as zero.
#[test]
fn finding_col_2_an_overflowing_half_space_normal_is_normalised() {
    let distance_with = |normal: [f64; 3], offset: f64| {
        let mut w = world(false);
        w.check_self = false; // the base box and l1's cylinder touch
        w.add_halfspace("floor", normal, offset).expect("accepted");
        check_queries(&w, &[0.0; 5], 0.1).unwrap();
        w.min_distance(&[0.0; 5]).unwrap()
    };
    for offset in [0.0, 0.02, -0.3] {
        let unit = distance_with([0.0, 0.0, 1.0], offset);
        for normal in [[0.0, 0.0, 1e300], [0.0, 0.0, f64::MAX], [0.0, 0.0, 2e-12], [0.0, -0.0, 7.0]] {
            let d = distance_with(normal, offset);
            assert!((d - unit).abs() < 1e-12, "normal {normal:?}, offset {offset}: min_distance {d}, with [0, 0, 1]: {unit}");
        }
    }
    let d = distance_with([0.0, 0.0, 1e300], 0.0);
    assert!((d + 0.05).abs() < 1e-9, "{d}");
    // a diagonal normal of huge components: (1, 1, 1) / sqrt 3
    let d = distance_with([f64::MAX, f64::MAX, f64::MAX], 0.0);
    assert!((d - distance_with([1.0, 1.0, 1.0], 0.0)).abs() < 1e-12);
    // zero, or too short to have a direction
    for normal in [[0.0; 3], [0.0, 0.0, 1e-12], [5e-324, 0.0, 0.0], [1e-200, 1e-200, 0.0]] {
        let e = world(false).add_halfspace("floor", normal, 0.0).unwrap_err();
        assert_eq!(e.to_string(), "plane 'floor': the normal is zero", "{normal:?}");
    }
}

/// COL-3 (fixed): obstacles whose numbers were finite but absurd (a sphere of radius 1e200 at
/// y = 1e300) were accepted; squared norms overflowed: the exact (exhaustive) check reported a
/// collision with a sphere 1e300 away, and min_distance answered inf for a 1 m sphere 1e200
/// away (pairs dropped). Now sizes and coordinates beyond `MAX_OBSTACLE_EXTENT` (1e6 m) are
/// refused, naming the obstacle and the field.
#[test]
fn finding_col_3_absurd_obstacle_magnitudes_are_refused() {
    let mut w = world(false);
    w.check_self = false;
    let refused = |r: genplan_core::Result<()>| r.unwrap_err().to_string();
    assert_eq!(
        refused(w.add_sphere("far", 2.5836478361061263e200, [0.0, 1e300, 0.0])),
        "sphere 'far': radius must be positive and at most 1e6 m, got 2.5836478361061263e200"
    );
    assert_eq!(
        refused(w.add_sphere("far", 1.0, [0.0, 1e200, 0.0])),
        "sphere 'far': centre must be within 1e6 m of the origin in each coordinate, got [0.0, 1e200, 0.0]"
    );
    assert_eq!(
        refused(w.add_box("slab", [1.0, 2e6, 1.0], Isometry3::identity())),
        "box 'slab': half extents must be positive and at most 1e6 m, got [1.0, 2000000.0, 1.0]"
    );
    assert_eq!(
        refused(w.add_box("slab", [1.0; 3], Isometry3::translation(0.0, 0.0, -1.5e6))),
        "box 'slab': centre must be within 1e6 m of the origin in each coordinate, got [0.0, 0.0, -1500000.0]"
    );
    let not_unit = Isometry3::from_parts(Translation3::identity(), UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0)));
    assert_eq!(refused(w.add_box("slab", [1.0; 3], not_unit)), "box 'slab': the pose's rotation is not a unit quaternion (norm 2.0)");
    assert_eq!(
        refused(w.add_halfspace("floor", [0.0, 0.0, 1.0], -1e300)),
        "plane 'floor': offset must be at most 1e6 m in absolute value, got -1e300"
    );
    assert!(w.obstacles.is_empty());
    // at the bounds: accepted, and the answers agree (a ball whose top is 0.95 m below the base
    // box's bottom face, at z = -0.05; a slab and a wall 1e6 m away)
    w.add_sphere("ground", 999_999.0, [0.0, 0.0, -1e6]).unwrap();
    w.add_box("slab", [1e6 - 2.0, 1e6, 1e6], Isometry3::translation(1e6, 0.0, 0.0)).unwrap();
    w.add_halfspace("wall", [-f64::MAX, 0.0, 0.0], -1e6).unwrap(); // x >= 1e6
    check_queries(&w, &[0.0; 5], 0.5).unwrap();
    let d = w.min_distance(&[0.0; 5]).unwrap();
    assert!((d - 0.95).abs() < 1e-6, "min_distance {d}, expected 0.95 (the ground)");
}

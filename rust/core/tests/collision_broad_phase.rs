//! The broad phase over obstacles (the hierarchy in src/collision/obstacles.rs, used by
//! `CollisionWorld::in_collision_unchecked`, `min_distance_unchecked` and `close_pairs` in
//! src/collision/world.rs) against an exhaustive check written here with parry alone: every robot
//! geometry against every obstacle, and every self pair, on random scenes of many boxes,
//! spheres, capsules, cylinders and a few half-spaces, at random configurations, as obstacles
//! are added, removed and cleared.

use genplan_core::collision::CollisionWorld;
use genplan_core::robot::preset;
use genplan_core::Scratch;
use nalgebra::{Isometry3, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::SharedShape;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Signed distance of two shapes (negative: penetration depth), as the world defines it: the
/// contact depth when they intersect (the half-space first, the order parry gets right), else
/// the distance.
fn signed_distance(pa: &Isometry3<f64>, a: &SharedShape, pb: &Isometry3<f64>, b: &SharedShape) -> f64 {
    if query::intersection_test(pa, &**a, pb, &**b).unwrap() {
        let c = if b.as_halfspace().is_some() {
            query::contact(pb, &**b, pa, &**a, 0.0)
        } else {
            query::contact(pa, &**a, pb, &**b, 0.0)
        };
        c.unwrap().map_or(0.0, |c| c.dist.min(0.0))
    } else {
        query::distance(pa, &**a, pb, &**b).unwrap()
    }
}

/// A checked pair: the two shapes at their poses, and their names.
type Pair = (Isometry3<f64>, SharedShape, Isometry3<f64>, SharedShape, String, String);

/// Every pair the world checks.
fn all_pairs(w: &CollisionWorld, q: &[f64]) -> Vec<Pair> {
    let mut links = Vec::new();
    w.model.forward_kinematics(q, &mut links).unwrap();
    let poses: Vec<Isometry3<f64>> = w.geometries().iter().map(|g| links[g.link] * g.offset).collect();
    let mut out = Vec::new();
    for (i, g) in w.geometries().iter().enumerate() {
        for o in w.obstacles.iter() {
            out.push((poses[i], g.shape.clone(), o.pose, o.shape.clone(), g.name.clone(), o.name.clone()));
        }
    }
    if w.check_self {
        for &(i, j) in w.self_pairs() {
            let (a, b) = (&w.geometries()[i], &w.geometries()[j]);
            out.push((poses[i], a.shape.clone(), poses[j], b.shape.clone(), a.name.clone(), b.name.clone()));
        }
    }
    out
}

/// Random boxes, spheres, capsules and cylinders within `spread` of the Panda's shoulder, and a
/// half-space one time in twenty.
fn scatter(w: &mut CollisionWorld, rng: &mut StdRng, n: usize, spread: f64, tag: &str) {
    for k in 0..n {
        let name = format!("{tag}{k}");
        let c = Vector3::new(rng.random_range(-spread..spread), rng.random_range(-spread..spread), 0.3 + rng.random_range(-spread..spread));
        let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let pose = Isometry3::new(c, axis * rng.random_range(0.0..3.0));
        let size = |rng: &mut StdRng| rng.random_range(0.01..0.15);
        match rng.random_range(0..20) {
            0..=5 => w.add_box(&name, [size(rng), size(rng), size(rng)], pose).unwrap(),
            6..=10 => w.add_sphere(&name, size(rng), c.into()).unwrap(),
            11..=15 => w.add_capsule(&name, size(rng), size(rng), pose).unwrap(),
            16..=18 => w.add_cylinder(&name, size(rng), size(rng), pose).unwrap(),
            _ => {
                let n = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
                w.add_halfspace(&name, n, rng.random_range(-2.0..-0.6)).unwrap()
            }
        }
    }
}

/// Compare the world's answers with the exhaustive ones on `qs`; the number in collision.
fn compare(w: &CollisionWorld, qs: &[Vec<f64>]) -> usize {
    let mut s = Scratch::default();
    let mut hits = 0;
    for q in qs {
        let pairs = all_pairs(w, q);
        let want_hit = pairs.iter().any(|(pa, a, pb, b, _, _)| query::intersection_test(pa, &**a, pb, &**b).unwrap());
        let dists: Vec<f64> = pairs.iter().map(|(pa, a, pb, b, _, _)| signed_distance(pa, a, pb, b)).collect();
        let want_d = dists.iter().copied().fold(f64::INFINITY, f64::min);

        let hit = w.in_collision_unchecked(q, &mut s);
        assert_eq!(hit, want_hit, "in_collision at {q:?}");
        assert_eq!(w.in_collision(q).unwrap(), want_hit);
        assert_eq!(w.in_collision_exhaustive(q).unwrap(), want_hit);
        let d = w.min_distance_unchecked(q, &mut s);
        assert_eq!(d, w.min_distance(q).unwrap());
        // the same pair distances, so equal up to parry's own round-off between the orders
        assert!((d - want_d).abs() <= 1e-9 * (1.0 + want_d.abs()) || d == want_d, "min_distance {d} vs exhaustive {want_d} at {q:?}");

        // close pairs: exactly the pairs closer than the margin, with their distances
        let margin = 0.05;
        let got = w.close_pairs(q, margin).unwrap();
        let mut want: Vec<(String, String, f64)> = pairs
            .iter()
            .zip(&dists)
            .filter(|(_, &d)| d < margin)
            .map(|((_, _, _, _, a, b), &d)| (a.clone(), b.clone(), d))
            .collect();
        want.sort_by(|x, y| x.2.total_cmp(&y.2));
        assert_eq!(got.len(), want.len(), "close pairs at {q:?}");
        for (g, (a, b, d)) in got.iter().zip(&want) {
            assert!((g.distance - d).abs() < 1e-9, "close pair {g:?} vs {a} {b} {d}");
        }
        let mut names: Vec<(&str, &str)> = got.iter().map(|p| (p.a.as_str(), p.b.as_str())).collect();
        let mut want_names: Vec<(&str, &str)> = want.iter().map(|(a, b, _)| (a.as_str(), b.as_str())).collect();
        names.sort();
        want_names.sort();
        assert_eq!(names, want_names);
        hits += hit as usize;
    }
    hits
}

#[test]
fn broad_phase_answers_as_the_exhaustive_check_on_random_scenes() {
    let (model, base) = preset("panda").unwrap().load().unwrap();
    let mut rng = StdRng::seed_from_u64(17);
    // 48 configurations: every scene is compared four ways, each against an exhaustive parry
    // check (minutes in a debug build, CI's, with more)
    let qs: Vec<Vec<f64>> =
        (0..48).map(|_| model.lower.iter().zip(&model.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect()).collect();
    let (mut hits, mut free) = (0, 0);
    // scenes from empty to cluttered: far and sparse, near and dense
    for (n, spread) in [(0, 1.0), (1, 0.4), (40, 2.0), (150, 1.2), (250, 0.7)] {
        let mut w = base.clone();
        scatter(&mut w, &mut rng, n, spread, "o");
        let h = compare(&w, &qs);
        hits += h;
        free += qs.len() - h;
        for k in (0..n).step_by(2) {
            w.remove_obstacle(&format!("o{k}")).unwrap();
        }
        scatter(&mut w, &mut rng, n / 3, spread, "p");
        compare(&w, &qs);
        w.check_self = false;
        compare(&w, &qs);
        w.clear_obstacles();
        assert!(w.obstacles.is_empty());
        compare(&w, &qs);
    }
    assert!(hits > 60 && free > 60, "{hits} in collision, {free} free: both kinds must be met");
}

#[test]
fn extra_obstacles_out_of_reach_change_no_answer() {
    // 200 boxes 1.6 to 3 m from the base (the Panda reaches about 1.2 m): the same answers as
    // without them, however they are indexed
    let (model, base) = preset("panda").unwrap().load().unwrap();
    let mut rng = StdRng::seed_from_u64(23);
    let mut w = base.clone();
    for k in 0..200 {
        let (r, a) = (rng.random_range(1.6..3.0), rng.random_range(0.0..std::f64::consts::TAU));
        let c = Vector3::new(r * f64::cos(a), r * f64::sin(a), rng.random_range(-0.4..1.6));
        w.add_box(&format!("far{k}"), [0.15, 0.15, 0.15], Isometry3::translation(c.x, c.y, c.z)).unwrap();
    }
    let (mut s, mut r) = (Scratch::default(), Scratch::default());
    let mut any_hit = false;
    for _ in 0..2000 {
        let q: Vec<f64> = model.lower.iter().zip(&model.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect();
        let hit = w.in_collision_unchecked(&q, &mut s);
        assert_eq!(hit, base.in_collision_unchecked(&q, &mut r));
        any_hit |= hit;
        let d = w.min_distance_unchecked(&q, &mut s);
        let d0 = base.min_distance_unchecked(&q, &mut r);
        assert!(d <= d0, "more obstacles cannot be farther");
        assert!(d > 0.0 || d == d0, "a far box in contact");
    }
    assert!(any_hit, "self-collisions occur among 2000 random configurations");
}

#[test]
fn talos_self_collision_as_the_exhaustive_check() {
    // self-collision only (no obstacles): the filtered pair loop against parry on every pair
    let (model, w) = preset("talos").unwrap().load().unwrap();
    let mut rng = StdRng::seed_from_u64(29);
    let mut s = Scratch::default();
    let (mut hits, mut n) = (0, 0);
    for _ in 0..150 {
        let mut q: Vec<f64> = model
            .lower
            .iter()
            .zip(&model.upper)
            .map(|(&l, &u)| if l.is_finite() && u.is_finite() { rng.random_range(l..=u) } else { 0.0 })
            .collect();
        q[2] = 1.0;
        q[6] = 1.0;
        let pairs = all_pairs(&w, &q);
        let want = pairs.iter().any(|(pa, a, pb, b, _, _)| query::intersection_test(pa, &**a, pb, &**b).unwrap());
        assert_eq!(w.in_collision_unchecked(&q, &mut s), want, "at {q:?}");
        assert_eq!(w.in_collision_exhaustive(&q).unwrap(), want);
        hits += want as usize;
        n += 1;
    }
    assert!(hits > 10 && hits < n - 10, "{hits} of {n} in collision: both kinds must be met");
}

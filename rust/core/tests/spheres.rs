//! The sphere check (src/collision/spheres.rs) and its planner checker
//! (`planning::SphereChecker`): each obstacle shape's closed-form test against the exact world
//! on a robot that is one sphere, conservativeness on the Panda against the exact world, the
//! batch and motion forms against the one-configuration form, the links fixed to the world
//! (checked once, their self pairs through a tree) and links of many spheres (placed when a test
//! needs them) against every sphere pair, links of many spheres in groups (each group's bounding
//! sphere tested first) against every sphere's own test, and the input checks.

use std::path::PathBuf;
use std::sync::Arc;

use genplan_core::collision::spheres::{SphereModel, SphereScratch, SphereWorld, FIXED_LEAF, LANES, MOVING_GROUP};
use genplan_core::collision::CollisionWorld;
use genplan_core::error::Error;
use genplan_core::kinematics::KinematicModel;
use genplan_core::planning::{CollisionChecker, SphereChecker, ValidityChecker};
use genplan_core::robot::preset;
use nalgebra::{Isometry3, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

#[path = "common/probe.rs"]
mod probe;

/// The unit cube [-0.5, 0.5]^3 as an OBJ file.
const CUBE_OBJ: &str = "v -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv 0.5 0.5 -0.5\nv -0.5 0.5 -0.5\n\
v -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv 0.5 0.5 0.5\nv -0.5 0.5 0.5\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

fn probe_world() -> CollisionWorld {
    probe::world()
}

fn cube_file() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("genplan-spheres-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("cube.obj");
    std::fs::write(&p, CUBE_OBJ).unwrap();
    p
}

fn random_pose(rng: &mut StdRng, spread: f64) -> Isometry3<f64> {
    let c = Vector3::new(rng.random_range(-spread..spread), rng.random_range(-spread..spread), 0.4 + rng.random_range(-spread..spread));
    let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
    Isometry3::new(c, axis * rng.random_range(0.0..3.0))
}

/// One obstacle of kind `kind` (0 box, 1 sphere, 2 cylinder, 3 capsule, 4 half-space, 5 mesh).
fn add(w: &mut CollisionWorld, rng: &mut StdRng, kind: usize, name: &str, spread: f64, cube: &PathBuf) {
    let pose = random_pose(rng, spread);
    let mut size = || rng.random_range(0.02..0.25);
    match kind {
        0 => w.add_box(name, [size(), size(), size()], pose).unwrap(),
        1 => w.add_sphere(name, size(), pose.translation.vector.into()).unwrap(),
        2 => w.add_cylinder(name, size(), size(), pose).unwrap(),
        3 => w.add_capsule(name, size(), size(), pose).unwrap(),
        4 => {
            let n = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
            w.add_halfspace(name, n, rng.random_range(-1.5..-0.3)).unwrap()
        }
        _ => w.add_mesh(name, cube, [size() * 2.0, size() * 2.0, size() * 2.0], pose).unwrap(),
    }
}

#[test]
fn every_shape_is_tested_exactly_on_a_one_sphere_robot() {
    let cube = cube_file();
    let mut rng = StdRng::seed_from_u64(11);
    let (mut hits, mut misses) = ([0usize; 6], [0usize; 6]);
    for kind in 0..6 {
        for trial in 0..40 {
            let mut w = probe_world();
            add(&mut w, &mut rng, kind, &format!("o{trial}"), 0.3, &cube);
            let model = w.model.clone();
            let spheres = SphereModel::new(&model, &["probe"], &[[0.0; 3]], &[0.1]).unwrap();
            let sw = SphereWorld::new(Arc::new(w.clone()), spheres).unwrap();
            let mut s = SphereScratch::default();
            for _ in 0..50 {
                let q = [rng.random_range(-0.8..0.8), rng.random_range(-0.8..0.8), 0.4 + rng.random_range(-0.8..0.8)];
                let d = w.min_distance(&q).unwrap();
                let by_spheres = sw.in_collision_unchecked(&q, &mut s);
                // the same sphere: the answers differ only within the f32 slack of a contact
                if d < 0.0 {
                    assert!(by_spheres, "kind {kind}: exact distance {d} at {q:?}, free by the sphere");
                    hits[kind] += 1;
                } else if d > 1e-4 {
                    assert!(!by_spheres, "kind {kind}: exact distance {d} at {q:?}, in collision by the sphere");
                    misses[kind] += 1;
                }
            }
        }
    }
    for kind in 0..6 {
        assert!(hits[kind] > 20 && misses[kind] > 50, "kind {kind}: {} hits and {} misses: both must be met", hits[kind], misses[kind]);
    }
}

/// A cover of the Panda's collision geometry: each shape's local box cut into cells of at most
/// 4 cm, each cell in the sphere through its corners (so every point of every shape is covered).
fn box_cover(w: &CollisionWorld) -> SphereModel {
    box_cover_cells(w, |_| 0.04)
}

/// As [`box_cover`] with cells of at most `cell(link name)` metres.
fn box_cover_cells(w: &CollisionWorld, cell: impl Fn(&str) -> f64) -> SphereModel {
    let model = &w.model;
    let (mut links, mut centers, mut radii) = (Vec::new(), Vec::new(), Vec::new());
    for g in w.geometries() {
        let b = g.shape.compute_local_aabb();
        let ext = b.maxs - b.mins;
        let edge = cell(&model.link_names[g.link]);
        let n: Vec<usize> = (0..3).map(|i| ((ext[i] / edge).ceil() as usize).max(1)).collect();
        let cell = Vector3::new(ext[0] / n[0] as f64, ext[1] / n[1] as f64, ext[2] / n[2] as f64);
        let r = 0.5 * cell.norm() * (1.0 + 1e-9) + 1e-9;
        for i in 0..n[0] {
            for j in 0..n[1] {
                for k in 0..n[2] {
                    let c = b.mins + Vector3::new((i as f64 + 0.5) * cell.x, (j as f64 + 0.5) * cell.y, (k as f64 + 0.5) * cell.z);
                    let c = g.offset * c;
                    links.push(model.link_names[g.link].as_str());
                    centers.push([c.x, c.y, c.z]);
                    radii.push(r);
                }
            }
        }
    }
    SphereModel::new(model, &links, &centers, &radii).unwrap()
}

fn draw(model: &KinematicModel, rng: &mut StdRng) -> Vec<f64> {
    model.lower.iter().zip(&model.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect()
}

#[test]
fn free_by_spheres_is_free_by_the_exact_geometry_on_the_panda() {
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    let cube = cube_file();
    let mut rng = StdRng::seed_from_u64(7);
    for k in 0..30 {
        add(&mut w, &mut rng, k % 6, &format!("o{k}"), 0.8, &cube);
    }
    let spheres = box_cover(&w);
    let sw = SphereWorld::new(Arc::new(w.clone()), spheres).unwrap();
    assert!(!sw.self_link_pairs().is_empty());
    // 2,000 configurations: a debug build (CI's) checks them in well under a minute
    let n = 2000;
    let qs: Vec<f64> = (0..n).flat_map(|_| draw(&model, &mut rng)).collect();
    let mut batch = vec![false; n];
    sw.in_collision_batch(&qs, &mut batch, &mut SphereScratch::default());
    let mut one = SphereScratch::default();
    // every length of a last block (one row at a time, four lanes, eight lanes)
    let mut s8 = SphereScratch::default();
    for len in 1..=17 {
        let mut part = vec![false; len];
        sw.in_collision_batch(&qs[..len * model.nq], &mut part, &mut s8);
        assert_eq!(part, batch[..len], "a batch of {len} rows");
    }
    let (mut exact_hits, mut false_positives) = (0, 0);
    for (i, q) in qs.chunks(model.nq).enumerate() {
        let exact = w.in_collision(q).unwrap();
        let by_spheres = sw.in_collision_unchecked(q, &mut one);
        assert_eq!(by_spheres, batch[i], "batch and single differ at row {i}");
        assert!(by_spheres || !exact, "row {i}: in collision by the exact geometry, free by the spheres");
        exact_hits += exact as usize;
        false_positives += (by_spheres && !exact) as usize;
    }
    assert!(exact_hits > n / 10 && exact_hits < n * 9 / 10, "{exact_hits} of {n} in collision: the scene must be met");
    assert!(false_positives < n, "{false_positives} false positives");
}

#[test]
fn a_motion_is_free_when_every_state_is() {
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    w.add_box("table", [0.3, 0.3, 0.02], Isometry3::translation(0.5, 0.0, 0.3)).unwrap();
    w.add_sphere("ball", 0.08, [0.3, 0.3, 0.6]).unwrap();
    let sw = SphereWorld::new(Arc::new(w), box_cover(&preset("panda").unwrap().load().unwrap().1)).unwrap();
    let mut rng = StdRng::seed_from_u64(3);
    let (mut s8, mut s1) = (SphereScratch::<LANES>::default(), SphereScratch::default());
    let (mut free, mut blocked) = (0, 0);
    for _ in 0..200 {
        let a = draw(&model, &mut rng);
        let b: Vec<f64> = a.iter().zip(draw(&model, &mut rng)).map(|(x, y)| x + 0.3 * (y - x)).collect();
        let res = 0.05;
        let got = sw.motion_free(&a, &b, res, &mut s8);
        let steps = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((y - x).abs())) / res;
        let steps = (steps.ceil() as usize).max(1);
        let want = (0..=steps).all(|k| {
            let t = k as f64 / steps as f64;
            let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + t * (y - x)).collect();
            !sw.in_collision_unchecked(&q, &mut s1)
        });
        assert_eq!(got, want);
        free += got as usize;
        blocked += !got as usize;
    }
    assert!(free > 10 && blocked > 10, "{free} free and {blocked} blocked motions: both must be met");
}

#[test]
fn the_sphere_checker_is_the_limits_and_the_spheres() {
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    w.add_box("table", [0.3, 0.3, 0.02], Isometry3::translation(0.5, 0.0, 0.3)).unwrap();
    let spheres = box_cover(&w);
    let sw = Arc::new(SphereWorld::new(Arc::new(w.clone()), spheres).unwrap());
    let mut rng = StdRng::seed_from_u64(5);
    let n = 301;
    let mut qs: Vec<f64> = (0..n).flat_map(|_| draw(&model, &mut rng)).collect();
    // a few rows past the limits
    for i in (0..n).step_by(17) {
        qs[i * model.nq] = model.upper[0] + 0.1;
    }
    let mut one = SphereScratch::default();
    let want: Vec<bool> = qs
        .chunks(model.nq)
        .map(|q| q[0] <= model.upper[0] && !sw.in_collision_unchecked(q, &mut one))
        .collect();
    let mut exact = vec![false; n];
    CollisionChecker::new(Arc::new(w), false).check(&qs, &mut exact).unwrap();
    for parallel in [false, true] {
        let mut valid = vec![false; n];
        SphereChecker::new(sw.clone(), parallel, false).check(&qs, &mut valid).unwrap();
        assert_eq!(valid, want, "parallel {parallel}");
        // conservative: valid by the spheres is valid by the exact checker
        assert!(valid.iter().zip(&exact).all(|(&v, &e)| !v || e));
    }
    assert!(want.iter().any(|&v| v) && want.iter().any(|&v| !v));
}

#[test]
fn all_valid_stops_early_and_agrees_with_check() {
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    w.add_box("table", [0.3, 0.3, 0.02], Isometry3::translation(0.5, 0.0, 0.3)).unwrap();
    let spheres = box_cover(&w);
    let sw = Arc::new(SphereWorld::new(Arc::new(w), spheres).unwrap());
    let mut rng = StdRng::seed_from_u64(11);
    let mut checker = SphereChecker::new(sw.clone(), false, false);
    let mut s8 = SphereScratch::default();
    let (mut all_free, mut some_hit) = (0, 0);
    for trial in 0..60 {
        // every length of a block (one row at a time, four lanes, eight lanes, several blocks)
        let n = 1 + trial % 19;
        // rows around one configuration (a short motion's states): free together, or not
        let base = draw(&model, &mut rng);
        let mut qs: Vec<f64> = (0..n)
            .flat_map(|_| base.iter().zip(model.lower.iter().zip(&model.upper)).map(|(&x, (&l, &u))| (x + rng.random_range(-0.05..0.05)).clamp(l, u)).collect::<Vec<_>>())
            .collect();
        if trial % 7 == 3 {
            qs[(n - 1) * model.nq] = model.upper[0] + 0.1;
        }
        let mut valid = vec![false; n];
        checker.check(&qs, &mut valid).unwrap();
        let want = valid.iter().all(|&v| v);
        let (got, checked) = checker.all_valid(&qs, n).unwrap();
        assert_eq!(got, want, "trial {trial}: {n} rows");
        assert!(checked >= 1 && checked <= n && (!got || checked == n), "trial {trial}: {checked} of {n} rows checked");
        // the spheres alone: a hit is in a block at or before the first row in collision
        let mut batch = vec![false; n];
        sw.in_collision_batch(&qs, &mut batch, &mut s8);
        let (hit, upto) = sw.any_in_collision(&qs, &mut s8);
        assert_eq!(hit, batch.iter().any(|&b| b), "trial {trial}");
        if hit {
            assert!(batch[..upto].iter().any(|&b| b), "trial {trial}: the hit within the {upto} rows checked");
        }
        all_free += want as usize;
        some_hit += !want as usize;
    }
    assert!(all_free > 5 && some_hit > 5, "{all_free} free and {some_hit} blocked batches: both must be met");
}

#[test]
fn a_confirmed_sphere_checker_answers_as_the_exact_checker() {
    // the boxes' cover reaches well beyond the links: many of its collisions are false
    // positives, which the exact geometry overrules; check and all_valid agree with the exact
    // checker on every row, for every batch length (several blocks, a hit in a later block)
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    w.add_box("table", [0.3, 0.3, 0.02], Isometry3::translation(0.5, 0.0, 0.3)).unwrap();
    let spheres = box_cover(&w);
    let sw = Arc::new(SphereWorld::new(Arc::new(w.clone()), spheres).unwrap());
    let mut exact = CollisionChecker::new(Arc::new(w), false);
    let mut rng = StdRng::seed_from_u64(23);
    let (mut overruled, mut blocked, mut free) = (0, 0, 0);
    for parallel in [false, true] {
        let mut checker = SphereChecker::new(sw.clone(), parallel, true);
        let mut spheres_only = SphereChecker::new(sw.clone(), parallel, false);
        for trial in 0..80 {
            let n = 1 + trial % 27;
            let base = draw(&model, &mut rng);
            let qs: Vec<f64> = (0..n)
                .flat_map(|_| base.iter().zip(model.lower.iter().zip(&model.upper)).map(|(&x, (&l, &u))| (x + rng.random_range(-0.3..0.3)).clamp(l, u)).collect::<Vec<_>>())
                .collect();
            let (mut want, mut got, mut by_spheres) = (vec![false; n], vec![false; n], vec![false; n]);
            exact.check(&qs, &mut want).unwrap();
            checker.check(&qs, &mut got).unwrap();
            spheres_only.check(&qs, &mut by_spheres).unwrap();
            assert_eq!(got, want, "trial {trial}: {n} rows, parallel {parallel}");
            overruled += by_spheres.iter().zip(&want).filter(|(&s, &e)| !s && e).count();
            let all = want.iter().all(|&v| v);
            let (valid, checked) = checker.all_valid(&qs, n).unwrap();
            assert_eq!(valid, all, "trial {trial}: {n} rows");
            if all {
                free += 1;
                assert_eq!(checked, n);
            } else {
                blocked += 1;
                let first = want.iter().position(|&v| !v).unwrap();
                assert_eq!(checked, first + 1, "trial {trial}: the first row in collision is {first}");
            }
        }
    }
    assert!(overruled > 20 && blocked > 10 && free > 10, "{overruled} overruled rows, {blocked} blocked and {free} free batches");
}

#[test]
fn bad_spheres_are_refused_by_name() {
    let (model, _) = preset("panda").unwrap().load().unwrap();
    let e = SphereModel::new(&model, &["panda_link1", "panda_link2"], &[[0.0; 3]], &[0.1, 0.1]).unwrap_err();
    assert!(matches!(e, Error::Shape { ref what, .. } if what.contains("centers")), "{e}");
    let e = SphereModel::new(&model, &["nowhere"], &[[0.0; 3]], &[0.1]).unwrap_err();
    assert!(matches!(e, Error::UnknownName { ref name, .. } if name == "nowhere"), "{e}");
    let e = SphereModel::new(&model, &["panda_link1"], &[[0.0; 3]], &[0.0]).unwrap_err();
    assert!(e.to_string().contains("radii"), "{e}");
    let e = SphereModel::new(&model, &["panda_link1"], &[[f64::NAN, 0.0, 0.0]], &[0.1]).unwrap_err();
    assert!(matches!(e, Error::NonFinite { .. }), "{e}");
}

#[test]
fn a_fixed_link_meeting_an_obstacle_makes_every_configuration_collide() {
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    let spheres = box_cover(&w);
    let base = model.link_index("panda_link0").unwrap();
    let first = model.link_index("panda_link1").unwrap();
    let free_world = SphereWorld::new(Arc::new(w.clone()), spheres.clone()).unwrap();
    assert!(free_world.fixed_links().contains(&base) && !free_world.fixed_links().contains(&first));
    // a ball inside the base: nothing the arm does moves the base out of it
    w.add_sphere("ball", 0.03, [0.0, 0.0, 0.05]).unwrap();
    let sw = SphereWorld::new(Arc::new(w.clone()), spheres).unwrap();
    let mut rng = StdRng::seed_from_u64(21);
    let n = 40;
    let qs: Vec<f64> = (0..n).flat_map(|_| draw(&model, &mut rng)).collect();
    let (mut s8, mut s1) = (SphereScratch::<LANES>::default(), SphereScratch::default());
    let mut batch = vec![false; n];
    sw.in_collision_batch(&qs, &mut batch, &mut s8);
    assert!(batch.iter().all(|&b| b));
    for q in qs.chunks(model.nq) {
        assert!(w.in_collision(q).unwrap(), "the exact geometry: the base meets the ball");
        assert!(sw.in_collision_unchecked(q, &mut s1));
    }
    assert!(sw.any_in_collision(&qs[..model.nq], &mut s8).0);
    assert!(!sw.motion_free(&qs[..model.nq], &qs[model.nq..2 * model.nq], 0.05, &mut s8));
    // the same configurations without the ball: not all in collision
    let mut without = vec![false; n];
    free_world.in_collision_batch(&qs, &mut without, &mut s8);
    assert!(without.iter().any(|&b| !b));
}

#[test]
fn a_fixed_link_of_many_spheres_answers_as_every_sphere_pair() {
    // the base (a fixed link) in cells of 2.5 cm, hundreds: its tree has several levels (the
    // moving links in 6 cm cells: the pairs below are compared one by one in a debug build)
    answers_as_every_sphere_pair(23, |name| if name == "panda_link0" { 0.025 } else { 0.06 });
}

#[test]
fn moving_links_of_many_spheres_answer_as_every_sphere_pair() {
    // every link in cells of 3 cm: links of tens of spheres, whose spheres are placed only when
    // a test needs them and pruned one by one against the other link's bounding sphere
    answers_as_every_sphere_pair(29, |_| 0.03);
}

#[test]
fn moving_links_in_groups_answer_as_every_sphere_against_every_obstacle() {
    // every link in cells of 2 cm: links of tens to hundreds of spheres, split into groups of at
    // most MOVING_GROUP; obstacles of every kind placed at spheres of drawn configurations. The
    // reference: each sphere alone, its least gap to the obstacles by the exact geometry of the
    // one-sphere probe (radius 0.1) at its centre, in f64.
    let cube = cube_file();
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    w.check_self = false;
    w.set_padding(0.01).unwrap();
    let mut probe = probe_world();
    let spheres = box_cover_cells(&w, |_| 0.02);
    let most = (0..model.n_links()).map(|l| spheres.link.iter().filter(|&&k| k == l).count()).max().unwrap();
    assert!(most > 8 * MOVING_GROUP, "{most} spheres on the largest link");
    let mut rng = StdRng::seed_from_u64(31);
    let mut poses = Vec::new();
    let mut placed = 0;
    while placed < 5 {
        // at a sphere of a drawn configuration, clear of the base (a fixed link: checked once)
        // and of the shoulder (there in every configuration)
        model.forward_kinematics(&draw(&model, &mut rng), &mut poses).unwrap();
        let i = rng.random_range(0..spheres.len());
        let c = poses[spheres.link[i]] * nalgebra::Point3::new(spheres.x[i], spheres.y[i], spheres.z[i]);
        if (c.x.hypot(c.y) < 0.3 && c.z < 0.4) || (c.coords - Vector3::new(0.0, 0.0, 0.333)).norm() < 0.4 {
            continue;
        }
        let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let pose = Isometry3::new(c.coords, axis * rng.random_range(0.0..3.0));
        let size = rng.random_range(0.02..0.05);
        let name = format!("o{placed}");
        for world in [&mut w, &mut probe] {
            match placed % 5 {
                0 => world.add_box(&name, [size, 0.5 * size, 1.5 * size], pose).unwrap(),
                1 => world.add_sphere(&name, size, c.coords.into()).unwrap(),
                2 => world.add_cylinder(&name, size, 2.0 * size, pose).unwrap(),
                3 => world.add_capsule(&name, 0.5 * size, 2.0 * size, pose).unwrap(),
                _ => world.add_mesh(&name, &cube, [2.0 * size, 3.0 * size, size], pose).unwrap(),
            }
        }
        placed += 1;
    }
    // a half-space beyond the base's reach
    for world in [&mut w, &mut probe] {
        world.add_halfspace("floor", [0.3, 0.2, 1.0], -0.5).unwrap();
    }
    let sw = SphereWorld::new(Arc::new(w.clone()), spheres.clone()).unwrap();
    // the least gap of any sphere: the probe's distance less the radius beyond the probe's and
    // the padding (1 cm)
    answers_as_the_least_gap(&sw, &model, &spheres, &mut rng, |c, r| probe.min_distance(&[c.x, c.y, c.z]).unwrap() + 0.1 - r - 0.01);
}

#[test]
fn many_obstacles_with_their_own_paddings_answer_as_every_sphere_against_every_obstacle() {
    // 21 obstacles (the checker tests a link against 8 obstacles' boxes at once: two full sets
    // and one of 5): 18 beyond the arm's reach and, one in each set, 3 at spheres of drawn
    // configurations, a box and a ball with a padding of their own (15 cm, so that many rows
    // meet them by their padding alone; the world's 1 cm) and a box. The reference: each sphere
    // against each obstacle alone, the exact gap of the one-sphere probe (radius 0.1) at its
    // centre, in f64, less that obstacle's padding.
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    w.check_self = false;
    w.set_padding(0.01).unwrap();
    let spheres = box_cover(&w);
    let mut rng = StdRng::seed_from_u64(47);
    let mut poses = Vec::new();
    let mut probes: Vec<(CollisionWorld, f64)> = Vec::new();
    while probes.len() < 21 {
        model.forward_kinematics(&draw(&model, &mut rng), &mut poses).unwrap();
        let i = rng.random_range(0..spheres.len());
        let c = poses[spheres.link[i]] * nalgebra::Point3::new(spheres.x[i], spheres.y[i], spheres.z[i]);
        if (c.x.hypot(c.y) < 0.3 && c.z < 0.4) || (c.coords - Vector3::new(0.0, 0.0, 0.333)).norm() < 0.4 {
            continue;
        }
        let k = probes.len();
        let near = [6, 12, 20].contains(&k);
        let c = if near { c.coords } else { c.coords + Vector3::new(0.0, 0.0, 4.0) };
        let name = format!("o{k}");
        let pose = Isometry3::new(c, Vector3::new(0.3, -0.2, 0.5) * rng.random_range(0.0..3.0));
        let size = rng.random_range(0.02..0.06);
        let mut probe = probe_world();
        for world in [&mut w, &mut probe] {
            if k % 2 == 0 {
                world.add_box(&name, [size, 0.5 * size, 1.5 * size], pose).unwrap();
            } else {
                world.add_sphere(&name, size, c.into()).unwrap();
            }
        }
        let pad = if k % 3 == 0 { 0.15 } else { 0.01 };
        if k % 3 == 0 {
            w.set_obstacle_padding(&name, Some(pad)).unwrap();
        }
        probes.push((probe, pad));
    }
    let sw = SphereWorld::new(Arc::new(w.clone()), spheres.clone()).unwrap();
    answers_as_the_least_gap(&sw, &model, &spheres, &mut rng, |c, r| {
        probes.iter().map(|(p, pad)| p.min_distance(&[c.x, c.y, c.z]).unwrap() + 0.1 - r - pad).fold(f64::INFINITY, f64::min)
    });
}

/// 160 drawn configurations checked by `sw` in a batch, one at a time and by `any_in_collision`:
/// the three agree, and each answer is the sign of the least of `gap(centre, radius)` over the
/// spheres (computed in f64 from the model's kinematics) wherever it is not within 1e-4 m of 0;
/// more than 90 % of the rows are compared, more than 10 % of them in collision and 10 % free.
fn answers_as_the_least_gap(sw: &SphereWorld, model: &KinematicModel, spheres: &SphereModel, rng: &mut StdRng,
                            gap: impl Fn(nalgebra::Point3<f64>, f64) -> f64) {
    let n = 160;
    let qs: Vec<f64> = (0..n).flat_map(|_| draw(model, rng)).collect();
    let mut batch = vec![false; n];
    sw.in_collision_batch(&qs, &mut batch, &mut SphereScratch::default());
    let (mut one, mut s8) = (SphereScratch::default(), SphereScratch::default());
    let (mut compared, mut hits) = (0, 0);
    let mut poses = Vec::new();
    for (row, q) in qs.chunks(model.nq).enumerate() {
        model.forward_kinematics(q, &mut poses).unwrap();
        let least = (0..spheres.len())
            .map(|i| gap(poses[spheres.link[i]] * nalgebra::Point3::new(spheres.x[i], spheres.y[i], spheres.z[i]), spheres.radius[i]))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(sw.in_collision_unchecked(q, &mut one), batch[row], "row {row}: batch and single differ");
        assert_eq!(sw.any_in_collision(q, &mut s8).0, batch[row], "row {row}: any and batch differ");
        if least.abs() > 1e-4 {
            assert_eq!(batch[row], least < 0.0, "row {row}: least gap {least}");
            compared += 1;
            hits += (least < 0.0) as usize;
        }
    }
    assert!(compared > n * 9 / 10 && hits > n / 10 && compared - hits > n / 10, "{compared} rows compared, {hits} in collision");
}

/// The Panda among random balls, covered by [`box_cover_cells`] with `cell`: each configuration's
/// answer (batch and single) is the one of every sphere against every ball and every sphere
/// pair of the self pairs, computed in `f64`, wherever the least gap is not within 1e-4 m of 0.
fn answers_as_every_sphere_pair(seed: u64, cell: impl Fn(&str) -> f64) {
    let (model, mut w) = preset("panda").unwrap().load().unwrap();
    let mut rng = StdRng::seed_from_u64(seed);
    let mut balls = Vec::new();
    for k in 0..12 {
        let c = [rng.random_range(-0.7..0.7), rng.random_range(-0.7..0.7), rng.random_range(0.0..1.0)];
        let r = rng.random_range(0.03..0.12);
        // none touching the base, whose spheres are checked once
        if (c[0] as f64).hypot(c[1]) < 0.3 && c[2] < 0.4 {
            continue;
        }
        w.add_sphere(&format!("b{k}"), r, c).unwrap();
        balls.push((c, r));
    }
    let spheres = box_cover_cells(&w, cell);
    let base = model.link_index("panda_link0").unwrap();
    let on_base = spheres.link.iter().filter(|&&l| l == base).count();
    assert!(on_base > 16 * FIXED_LEAF, "{on_base} spheres on the base");
    let sw = SphereWorld::new(Arc::new(w.clone()), spheres.clone()).unwrap();
    let pairs = sw.self_link_pairs();
    assert!(pairs.iter().any(|&(a, b)| a == base || b == base), "a self pair with the base");
    let n = 300;
    let qs: Vec<f64> = (0..n).flat_map(|_| draw(&model, &mut rng)).collect();
    let mut batch = vec![false; n];
    sw.in_collision_batch(&qs, &mut batch, &mut SphereScratch::default());
    let mut one = SphereScratch::default();
    let of_link = |l: usize| (0..spheres.len()).filter(|&i| spheres.link[i] == l).collect::<Vec<_>>();
    let pair_spheres: Vec<(bool, Vec<usize>, Vec<usize>)> = pairs.iter().map(|&(a, b)| (a == base || b == base, of_link(a), of_link(b))).collect();
    let (mut poses, mut compared, mut by_base, mut by_moving) = (Vec::new(), 0, 0, 0);
    for (row, q) in qs.chunks(model.nq).enumerate() {
        // every sphere in the world frame (f64), every obstacle and self pair of spheres
        model.forward_kinematics(q, &mut poses).unwrap();
        let at: Vec<Vector3<f64>> = (0..spheres.len())
            .map(|i| (poses[spheres.link[i]] * nalgebra::Point3::new(spheres.x[i], spheres.y[i], spheres.z[i])).coords)
            .collect();
        // the least gap (distance less the radii) of any tested pair, and of the base's
        let (mut gap, mut base_gap, mut moving_gap) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for i in 0..spheres.len() {
            for (c, r) in &balls {
                gap = gap.min((at[i] - Vector3::from(*c)).norm() - spheres.radius[i] - r);
            }
        }
        for (with_base, ia, ib) in &pair_spheres {
            for &i in ia {
                for &j in ib {
                    let g = (at[i] - at[j]).norm() - spheres.radius[i] - spheres.radius[j];
                    gap = gap.min(g);
                    if *with_base {
                        base_gap = base_gap.min(g);
                    } else {
                        moving_gap = moving_gap.min(g);
                    }
                }
            }
        }
        assert_eq!(sw.in_collision_unchecked(q, &mut one), batch[row], "row {row}: batch and single differ");
        if gap.abs() > 1e-4 {
            assert_eq!(batch[row], gap < 0.0, "row {row}: least gap {gap}");
            compared += 1;
            by_base += (base_gap < 0.0) as usize;
            by_moving += (moving_gap < 0.0) as usize;
        }
    }
    assert!(compared > n * 9 / 10 && by_base > 5 && by_moving > 5, "{compared} rows compared, {by_base} met by the base, {by_moving} by two moving links");
}

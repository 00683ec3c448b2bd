//! Point clouds as obstacles (src/collision/cloud.rs): a cloud answers every query as the same
//! points added one by one as sphere obstacles do; a new frame replaces the old in place; the
//! robot's own points are found; bad input is refused before any work.

use genplan_core::collision::{voxel_downsample, CollisionWorld};
use genplan_core::error::Error;
use genplan_core::kinematics::KinematicModel;
use genplan_core::robot::preset;
use genplan_core::Scratch;
use std::sync::Arc;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn panda() -> (Arc<KinematicModel>, CollisionWorld) {
    preset("panda").unwrap().load().unwrap()
}

fn draw(model: &KinematicModel, rng: &mut StdRng) -> Vec<f64> {
    model.lower.iter().zip(&model.upper).map(|(&l, &u)| rng.random_range(l..=u)).collect()
}

/// `n` points on a wall in front of the Panda (x = 0.7, y and z in a square) and a few in the
/// air, all within its reach.
fn wall(rng: &mut StdRng, n: usize) -> Vec<f64> {
    (0..n)
        .flat_map(|k| {
            if k % 40 == 0 {
                [rng.random_range(-0.8..0.8), rng.random_range(-0.8..0.8), rng.random_range(0.0..1.0)]
            } else {
                [0.7, rng.random_range(-0.3..0.3), rng.random_range(0.2..0.8)]
            }
        })
        .collect()
}

#[test]
fn a_cloud_answers_as_its_points_added_as_spheres() {
    let (model, base) = panda();
    let mut rng = StdRng::seed_from_u64(1);
    let pts = wall(&mut rng, 400);
    let r = 0.02;
    let mut cloud = base.clone();
    cloud.add_points("cloud", &pts, r, None).unwrap();
    // the obstacles alone: self contacts would hide them
    cloud.check_self = false;
    let mut balls = base.clone();
    balls.check_self = false;
    for (k, p) in pts.chunks_exact(3).enumerate() {
        balls.add_sphere(&format!("p{k}"), r, [p[0], p[1], p[2]]).unwrap();
    }
    let (mut s, mut t) = (Scratch::default(), Scratch::default());
    let gm = vec![0.03; cloud.geometries().len()];
    let pm = vec![0.03; cloud.self_pairs().len()];
    let (mut hits, mut clear) = (0, 0);
    for _ in 0..300 {
        let q = draw(&model, &mut rng);
        let hit = cloud.in_collision_unchecked(&q, &mut s);
        assert_eq!(hit, balls.in_collision_unchecked(&q, &mut t), "in_collision at {q:?}");
        hits += usize::from(hit);
        let (a, b) = (cloud.min_distance_unchecked(&q, &mut s), balls.min_distance_unchecked(&q, &mut t));
        assert!((a - b).abs() < 1e-9, "min_distance at {q:?}: {a} vs {b}");
        let c = cloud.clear_by(&q, &gm, &pm, &mut s);
        assert_eq!(c, balls.clear_by(&q, &gm, &pm, &mut t), "clear_by at {q:?}");
        clear += usize::from(c);
        // the closest obstacle pair is the cloud where it is a ball
        let (pc, pb) = (cloud.close_pairs(&q, 0.05).unwrap(), balls.close_pairs(&q, 0.05).unwrap());
        let dc: Vec<f64> = pc.iter().filter(|p| p.b == "cloud").map(|p| p.distance).collect();
        let db: Vec<f64> = pb.iter().filter(|p| p.b.starts_with('p')).map(|p| p.distance).collect();
        assert_eq!(dc.len() > 0, db.len() > 0);
    }
    assert!(hits > 30 && hits < 270 && clear > 10, "{hits} in collision, {clear} clear: the cloud must be met and missed");
    // point distances: the distance to the nearest ball
    let probes = [0.6, 0.0, 0.5, 0.7, 0.0, 0.5, 0.0, 0.0, 2.0];
    let (mut d, mut g) = (vec![0.0; 3], vec![0.0; 9]);
    let (mut e, mut h) = (vec![0.0; 3], vec![0.0; 9]);
    cloud.point_distances(&probes, 1.0, &mut d, &mut g).unwrap();
    balls.point_distances(&probes, 1.0, &mut e, &mut h).unwrap();
    for k in 0..3 {
        assert!((d[k] - e[k]).abs() < 1e-9, "{d:?} vs {e:?}");
    }
}

#[test]
fn a_new_frame_replaces_the_old_in_place() {
    let (model, mut w) = panda();
    w.add_box("table", [0.3, 0.3, 0.01], nalgebra::Isometry3::translation(0.5, 0.0, -0.2)).unwrap();
    w.add_points("cam", &[0.4, 0.0, 0.5], 0.05, None).unwrap();
    w.add_sphere("ball", 0.05, [0.0, 0.9, 0.5]).unwrap();
    let names = |w: &CollisionWorld| w.obstacles.iter().map(|o| o.name.clone()).collect::<Vec<_>>();
    let before = names(&w);
    let mut rng = StdRng::seed_from_u64(2);
    let pts = wall(&mut rng, 5000);
    w.replace_points("cam", &pts).unwrap();
    assert_eq!(names(&w), before);
    assert_eq!(w.obstacles[1].cloud.unwrap().points, 5000);
    assert_eq!(w.obstacles[1].cloud.unwrap().radius, 0.05);
    // a bad frame leaves the old one, and a non-cloud or unknown name is refused
    assert!(matches!(w.replace_points("cam", &[0.0, f64::NAN, 0.0]), Err(Error::NonFinite { .. })));
    assert!(matches!(w.replace_points("cam", &[]), Err(Error::Invalid(_))));
    assert_eq!(w.obstacles[1].cloud.unwrap().points, 5000);
    assert!(matches!(w.replace_points("ball", &pts), Err(Error::Invalid(m)) if m.contains("not a point cloud")));
    assert!(matches!(w.replace_points("nope", &pts), Err(Error::UnknownName { .. })));
    // with a voxel, each frame is down-sampled
    w.remove_obstacle("cam").unwrap();
    w.add_points("cam", &pts, 0.01, Some(0.05)).unwrap();
    let n = w.obstacles.last().unwrap().cloud.unwrap().points;
    assert_eq!(n * 3, voxel_downsample(&pts, 0.05).len());
    assert!(n < 5000 && n > 100, "{n} voxels");
    // the answers follow the frame
    let q: Vec<f64> = model.lower.iter().zip(&model.upper).map(|(l, u)| 0.5 * (l + u)).collect();
    w.replace_points("cam", &[5.0, 5.0, 5.0]).unwrap();
    let far = w.min_distance(&q).unwrap();
    w.replace_points("cam", &[0.3, 0.0, 0.6]).unwrap();
    assert!(w.min_distance(&q).unwrap() < far);
}

#[test]
fn voxels_keep_one_centroid_each_within_reach_of_their_points() {
    let mut rng = StdRng::seed_from_u64(3);
    let pts = wall(&mut rng, 20_000);
    let v = 0.02;
    let out = voxel_downsample(&pts, v);
    let key = |p: &[f64]| [(p[0] / v).floor() as i64, (p[1] / v).floor() as i64, (p[2] / v).floor() as i64];
    let occupied: std::collections::HashSet<_> = pts.chunks_exact(3).map(key).collect();
    assert_eq!(out.len(), 3 * occupied.len(), "one point per occupied voxel");
    // each input point within a voxel's diagonal of a kept one (its voxel's centroid)
    let reach = v * 3f64.sqrt() + 1e-12;
    for p in pts.chunks_exact(3).step_by(50) {
        assert!(out.chunks_exact(3).any(|c| ((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2) + (c[2] - p[2]).powi(2)).sqrt() <= reach));
    }
}

#[test]
fn the_robots_own_points_are_found() {
    let (model, w) = panda();
    let q: Vec<f64> = model.lower.iter().zip(&model.upper).map(|(l, u)| 0.5 * (l + u)).collect();
    // each geometry's origin lies in or near it; points 2 m away do not
    let mut links = Vec::new();
    w.model.forward_kinematics(&q, &mut links).unwrap();
    let mut pts = Vec::new();
    for g in w.geometries() {
        let c = (links[g.link] * g.offset).translation.vector;
        pts.extend([c.x, c.y, c.z]);
    }
    let n = w.geometries().len();
    pts.extend([2.0, 2.0, 2.0, -2.0, 0.0, 0.5]);
    let on = w.robot_points(&q, &pts, 0.05).unwrap();
    assert!(on[..n].iter().filter(|&&b| b).count() >= n - 1, "{on:?}");
    assert!(!on[n] && !on[n + 1]);
    assert!(matches!(w.robot_points(&q, &pts, -0.1), Err(Error::Invalid(_))));
    assert!(matches!(w.robot_points(&q, &[0.0, f64::NAN, 0.0], 0.1), Err(Error::NonFinite { .. })));
    assert!(matches!(w.robot_points(&q, &[0.0, 0.0], 0.1), Err(Error::Shape { .. })));
}

#[test]
fn bad_clouds_are_refused_before_any_work() {
    let (_, mut w) = panda();
    assert!(matches!(w.add_points("c", &[], 0.01, None), Err(Error::Invalid(m)) if m.contains("empty")));
    assert!(matches!(w.add_points("c", &[0.0, 0.0], 0.01, None), Err(Error::Shape { .. })));
    assert!(matches!(w.add_points("c", &[0.0, 0.0, f64::INFINITY], 0.01, None), Err(Error::NonFinite { index: 2, .. })));
    assert!(matches!(w.add_points("c", &[0.0, 0.0, 2e6], 0.01, None), Err(Error::Invalid(_))));
    for r in [-0.01, 0.0, f64::NAN] {
        assert!(matches!(w.add_points("c", &[0.0, 0.0, 0.0], r, None), Err(Error::Invalid(m)) if m.contains("radius")));
    }
    for v in [0.0, -1.0, f64::NAN] {
        assert!(matches!(w.add_points("c", &[0.0, 0.0, 0.0], 0.01, Some(v)), Err(Error::Invalid(m)) if m.contains("voxel")));
    }
    w.add_sphere("c", 0.1, [0.0, 0.0, 3.0]).unwrap();
    assert!(matches!(w.add_points("c", &[0.0, 0.0, 0.0], 0.01, None), Err(Error::Invalid(m)) if m.contains("already")));
    assert_eq!(w.obstacles.len(), 1);
}


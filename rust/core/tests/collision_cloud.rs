//! Point clouds as obstacles (src/collision/cloud.rs, cloud_grid.rs): a cloud answers every query
//! as the same points added one by one as sphere obstacles do (the sphere checker's too); its
//! grid answers as a test of every ball does, for dense, sparse, flat and one-point clouds; a new
//! frame replaces the old in place; the robot's own points are found; bad input is refused before
//! any work.

use genplan_core::collision::spheres::{SphereModel, SphereScratch, SphereWorld};
use genplan_core::collision::{voxel_downsample, CloudGrid, CollisionWorld, MAX_CELLS_PER_BALL, MIN_CELLS};
use genplan_core::error::Error;
use genplan_core::kinematics::KinematicModel;
use genplan_core::robot::preset;
use genplan_core::Scratch;
use std::sync::Arc;

use nalgebra::{Isometry3, Point3};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Shape};
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
    let near = w.min_distance(&q).unwrap();
    assert!(near < far);
    // a new frame is built in the old one's memory, except while a clone of the world shares
    // it: the clone keeps its frame, each world then answers for its own, and the next frame
    // (the grid no longer shared) matches a cloud added with it
    let snapshot = w.clone();
    w.replace_points("cam", &[5.0, 5.0, 5.0]).unwrap();
    assert_eq!(snapshot.min_distance(&q).unwrap(), near);
    assert_eq!(w.min_distance(&q).unwrap(), far);
    w.replace_points("cam", &pts).unwrap();
    let mut fresh = w.clone();
    fresh.remove_obstacle("cam").unwrap();
    fresh.add_points("cam", &pts, 0.01, Some(0.05)).unwrap();
    assert_eq!(w.obstacles.last().unwrap().cloud, fresh.obstacles.last().unwrap().cloud);
    for _ in 0..50 {
        let q = draw(&model, &mut rng);
        assert_eq!(w.min_distance(&q).unwrap(), fresh.min_distance(&q).unwrap());
        assert_eq!(w.in_collision(&q).unwrap(), fresh.in_collision(&q).unwrap());
    }
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
fn voxels_come_out_in_the_order_of_their_coordinates_whatever_the_extent() {
    // the voxel rank as one u64 (a cloud in a room) and as three i64 (a box whose voxels do not
    // fit a u64) give the centroids of a plain sort of the integer coordinates
    let reference = |pts: &[f64], v: f64| {
        let inv = 1.0 / v; // the voxel's key: floor(x * (1 / voxel)), as the down-sampling computes it
        let mut keys: Vec<([i64; 3], usize)> =
            pts.chunks_exact(3).enumerate().map(|(i, p)| ([0, 1, 2].map(|k| (p[k] * inv).floor() as i64), i)).collect();
        keys.sort_unstable();
        let mut out: Vec<f64> = Vec::new();
        for run in keys.chunk_by(|a, b| a.0 == b.0) {
            let n = run.len() as f64;
            out.extend((0..3).map(|k| run.iter().map(|&(_, i)| pts[3 * i + k]).sum::<f64>() / n));
        }
        out
    };
    let mut rng = StdRng::seed_from_u64(5);
    let mut pts = wall(&mut rng, 5000);
    pts.extend((0..3000).map(|_| rng.random_range(-2.0..2.0)));
    for v in [0.01, 0.05, 0.3] {
        let (got, want) = (voxel_downsample(&pts, v), reference(&pts, v));
        assert_eq!(got.len(), want.len(), "voxel {v}: voxels");
        assert!(got == want, "voxel {v}: first difference at {:?}", got.iter().zip(&want).position(|(a, b)| a != b));
    }
    let far = [-9e5, 1.0, 2.0, 9e5, -3.0, 0.5, 1e-7, 2e-7, 0.0, 1.5e-7, 2.5e-7, 0.0, 9e5, -3.0, 0.5];
    assert_eq!(voxel_downsample(&far, 1e-6), reference(&far, 1e-6));
    assert_eq!(voxel_downsample(&far, 1e-6).len(), 3 * 3);
}

#[test]
fn a_query_sphere_meets_the_balls_it_reaches() {
    // any_within against every ball, for spheres of many sizes around and inside the cloud,
    // some exactly at a ball's reach
    let mut rng = StdRng::seed_from_u64(8);
    let pts = wall(&mut rng, 3000);
    let r = 0.01;
    let grid = CloudGrid::new(&pts, r);
    let balls: Vec<Point3<f64>> = pts.chunks_exact(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
    let (mut hits, mut misses) = (0, 0);
    for k in 0..4000 {
        let s = rng.random_range(0.0..0.12);
        let c = if k % 4 == 0 {
            // just inside or outside a ball's reach along a random direction
            let b = balls[rng.random_range(0..balls.len())];
            let d = nalgebra::Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize();
            b + d * (s + r) * if k % 8 == 0 { 0.999_999 } else { 1.000_001 }
        } else {
            Point3::new(rng.random_range(-0.3..1.3), rng.random_range(-0.9..0.9), rng.random_range(-0.3..1.5))
        };
        let want = balls.iter().any(|b| (b - c).norm_squared() <= (s + r) * (s + r));
        assert_eq!(grid.any_within(&c, s), want, "sphere {s} at {c:?}");
        if want {
            hits += 1;
        } else {
            misses += 1;
        }
    }
    assert!(hits > 500 && misses > 500, "{hits} hits, {misses} misses");
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


/// parry's signed distance between `shape` at `pose` and a ball (`r`) at `c`, as the world
/// computes a pair's (contact depth when they intersect).
fn ball_pair_distance(shape: &dyn Shape, pose: &Isometry3<f64>, c: &Point3<f64>, r: f64) -> f64 {
    let (at, ball) = (Isometry3::translation(c.x, c.y, c.z), Ball::new(r));
    if query::intersection_test(pose, shape, &at, &ball).unwrap() {
        query::contact(pose, shape, &at, &ball, 0.0).unwrap().map_or(0.0, |k| k.dist.min(0.0))
    } else {
        query::distance(pose, shape, &at, &ball).unwrap()
    }
}

/// The grid's answers against every ball tested, for the Panda's geometries at random
/// configurations: in reach (margins 0 and 3 cm), the least distance (exact below its bound),
/// and the nearest ball to points in, around and far outside the cloud.
fn check_grid_against_every_ball(pts: &[f64], r: f64, seed: u64) -> (usize, usize) {
    let (model, w) = panda();
    let grid = CloudGrid::new(pts, r);
    assert_eq!(grid.len() * 3, pts.len());
    let centers: Vec<Point3<f64>> = pts.chunks_exact(3).map(|p| Point3::new(p[0], p[1], p[2])).collect();
    let mut rng = StdRng::seed_from_u64(seed);
    let (mut met, mut missed) = (0, 0);
    let mut links = Vec::new();
    for _ in 0..40 {
        let q = draw(&model, &mut rng);
        w.model.forward_kinematics(&q, &mut links).unwrap();
        for g in w.geometries() {
            let pose = links[g.link] * g.offset;
            let shape = &*g.shape;
            let (local, world) = (shape.compute_local_aabb(), shape.compute_aabb(&pose));
            let d: Vec<f64> = centers.iter().map(|c| ball_pair_distance(shape, &pose, c, r)).collect();
            let best = d.iter().copied().fold(f64::INFINITY, f64::min);
            for m in [0.0, 0.03] {
                let want = d.iter().any(|&x| x <= m);
                // a ball at the boundary within rounding may go either way
                if d.iter().all(|&x| (x - m).abs() > 1e-9) {
                    assert_eq!(grid.touches(shape, &pose, &local, &world, m), want, "{} margin {m} at {q:?}", g.name);
                }
                if m == 0.0 {
                    (met, missed) = (met + usize::from(want), missed + usize::from(!want));
                }
            }
            let got = grid.distance(shape, &pose, &world, f64::INFINITY);
            assert!((got - best).abs() < 1e-9, "{}: distance {got} vs {best}", g.name);
            // below a bound: exact; above it: at least the bound
            let bound = best + 0.01;
            assert!((grid.distance(shape, &pose, &world, bound) - best).abs() < 1e-9);
            assert!(grid.distance(shape, &pose, &world, best - 0.01) >= best - 0.01);
        }
    }
    for _ in 0..200 {
        let p = Point3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
        let want = centers.iter().map(|c| (p - c).norm() - r).fold(f64::INFINITY, f64::min);
        let (got, g) = grid.nearest(&p, f64::INFINITY).unwrap();
        assert!((got - want).abs() < 1e-12, "nearest to {p:?}: {got} vs {want}");
        let c = p - g * (got + r);
        assert!(centers.iter().any(|k| (k - c).norm() < 1e-9), "the gradient points from a centre");
        assert!(grid.nearest(&p, want - 1e-6).is_none());
        for sphere in [0.05, 0.3] {
            assert_eq!(grid.any_within(&p, sphere), centers.iter().any(|k| (k - p).norm() <= sphere + r));
        }
    }
    check_clearance(&grid, &centers, &mut rng);
    (met, missed)
}

/// The grid's clearance field bounds the distance to the nearest centre from below, at points
/// anywhere and near the centres, and within four half diagonals of a field cell of it inside
/// the centres' box (so it clears what it should).
fn check_clearance(grid: &CloudGrid, centers: &[Point3<f64>], rng: &mut StdRng) {
    let (lo, hi) = centers.iter().fold((Point3::from([f64::INFINITY; 3]), Point3::from([f64::NEG_INFINITY; 3])), |(a, b), c| (a.inf(c), b.sup(c)));
    let h = grid.field_cell();
    let mut cleared = 0;
    for k in 0..600 {
        let p = match k % 3 {
            0 => Point3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)),
            1 => centers[k % centers.len()] + nalgebra::Vector3::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2)),
            _ => Point3::from(lo.coords.zip_map(&hi.coords, |a, b| if a < b { rng.random_range(a..=b) } else { a })),
        };
        let want = centers.iter().map(|c| (p - c).norm()).fold(f64::INFINITY, f64::min);
        let got = grid.clearance(&p);
        assert!(got <= want, "clearance {got} above the distance {want} at {p:?}");
        if (0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]) {
            assert!(got >= want - 2.0 * 3f64.sqrt() * h - 1e-5, "clearance {got} loose for {want} at {p:?} (cell {h})");
        }
        cleared += usize::from(got > 0.0);
    }
    assert!(cleared > 0 || centers.len() > 1000, "nothing cleared");
}

#[test]
fn the_grid_answers_as_every_ball_tested() {
    let mut rng = StdRng::seed_from_u64(4);
    // a dense wall in reach
    let (met, missed) = check_grid_against_every_ball(&wall(&mut rng, 3000), 0.02, 5);
    assert!(met > 20 && missed > 100, "{met} met, {missed} missed");
    // sparse over a large box (wide cells), flat (a zero extent), one point, repeated points
    let sparse: Vec<f64> = (0..600).flat_map(|_| [rng.random_range(-50.0..50.0), rng.random_range(-50.0..50.0), rng.random_range(-1.0..1.0)]).collect();
    check_grid_against_every_ball(&sparse, 0.05, 6);
    let flat: Vec<f64> = (0..800).flat_map(|_| [rng.random_range(-0.5..0.9), rng.random_range(-0.6..0.6), 0.3]).collect();
    let (met, _) = check_grid_against_every_ball(&flat, 0.01, 7);
    assert!(met > 5, "{met}");
    // rows of more than 64 cells (several cells per occupancy bit), occupied in separate runs
    let strip: Vec<f64> = (0..2400)
        .flat_map(|k| {
            let x = [-2.0, -0.5, 0.3, 1.5][k % 4] + rng.random_range(0.0..[0.8, 0.3, 0.3, 0.5][k % 4]);
            [x, rng.random_range(-0.5..0.5), rng.random_range(0.0..1.0)]
        })
        .collect();
    let cells = 4.0 / CloudGrid::new(&strip, 0.01).cell();
    assert!(cells > 64.0, "{cells} cells a row");
    let (met, missed) = check_grid_against_every_ball(&strip, 0.01, 10);
    assert!(met > 20 && missed > 20, "{met} met, {missed} missed");
    check_grid_against_every_ball(&[0.4, 0.1, 0.5], 0.1, 8);
    check_grid_against_every_ball(&[0.4, 0.1, 0.5, 0.4, 0.1, 0.5, 0.4, 0.1, 0.5], 0.1, 9);
}

#[test]
fn a_sparse_cloud_gets_wide_cells() {
    let mut rng = StdRng::seed_from_u64(10);
    let n = 1000;
    let pts: Vec<f64> = (0..3 * n).map(|_| rng.random_range(-500.0..500.0)).collect();
    let grid = CloudGrid::new(&pts, 0.01);
    let cells = (1000.0 / grid.cell()).ceil().powi(3);
    assert!(cells <= (MAX_CELLS_PER_BALL * n + MIN_CELLS) as f64 * 1.01, "{cells} cells of {} m", grid.cell());
    // dense: cells of four radii
    let dense = wall(&mut rng, 5000);
    assert_eq!(CloudGrid::new(&dense, 0.01).cell(), 0.04);
}

/// Spheres covering the Panda's geometry: each geometry's bounding sphere.
fn bounding_spheres(w: &CollisionWorld) -> SphereModel {
    let model = &w.model;
    let (mut links, mut centers, mut radii) = (Vec::new(), Vec::new(), Vec::new());
    for g in w.geometries() {
        let b = g.shape.compute_local_bounding_sphere();
        let c = g.offset * b.center;
        links.push(model.link_names[g.link].as_str());
        centers.push([c.x, c.y, c.z]);
        radii.push(b.radius);
    }
    SphereModel::new(model, &links, &centers, &radii).unwrap()
}

#[test]
fn the_sphere_checker_meets_a_cloud_as_its_balls() {
    let (model, mut base) = panda();
    // the obstacles alone: the bounding spheres of neighbouring links overlap
    base.check_self = false;
    let mut rng = StdRng::seed_from_u64(11);
    let pts = wall(&mut rng, 400);
    let r = 0.02;
    let mut cloud = base.clone();
    cloud.add_points("cloud", &pts, r, None).unwrap();
    let mut balls = base.clone();
    for (k, p) in pts.chunks_exact(3).enumerate() {
        balls.add_sphere(&format!("p{k}"), r, [p[0], p[1], p[2]]).unwrap();
    }
    let spheres = bounding_spheres(&base);
    let (a, b) = (SphereWorld::new(Arc::new(cloud), spheres.clone()).unwrap(), SphereWorld::new(Arc::new(balls), spheres).unwrap());
    let qs: Vec<f64> = (0..300).flat_map(|_| draw(&model, &mut rng)).collect();
    let (mut x, mut y) = (vec![false; 300], vec![false; 300]);
    a.in_collision_batch(&qs, &mut x, &mut SphereScratch::default());
    b.in_collision_batch(&qs, &mut y, &mut SphereScratch::default());
    assert_eq!(x, y);
    let hits = x.iter().filter(|&&h| h).count();
    assert!(hits > 15 && hits < 285, "{hits} of 300 in collision");
    // one configuration at a time, and a motion's states
    let nq = model.nq;
    for k in 0..50 {
        let q = &qs[k * nq..(k + 1) * nq];
        assert_eq!(a.in_collision(q).unwrap(), y[k]);
    }
    let mut s = SphereScratch::default();
    for k in 0..20 {
        let (qa, qb) = (&qs[k * nq..(k + 1) * nq], &qs[(k + 1) * nq..(k + 2) * nq]);
        assert_eq!(a.motion_free(qa, qb, 0.05, &mut s), b.motion_free(qa, qb, 0.05, &mut SphereScratch::default()));
    }
}

#[test]
fn clearance_margins_on_a_cloud_match_its_balls() {
    let (model, base) = panda();
    let mut rng = StdRng::seed_from_u64(12);
    let pts = wall(&mut rng, 300);
    let mut cloud = base.clone();
    cloud.add_points("cloud", &pts, 0.015, None).unwrap();
    let mut balls = base.clone();
    for (k, p) in pts.chunks_exact(3).enumerate() {
        balls.add_sphere(&format!("p{k}"), 0.015, [p[0], p[1], p[2]]).unwrap();
    }
    let (mut s, mut t) = (Scratch::default(), Scratch::default());
    let pm = vec![0.0; cloud.self_pairs().len()];
    let mut differ = 0;
    for k in 0..200 {
        let q = draw(&model, &mut rng);
        let gm = vec![[0.0, 0.01, 0.08][k % 3]; cloud.geometries().len()];
        let c = cloud.clear_by(&q, &gm, &pm, &mut s);
        assert_eq!(c, balls.clear_by(&q, &gm, &pm, &mut t), "clear_by at {q:?}");
        differ += usize::from(c != cloud.clear_by(&q, &vec![0.0; gm.len()], &pm, &mut s));
    }
    assert!(differ > 5, "the margins must matter: {differ}");
}

//! Non-convex meshes (`MeshShape` in src/collision/geometry.rs, `CollisionWorld::add_mesh_as`,
//! `from_urdf_with`): a cup kept as a mesh (a closed mesh is a solid), as V-HACD's convex parts,
//! or as its hull; an open mesh as a surface; signed distances, certified clearance and the
//! robot's own meshes; bad input.

use std::path::PathBuf;
use std::sync::Arc;

use genplan_core::collision::{CollisionWorld, MeshShape, Scratch};
use genplan_core::error::Error;
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::mesh::read_mesh;
use genplan_core::urdf::Urdf;
use nalgebra::Isometry3;

#[path = "common/probe.rs"]
mod probe;
use probe::XYZ;
#[path = "common/temp_dir.rs"]
mod temp_dir;
use temp_dir::TempDir;

/// The probe robot (a ball of radius 0.1 at q), without self pairs.
fn world() -> CollisionWorld {
    let mut w = probe::world();
    w.check_self = false;
    w
}


/// The union of axis-aligned boxes (min, max) as one closed OBJ mesh: the grid of every box
/// face's coordinates, a cell inside when a box holds its centre, a quad (two triangles, facing
/// out) wherever an inside cell meets an outside one. `flip` reverses every triangle; `skip`
/// leaves out the first `skip` quads (an open mesh).
fn box_union_obj(boxes: &[([f64; 3], [f64; 3])], flip: bool, skip: usize) -> String {
    let axes: Vec<Vec<f64>> = (0..3)
        .map(|k| {
            let mut v: Vec<f64> = boxes.iter().flat_map(|(lo, hi)| [lo[k], hi[k]]).collect();
            v.sort_by(f64::total_cmp);
            v.dedup();
            v
        })
        .collect();
    let n = [axes[0].len() - 1, axes[1].len() - 1, axes[2].len() - 1];
    let inside = |c: [isize; 3]| -> bool {
        if (0..3).any(|k| c[k] < 0 || c[k] as usize >= n[k]) {
            return false;
        }
        let m: Vec<f64> = (0..3).map(|k| 0.5 * (axes[k][c[k] as usize] + axes[k][c[k] as usize + 1])).collect();
        boxes.iter().any(|(lo, hi)| (0..3).all(|k| lo[k] < m[k] && m[k] < hi[k]))
    };
    let mut text = String::new();
    let mut count = 0;
    let mut quads = 0;
    for i in 0..n[0] as isize {
        for j in 0..n[1] as isize {
            for k in 0..n[2] as isize {
                if !inside([i, j, k]) {
                    continue;
                }
                for axis in 0..3 {
                    for dir in [-1isize, 1] {
                        let mut nb = [i, j, k];
                        nb[axis] += dir;
                        if inside(nb) {
                            continue;
                        }
                        quads += 1;
                        if quads <= skip {
                            continue;
                        }
                        // the face's corners, counter-clockwise seen from outside
                        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                        let cell = [i as usize, j as usize, k as usize];
                        let at = |du: usize, dv: usize| {
                            let mut p = [0.0; 3];
                            p[axis] = axes[axis][cell[axis] + usize::from(dir > 0)];
                            p[u] = axes[u][cell[u] + du];
                            p[v] = axes[v][cell[v] + dv];
                            p
                        };
                        let mut corners = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
                        if (dir < 0) != flip {
                            corners.reverse();
                        }
                        for p in corners {
                            text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
                        }
                        let b = count * 4 + 1;
                        text += &format!("f {} {} {}\nf {} {} {}\n", b, b + 1, b + 2, b, b + 2, b + 3);
                        count += 1;
                    }
                }
            }
        }
    }
    text
}

/// A cup: a 2 x 2 x 1 block with a 1.2 x 1.2 x 0.6 cavity open at the top; walls and bottom 0.4
/// thick (a probe of radius 0.1 fits wholly inside them).
fn cup() -> Vec<([f64; 3], [f64; 3])> {
    vec![
        ([-1.0, -1.0, 0.0], [1.0, 1.0, 0.4]),
        ([-1.0, -1.0, 0.4], [-0.6, 1.0, 1.0]),
        ([0.6, -1.0, 0.4], [1.0, 1.0, 1.0]),
        ([-0.6, -1.0, 0.4], [0.6, -0.6, 1.0]),
        ([-0.6, 0.6, 0.4], [0.6, 1.0, 1.0]),
    ]
}

/// Probe positions: the cavity's middle, inside a wall and inside the bottom (no surface
/// touched), crossing the rim, above the cup.
const CAVITY: [f64; 3] = [0.0, 0.0, 0.7];
const IN_WALL: [f64; 3] = [0.8, 0.0, 0.7];
const IN_BOTTOM: [f64; 3] = [0.0, 0.0, 0.2];
const ON_RIM: [f64; 3] = [0.8, 0.0, 1.05];
const ABOVE: [f64; 3] = [0.0, 0.0, 1.3];

fn with_cup(kind: MeshShape, flip: bool, skip: usize, dir: &TempDir) -> CollisionWorld {
    let path = dir.write(&format!("cup-{flip}-{skip}.obj"), &box_union_obj(&cup(), flip, skip));
    let mut w = world();
    w.add_mesh_as("cup", &path, [1.0; 3], Isometry3::identity(), kind).unwrap();
    w
}

#[test]
fn the_box_union_is_closed_and_faces_out() {
    let dir = TempDir::new("cup-closed");
    let mesh = read_mesh(&dir.write("cup.obj", &box_union_obj(&cup(), false, 0))).unwrap();
    assert!(mesh.is_closed());
    // 2 x 2 x 1 minus 1.2 x 1.2 x 0.6
    assert!((mesh.signed_volume() - (4.0 - 1.2 * 1.2 * 0.6)).abs() < 1e-9, "{}", mesh.signed_volume());
    let flipped = read_mesh(&dir.write("flipped.obj", &box_union_obj(&cup(), true, 0))).unwrap();
    assert!(flipped.is_closed());
    assert!((flipped.signed_volume() + mesh.signed_volume()).abs() < 1e-9);
    let open = read_mesh(&dir.write("open.obj", &box_union_obj(&cup(), false, 1))).unwrap();
    assert!(!open.is_closed(), "a missing quad leaves free edges");
}

#[test]
fn a_closed_mesh_kept_as_a_mesh_is_a_solid_with_its_cavity_free() {
    let dir = TempDir::new("cup-solid");
    for flip in [false, true] {
        // triangles facing inward are turned outward: the same solid
        let w = with_cup(MeshShape::Mesh, flip, 0, &dir);
        assert!(!w.in_collision(&CAVITY).unwrap(), "the cavity is free (flip {flip})");
        assert!(w.in_collision(&IN_WALL).unwrap(), "a probe wholly inside a wall collides (flip {flip})");
        assert!(w.in_collision(&IN_BOTTOM).unwrap());
        assert!(w.in_collision(&ON_RIM).unwrap());
        assert!(!w.in_collision(&ABOVE).unwrap());
        for q in [CAVITY, IN_WALL, IN_BOTTOM, ON_RIM, ABOVE] {
            assert_eq!(w.in_collision(&q).unwrap(), w.in_collision_exhaustive(&q).unwrap(), "at {q:?}");
        }
        // distances: the cavity's wall 0.6 away (minus the probe); wholly inside a wall, minus
        // the probe's distance to the wall's faces (a lower bound on the depth)
        assert!((w.min_distance(&CAVITY).unwrap() - 0.2).abs() < 1e-9, "{}", w.min_distance(&CAVITY).unwrap());
        assert!((w.min_distance(&IN_WALL).unwrap() + 0.1).abs() < 1e-9, "{}", w.min_distance(&IN_WALL).unwrap());
        // above the middle: the inner rim, (0.6, 0, 1) and its like, is nearest
        assert!((w.min_distance(&ABOVE).unwrap() - (0.45f64.sqrt() - 0.1)).abs() < 1e-9);
        // certified clearance: inside a wall is never clear, the cavity is clear by less than 0.2
        let mut s = Scratch::default();
        assert!(!w.clear_by(&IN_WALL, &[0.0], &[], &mut s));
        assert!(w.clear_by(&CAVITY, &[0.15], &[], &mut s));
        assert!(!w.clear_by(&CAVITY, &[0.25], &[], &mut s));
        // signed distances of points: inside the wall negative, in the cavity positive
        let pts = [IN_WALL, CAVITY].concat();
        let (mut d, mut g) = ([0.0; 2], [0.0; 6]);
        w.point_distances(&pts, 5.0, &mut d, &mut g).unwrap();
        assert!((d[0] + 0.2).abs() < 1e-9, "{d:?}");
        assert!((d[1] - 0.3).abs() < 1e-9, "{d:?}");
        assert!(g[0] > 0.99 || g[0] < -0.99, "the gradient leaves the wall along x: {g:?}");
    }
}

#[test]
fn an_open_mesh_is_a_surface() {
    let dir = TempDir::new("cup-open");
    let w = with_cup(MeshShape::Mesh, false, 1, &dir);
    // the surface still blocks a probe crossing it; wholly inside the (open) wall nothing is met
    assert!(w.in_collision(&ON_RIM).unwrap());
    assert!(!w.in_collision(&IN_WALL).unwrap());
    assert!(!w.in_collision(&CAVITY).unwrap());
    // a flat square is a plate of zero thickness
    let plate = dir.write("plate.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
    let mut w = world();
    w.add_mesh_as("plate", &plate, [1.0; 3], Isometry3::identity(), MeshShape::Mesh).unwrap();
    assert!(w.in_collision(&[0.5, 0.5, 0.05]).unwrap());
    assert!(!w.in_collision(&[0.5, 0.5, 0.15]).unwrap());
    assert!((w.min_distance(&[0.5, 0.5, 0.15]).unwrap() - 0.05).abs() < 1e-9);
}

#[test]
fn the_hull_fills_the_cavity_and_the_parts_keep_it() {
    let dir = TempDir::new("cup-parts");
    let hull = with_cup(MeshShape::Hull, false, 0, &dir);
    assert!(hull.in_collision(&CAVITY).unwrap(), "the hull fills the cavity");
    let parts = with_cup(MeshShape::Decomposed, false, 0, &dir);
    let c = parts.obstacles[0].shape.as_compound().expect("a compound of convex parts");
    assert!(c.shapes().len() >= 2, "{} parts", c.shapes().len());
    assert!(!parts.in_collision(&CAVITY).unwrap(), "the parts leave the cavity free");
    for q in [IN_WALL, IN_BOTTOM, ON_RIM] {
        assert!(parts.in_collision(&q).unwrap(), "at {q:?}");
    }
    assert!(!parts.in_collision(&ABOVE).unwrap());
    let (mut d, mut g) = ([0.0; 1], [0.0; 3]);
    parts.point_distances(&IN_BOTTOM, 5.0, &mut d, &mut g).unwrap();
    assert!(d[0] < 0.0, "inside a part: {d:?}");
}

#[test]
fn a_robot_link_made_of_parts() {
    let dir = TempDir::new("cup-robot");
    dir.write("cup.obj", &box_union_obj(&cup(), false, 0));
    let urdf_text = XYZ.replace(
        r#"<sphere radius="0.1"/>"#,
        &format!(r#"<mesh filename="{}"/>"#, dir.0.join("cup.obj").display()),
    );
    let urdf = Urdf::parse(&urdf_text).unwrap();
    let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap());
    // a ball in the cup's cavity (the cup at the origin)
    for (kind, hit) in [(MeshShape::Hull, true), (MeshShape::Decomposed, false)] {
        let mut w = CollisionWorld::from_urdf_with(model.clone(), &urdf, &[], None, kind).unwrap();
        w.add_sphere("ball", 0.2, CAVITY).unwrap();
        assert_eq!(w.in_collision(&[0.0; 3]).unwrap(), hit, "{kind:?}");
        assert!(w.in_collision(&[0.8, 0.0, 0.0]).unwrap(), "{kind:?}: the ball inside a wall");
    }
}

#[test]
fn bad_shapes_and_meshes_are_refused_naming_them() {
    let e = MeshShape::from_name("convex").unwrap_err();
    assert!(matches!(e, Error::UnknownName { .. }), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("mesh shape") && msg.contains("'convex'") && msg.contains("hull, mesh, decomposed"), "{msg}");
    for (k, name) in MeshShape::NAMES.iter().enumerate() {
        assert_eq!(MeshShape::from_name(name).unwrap().name(), *name);
        assert_eq!(MeshShape::from_name(name).unwrap() as usize, k);
    }
    let dir = TempDir::new("mesh-bad");
    // a flat mesh has no volume to split into convex parts
    let plate = dir.write("plate.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
    let mut w = world();
    let e = w.add_mesh_as("plate", &plate, [1.0; 3], Isometry3::identity(), MeshShape::Decomposed).unwrap_err();
    assert!(matches!(e, Error::Mesh { .. }), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("plate.obj") && msg.contains("mesh 'plate'") && msg.contains("decomposed"), "{msg}");
    let broken = dir.write("broken.obj", "v 0 0 0\nf 1 2 3\n");
    for kind in [MeshShape::Hull, MeshShape::Mesh, MeshShape::Decomposed] {
        let e = w.add_mesh_as("m", &broken, [1.0; 3], Isometry3::identity(), kind).unwrap_err();
        assert!(matches!(e, Error::Mesh { .. }) && e.to_string().contains("broken.obj"), "{e}");
    }
    assert!(w.obstacles.is_empty(), "no failed call added anything");
}

#[test]
fn a_robot_file_names_its_mesh_shape() {
    use genplan_core::robot::RobotDescription;
    let dir = TempDir::new("cup-robot-file");
    dir.write("cup.obj", &box_union_obj(&cup(), false, 0));
    let urdf = XYZ.replace(r#"<sphere radius="0.1"/>"#, r#"<mesh filename="cup.obj"/>"#);
    dir.write("cup.urdf", &urdf);
    let file = |extra: &str| dir.write("cup.toml", &format!("urdf = \"cup.urdf\"\n{extra}"));
    let default = RobotDescription::from_file(file(""), &[]).unwrap();
    assert_eq!(default.mesh_shape, MeshShape::Hull);
    let d = RobotDescription::from_file(file("mesh_shape = \"decomposed\"\n"), &[]).unwrap();
    assert_eq!(d.mesh_shape, MeshShape::Decomposed);
    let (_, world) = d.load().unwrap();
    assert!(world.geometries()[0].shape.as_compound().is_some(), "the link is its convex parts");
    let e = RobotDescription::from_file(file("mesh_shape = \"convex\"\n"), &[]).unwrap_err().to_string();
    assert!(e.contains("cup.toml") && e.contains("'mesh_shape'") && e.contains("hull, mesh, decomposed"), "{e}");
}

#[test]
fn decompositions_are_kept_in_the_cache_folder() {
    use genplan_core::collision::set_decomposition_cache;
    let dir = TempDir::new("cup-cache");
    let cache = dir.0.join("decompositions");
    set_decomposition_cache(Some(cache.clone()));
    let first = with_cup(MeshShape::Decomposed, false, 0, &dir);
    let files: Vec<PathBuf> = std::fs::read_dir(&cache).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(files.len(), 1, "one file per mesh and parameters: {files:?}");
    let parts = |w: &CollisionWorld| w.obstacles[0].shape.as_compound().unwrap().shapes().len();
    // read back: the same parts, the same answers
    let again = with_cup(MeshShape::Decomposed, false, 0, &dir);
    assert_eq!(parts(&first), parts(&again));
    for q in [CAVITY, IN_WALL, IN_BOTTOM, ON_RIM, ABOVE] {
        assert_eq!(first.in_collision(&q).unwrap(), again.in_collision(&q).unwrap());
        assert_eq!(first.min_distance(&q).unwrap().to_bits(), again.min_distance(&q).unwrap().to_bits());
    }
    // a damaged file is computed anew and rewritten
    let bytes = std::fs::read(&files[0]).unwrap();
    std::fs::write(&files[0], &bytes[..bytes.len() - 5]).unwrap();
    let fixed = with_cup(MeshShape::Decomposed, false, 0, &dir);
    assert_eq!(parts(&fixed), parts(&first));
    assert_eq!(std::fs::read(&files[0]).unwrap(), bytes);
    set_decomposition_cache(None);
}

/// Two decomposed links (a cup fixed at the origin, a cup a third its size moved by three
/// prismatic joints): the world answers as parry's test of the two compounds does, for the self
/// pair and for an obstacle, including where their hulls meet and the parts do not (the small
/// cup in the big one's cavity), and the exhaustive check agrees.
#[test]
fn decomposed_links_answer_as_their_parts() {
    use parry3d_f64::query;
    use genplan_core::collision::Hull;
    use parry3d_f64::shape::{Ball, ConvexPolyhedron, Shape};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    let dir = TempDir::new("cup-pair");
    let path = dir.write("cup.obj", &box_union_obj(&cup(), false, 0));
    let mesh = |scale: &str| format!(r#"<collision><geometry><mesh filename="{}" scale="{scale}"/></geometry></collision>"#, path.display());
    let urdf_text = XYZ
        .replace(r#"<link name="base"/>"#, &format!(r#"<link name="base">{}</link>"#, mesh("1 1 1")))
        .replace(r#"<sphere radius="0.1"/>"#, &mesh("0.3 0.3 0.3").replace("<collision><geometry>", "").replace("</geometry></collision>", ""));
    let urdf = Urdf::parse(&urdf_text).unwrap();
    let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap());
    let mut w = CollisionWorld::from_urdf_with(model.clone(), &urdf, &[], None, MeshShape::Decomposed).unwrap();
    assert_eq!(w.self_pairs().len(), 1, "the two cups are a self pair");
    let hull_of = |s: &dyn Shape| {
        let c = s.as_compound().expect("a compound of convex parts");
        assert!(c.shapes().len() >= 2, "{} parts", c.shapes().len());
        let pts: Vec<_> = c.shapes().iter().flat_map(|(p, part)| part.as_shape::<Hull>().unwrap().polyhedron().points().iter().map(|v| p * v).collect::<Vec<_>>()).collect();
        ConvexPolyhedron::from_convex_hull(&pts).unwrap()
    };
    let (ga, gb) = (&w.geometries()[0], &w.geometries()[1]);
    let (sa, sb) = (ga.shape.clone(), gb.shape.clone());
    let (ha, hb) = (hull_of(&*sa), hull_of(&*sb));
    let (oa, ob, la, lb) = (ga.offset, gb.offset, ga.link, gb.link);
    let ball = Ball::new(0.15);
    let at_ball = Isometry3::translation(0.0, 0.0, 2.0);
    w.add_sphere("ball", 0.15, [0.0, 0.0, 2.0]).unwrap();
    let mut rng = StdRng::seed_from_u64(11);
    let (mut links, mut hulls_only, mut hits) = (Vec::new(), 0, 0);
    for k in 0..2000 {
        // every other one in and around the big cup's cavity, where the hulls meet
        let q = if k % 2 == 0 {
            [rng.random_range(-0.4..0.4), rng.random_range(-0.4..0.4), rng.random_range(0.3..0.8)]
        } else {
            [rng.random_range(-1.4..1.4), rng.random_range(-1.4..1.4), rng.random_range(-0.5..2.2)]
        };
        model.forward_kinematics(&q, &mut links).unwrap();
        let (pa, pb) = (links[la] * oa, links[lb] * ob);
        let parts = query::intersection_test(&pa, &*sa, &pb, &*sb).unwrap();
        let hulls = query::intersection_test(&pa, &ha, &pb, &hb).unwrap();
        hulls_only += usize::from(hulls && !parts);
        hits += usize::from(parts);
        // the cups against a ball above the fixed one
        let on_ball = query::intersection_test(&pb, &*sb, &at_ball, &ball).unwrap() || query::intersection_test(&pa, &*sa, &at_ball, &ball).unwrap();
        w.check_self = true;
        assert_eq!(w.in_collision(&q).unwrap(), parts || on_ball, "at {q:?}");
        assert_eq!(w.in_collision_exhaustive(&q).unwrap(), parts || on_ball, "exhaustive at {q:?}");
        w.check_self = false;
        assert_eq!(w.in_collision(&q).unwrap(), on_ball, "the ball at {q:?}");
    }
    assert!(hits > 100 && hulls_only > 50, "{hits} in contact, {hulls_only} with the hulls alone meeting");
}

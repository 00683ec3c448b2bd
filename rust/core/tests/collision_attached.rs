//! Attached objects (`CollisionWorld::attach`, src/collision/attached.rs) and clearance margins
//! (`CollisionWorld::set_padding`, `set_obstacle_padding`, in src/collision/world.rs): the
//! filtered check against the exhaustive one with the attached geometry, the touch links left
//! out, and a padded check against the distances of `close_pairs`.

use genplan_core::collision::CollisionWorld;
use genplan_core::kinematics::KinematicModel;
use genplan_core::robot::preset;
use genplan_core::Scratch;
use nalgebra::Isometry3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn draw(model: &KinematicModel, rng: &mut StdRng) -> Vec<f64> {
    model.lower.iter().zip(&model.upper).map(|(l, u)| rng.random_range(*l..=*u)).collect()
}

/// The Panda with a rod in its hand (0.15 to 0.35 m along the hand's z axis).
fn panda_with_rod() -> (std::sync::Arc<KinematicModel>, CollisionWorld, Vec<String>) {
    let (model, mut world) = preset("panda").unwrap().load().unwrap();
    world.add_box("rod", [0.015, 0.015, 0.1], Isometry3::translation(0.0, 0.0, 0.25)).unwrap();
    let q0 = vec![0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let touch = world.attach("rod", "panda_hand", &[], Some(&q0)).unwrap();
    (model, world, touch)
}

#[test]
fn an_attached_object_is_robot_geometry_checked_as_the_exhaustive_loop_does() {
    let (model, mut world, touch) = panda_with_rod();
    assert!(touch.iter().any(|l| l == "panda_hand"), "{touch:?}");
    assert!(world.obstacles.is_empty(), "the rod left the obstacles");
    let rod = world.geometries().iter().position(|g| g.name == "rod").unwrap();
    let hand = model.link_index("panda_hand").unwrap();
    for &(i, j) in world.self_pairs() {
        if i == rod || j == rod {
            let other = &world.geometries()[if i == rod { j } else { i }];
            assert!(!touch.contains(&model.link_names[other.link]), "{} is a touch link", other.name);
            assert_ne!(model.body_of_link[other.link], model.body_of_link[hand]);
        }
    }
    world.add_box("box", [0.1, 0.1, 0.1], Isometry3::translation(0.5, 0.0, 0.4)).unwrap();
    let mut rng = StdRng::seed_from_u64(3);
    let mut s = Scratch::default();
    let mut hits = 0;
    for _ in 0..2000 {
        let q = draw(&model, &mut rng);
        let hit = world.in_collision_unchecked(&q, &mut s);
        assert_eq!(hit, world.in_collision_exhaustive(&q).unwrap());
        hits += usize::from(hit);
    }
    assert!(hits > 100 && hits < 1900, "{hits} hits");
}

#[test]
fn a_padded_check_is_an_obstacle_pair_closer_than_its_padding() {
    let (model, mut world, _) = panda_with_rod();
    world.check_self = false;
    world.add_box("box", [0.1, 0.1, 0.1], Isometry3::translation(0.5, 0.0, 0.4)).unwrap();
    world.add_sphere("ball", 0.08, [0.0, 0.5, 0.5]).unwrap();
    world.add_halfspace("floor", [0.0, 0.0, 1.0], -0.3).unwrap();
    world.set_padding(0.04).unwrap();
    world.set_obstacle_padding("ball", Some(0.1)).unwrap();
    let pad = |name: &str| if name == "ball" { 0.1 } else { 0.04 };
    let mut rng = StdRng::seed_from_u64(4);
    let mut s = Scratch::default();
    let (mut hits, mut n) = (0, 0);
    for _ in 0..2000 {
        let q = draw(&model, &mut rng);
        let slack = world.close_pairs(&q, 0.2).unwrap().iter().map(|p| p.distance - pad(&p.b)).fold(f64::INFINITY, f64::min);
        if slack.abs() < 1e-7 {
            continue;
        }
        n += 1;
        let hit = world.in_collision_unchecked(&q, &mut s);
        assert_eq!(hit, slack <= 0.0, "slack {slack}");
        hits += usize::from(hit);
    }
    assert!(n > 1900 && hits > 100 && hits < n - 100, "{hits} hits of {n}");
}

#[test]
fn bad_attachments_and_margins_are_refused() {
    let (_, mut world) = preset("panda").unwrap().load().unwrap();
    world.add_box("rod", [0.01, 0.01, 0.1], Isometry3::identity()).unwrap();
    world.add_halfspace("floor", [0.0, 0.0, 1.0], 0.0).unwrap();
    let e = world.attach("rod", "wrist", &[], None).unwrap_err().to_string();
    assert!(e.contains("unknown link 'wrist'") && e.contains("panda_hand"), "{e}");
    let e = world.attach("crate", "panda_hand", &[], None).unwrap_err().to_string();
    assert!(e.contains("unknown obstacle 'crate'"), "{e}");
    let e = world.attach("floor", "panda_hand", &[], None).unwrap_err().to_string();
    assert!(e.contains("half-space"), "{e}");
    let e = world.attach("rod", "panda_hand", &["elbow".to_string()], None).unwrap_err().to_string();
    assert!(e.contains("unknown link 'elbow'"), "{e}");
    assert_eq!(world.obstacles.len(), 2, "nothing attached");
    for bad in [-0.01, f64::NAN, f64::INFINITY, 11.0] {
        assert!(world.set_padding(bad).unwrap_err().to_string().contains("padding"));
        assert!(world.set_obstacle_padding("rod", Some(bad)).unwrap_err().to_string().contains("obstacle 'rod' padding"));
    }
    assert_eq!(world.padding(), 0.0);
}

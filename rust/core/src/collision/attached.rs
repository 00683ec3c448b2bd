//! Objects attached to the robot's links ([`CollisionWorld::attach`]): a tool, a held part, a
//! tray. Each becomes one more robot geometry on its link, so every query that checks the
//! robot's own geometry checks it too (in collision, minimum distance, close pairs, the clearance
//! of certified motions and the swept-motion bounds built from the world), against the obstacles
//! (with their padding) and against the robot's other links, minus its touch links.

use std::collections::BTreeSet;

use nalgebra::Isometry3;
use parry3d_f64::query;

use super::geometry::bounding_sphere;
use super::groups::LinkGroups;
use super::{CollisionWorld, RobotGeometry, Scratch};
use crate::error::{unknown, Error, Result};

/// An object attached to a link ([`CollisionWorld::attach`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Attached {
    /// Its name: the name of its robot geometry.
    pub name: String,
    /// The link that holds it (index into the model's links).
    pub link: usize,
    /// Its index in [`CollisionWorld::geometries`].
    pub geometry: usize,
    /// The links it is never checked against (indices, ascending): the holding link's rigid body,
    /// the rigid bodies of the links named by the caller, and the links whose geometry touches it
    /// at the configuration given to [`CollisionWorld::attach`] (MoveIt's touch links).
    pub touch_links: Vec<usize>,
}

impl CollisionWorld {
    /// The objects attached to the robot, in the order attached.
    pub fn attached(&self) -> &[Attached] {
        &self.attached
    }

    /// Attach obstacle `name` to `link`: the obstacle (added as usual with an `add_*` method, its
    /// pose read as the pose in the link's frame) leaves the obstacles and becomes a robot
    /// geometry of that name on the link, moving with it. It is checked against the obstacles
    /// and the robot's other geometry, except the links it may touch: the holding link's rigid
    /// body, the rigid bodies of `touch_links` (link names) and, with `q` (a configuration,
    /// checked), the links whose geometry it intersects at `q` (the robot's default
    /// configuration: what the grasp itself touches). A half-space or a point cloud cannot be attached; an unknown obstacle or link
    /// lists the known ones; a name already taken by a robot geometry is refused. Returns the
    /// touch links' names.
    pub fn attach(&mut self, name: &str, link: &str, touch_links: &[String], q: Option<&[f64]>) -> Result<Vec<String>> {
        let Some(k) = self.obstacles.iter().position(|o| o.name == name) else {
            let known: Vec<&str> = self.obstacles.iter().map(|o| o.name.as_str()).collect();
            return Err(unknown("obstacle", name, &known));
        };
        let li = self.model.link_index(link)?;
        let o = &self.obstacles[k];
        if o.cloud.is_some() || o.shape.as_halfspace().is_some() {
            return Err(Error::Invalid(format!("attached object '{name}': a half-space or a point cloud cannot be attached")));
        }
        if self.geometries.iter().any(|g| g.name == name) {
            return Err(Error::Invalid(format!("attached object '{name}': the robot already has a geometry of that name")));
        }
        // whole rigid bodies: the links joined by fixed or locked joints move as one
        let bodies = &self.model.body_of_link;
        let body = |l: usize| (0..bodies.len()).filter(move |&k| bodies[k] == bodies[l]);
        let mut touch: BTreeSet<usize> = body(li).collect();
        for t in touch_links {
            touch.extend(body(self.model.link_index(t)?));
        }
        if let Some(q) = q {
            self.model.check_configuration(q)?;
        }
        let (shape, offset) = (o.shape.clone(), o.pose);
        let (center, radius) = bounding_sphere(&shape);
        let local_aabb = shape.compute_local_aabb();
        let geometry = RobotGeometry { name: name.to_string(), link: li, offset, shape, center, radius, local_aabb };
        if let Some(q) = q {
            let mut s = Scratch::default();
            self.geometry_poses(q, &mut s);
            let pose: Isometry3<f64> = s.links[li] * offset;
            for (j, g) in self.geometries.iter().enumerate() {
                if !touch.contains(&g.link) && query::intersection_test(&pose, &*geometry.shape, &s.poses[j], &*g.shape).unwrap_or(true) {
                    touch.insert(g.link);
                }
            }
        }
        self.obstacles.remove(k);
        let index = self.geometries.len();
        for (j, g) in self.geometries.iter().enumerate() {
            if !touch.contains(&g.link) {
                self.self_pairs.push((j, index));
            }
        }
        self.geometries.push(geometry);
        self.groups = LinkGroups::new(&self.geometries, &self.self_pairs);
        let touch_links: Vec<usize> = touch.into_iter().collect();
        let names = touch_links.iter().map(|&l| self.model.link_names[l].clone()).collect();
        self.attached.push(Attached { name: name.to_string(), link: li, geometry: index, touch_links });
        Ok(names)
    }
}

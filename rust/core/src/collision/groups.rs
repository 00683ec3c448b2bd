//! The robot's geometry grouped by link ([`LinkGroups`]): one bounding sphere and one box per
//! link (in the link frame), and the self-collision pairs grouped by the link pair they join.
//!
//! `CollisionWorld::in_collision_unchecked` (`world.rs`) tests these link volumes first: a link
//! pair whose spheres or oriented boxes are apart skips all its geometry pairs, and a link that
//! meets nothing is never posed geometry by geometry. The Panda's collision model has 39 shapes
//! on 10 links and 252 self pairs on 36 link pairs; posing every shape and filtering every pair
//! was most of a check (rust/core/benches are at benches/collision.rs). The geometry pairs that
//! remain go through the same filters and narrow phase as before, so the answer is unchanged
//! (tests/collision_broad_phase.rs compares it with an exhaustive loop).

use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::Point3;
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};

use super::RobotGeometry;

/// The geometries attached to one link, with volumes bounding all of them in the link frame.
#[derive(Clone, Debug)]
pub(super) struct LinkGroup {
    /// The link's index in the kinematic model.
    pub link: usize,
    /// Indices into the world's geometries, ascending.
    pub geometries: Vec<usize>,
    /// A sphere containing every geometry's bounding sphere: centre (link frame) and radius.
    pub center: Point3<f64>,
    pub radius: f64,
    /// A box containing every geometry's local box placed at its offset (link frame).
    pub local_aabb: Aabb,
}

/// The self pairs between the geometries of two link groups `a <= b` (`a == b` cannot happen
/// with a URDF model, whose geometries on one link share a body, but is kept general):
/// `pairs[start..end]` of [`LinkGroups::pairs`]. Compact (24 bytes), as a check scans them all.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct GroupPair {
    pub a: u32,
    pub b: u32,
    pub start: u32,
    pub end: u32,
    /// The squared sum of the two groups' sphere radii: the spheres are apart when their
    /// centres' squared distance exceeds it.
    pub reach2: f64,
}

/// The geometries grouped by link and the self pairs grouped by link pair (see the module text).
#[derive(Clone, Debug, Default)]
pub(super) struct LinkGroups {
    pub groups: Vec<LinkGroup>,
    /// The world's self pairs, reordered so that each [`GroupPair`]'s are contiguous.
    pub pairs: Vec<(usize, usize)>,
    /// For each of `pairs`, its index in the world's self pairs (where per-pair margins are).
    pub index: Vec<usize>,
    pub group_pairs: Vec<GroupPair>,
    /// Unique to this grouping (clones share it): what a `Scratch` holding copies of
    /// `group_pairs` checks they came from (1, 2, ... in the order groupings are built; 0 for
    /// the empty default).
    pub id: u64,
}

/// The last [`LinkGroups::id`] handed out.
static LAST_ID: AtomicU64 = AtomicU64::new(0);

impl LinkGroups {
    /// Group `geometries` by link and `self_pairs` (indices into `geometries`) by link pair.
    pub fn new(geometries: &[RobotGeometry], self_pairs: &[(usize, usize)]) -> LinkGroups {
        let mut groups: Vec<LinkGroup> = Vec::new();
        let mut group_of = vec![0; geometries.len()];
        for (i, g) in geometries.iter().enumerate() {
            let k = match groups.iter().position(|x| x.link == g.link) {
                Some(k) => k,
                None => {
                    groups.push(LinkGroup {
                        link: g.link,
                        geometries: Vec::new(),
                        center: Point3::origin(),
                        radius: 0.0,
                        local_aabb: Aabb::new_invalid(),
                    });
                    groups.len() - 1
                }
            };
            groups[k].geometries.push(i);
            group_of[i] = k;
        }
        for group in &mut groups {
            // the box around the members' boxes; the sphere centred on it, reaching the farthest
            // member's bounding sphere
            let mut aabb = Aabb::new_invalid();
            for &i in &group.geometries {
                let g = &geometries[i];
                aabb.merge(&g.local_aabb.transform_by(&g.offset));
            }
            let c = aabb.center();
            let mut r: f64 = 0.0;
            for &i in &group.geometries {
                let g = &geometries[i];
                r = r.max((g.offset * g.center - c).norm() + g.radius);
            }
            // a little slack so that rounding in the world transforms never rules out a touch
            group.center = c;
            group.radius = r * (1.0 + 1e-9) + 1e-12;
            group.local_aabb = aabb.loosened(1e-12 + 1e-9 * aabb.half_extents().amax());
        }
        let mut keyed: Vec<((usize, usize), (usize, usize), usize)> = self_pairs
            .iter()
            .enumerate()
            .map(|(p, &(i, j))| {
                let (a, b) = (group_of[i], group_of[j]);
                ((a.min(b), a.max(b)), (i, j), p)
            })
            .collect();
        keyed.sort_by_key(|&(key, _, p)| (key, p));
        let mut group_pairs: Vec<GroupPair> = Vec::new();
        let mut pairs = Vec::with_capacity(keyed.len());
        let mut index = Vec::with_capacity(keyed.len());
        for (p, &(key, pair, original)) in keyed.iter().enumerate() {
            match group_pairs.last_mut() {
                Some(gp) if (gp.a as usize, gp.b as usize) == key => gp.end = p as u32 + 1,
                _ => {
                    let r = groups[key.0].radius + groups[key.1].radius;
                    group_pairs.push(GroupPair { a: key.0 as u32, b: key.1 as u32, start: p as u32, end: p as u32 + 1, reach2: r * r })
                }
            }
            pairs.push(pair);
            index.push(original);
        }
        let id = LAST_ID.fetch_add(1, Ordering::Relaxed) + 1;
        LinkGroups { groups, pairs, index, group_pairs, id }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::preset;

    #[test]
    fn groups_cover_every_geometry_and_pair_once() {
        for name in ["panda", "talos"] {
            let (_, world) = preset(name).unwrap().load().unwrap();
            let lg = LinkGroups::new(world.geometries(), world.self_pairs());
            let mut seen = vec![0; world.geometries().len()];
            for g in &lg.groups {
                for &i in &g.geometries {
                    seen[i] += 1;
                    let geo = &world.geometries()[i];
                    assert_eq!(geo.link, g.link);
                    // every member inside the group's volumes
                    let c = geo.offset * geo.center;
                    assert!((c - g.center).norm() + geo.radius <= g.radius, "{name}: sphere of {}", geo.name);
                    let b = geo.local_aabb.transform_by(&geo.offset);
                    assert!(g.local_aabb.contains(&b), "{name}: box of {}", geo.name);
                }
            }
            assert!(seen.iter().all(|&k| k == 1), "{name}: each geometry in one group");
            let mut pairs = lg.pairs.clone();
            let mut expected = world.self_pairs().to_vec();
            pairs.sort_unstable();
            expected.sort_unstable();
            assert_eq!(pairs, expected, "{name}: the same self pairs");
            for (p, &k) in lg.pairs.iter().zip(&lg.index) {
                assert_eq!(*p, world.self_pairs()[k]);
            }
            let mut covered = 0;
            for gp in &lg.group_pairs {
                let (a, b, start, end) = (gp.a as usize, gp.b as usize, gp.start as usize, gp.end as usize);
                assert!(a <= b && start < end && start == covered);
                assert_eq!(gp.reach2, (lg.groups[a].radius + lg.groups[b].radius).powi(2));
                covered = end;
                for &(i, j) in &lg.pairs[start..end] {
                    let (li, lj) = (world.geometries()[i].link, world.geometries()[j].link);
                    let (la, lb) = (lg.groups[a].link, lg.groups[b].link);
                    assert!((li, lj) == (la, lb) || (li, lj) == (lb, la));
                }
            }
            assert_eq!(covered, lg.pairs.len());
            assert!(lg.group_pairs.len() <= lg.pairs.len());
            if name == "panda" {
                // 39 shapes on 10 links
                assert!(lg.groups.len() < 12 && lg.group_pairs.len() < lg.pairs.len() / 4, "{} link pairs", lg.group_pairs.len());
            }
        }
    }
}

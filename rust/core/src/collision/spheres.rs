//! The robot as spheres ([`SphereModel`]: each link's geometry covered by spheres, given in the
//! link frames) checked against a world's obstacles ([`SphereWorld`]): the fast, conservative
//! collision check.
//!
//! The spheres come from `genplan.spheres.robot_spheres` (a guaranteed cover of each link's
//! collision solid) or from the caller. Because they cover the links, a configuration free by the
//! spheres is free by the exact geometry; the converse does not hold (the spheres reach a little
//! beyond the links: false positives).
//!
//! A check runs on `N` configurations at once, as lanes ([`SphereScratch`]): the kinematics'
//! joints that place the links with spheres (only those) run in `f32` across the lanes, each
//! joint one product of rotation matrices per lane (its angle's sine and cosine in `f64`), so
//! that the kinematics, placing the spheres and testing them against each obstacle are loops
//! over the lanes of fixed-size arrays, which the compiler turns into vector instructions (`N` = [`LANES`] = 8: one AVX register of `f32`, two SSE
//! ones). On x86-64 the kernel is compiled a second time with AVX2 and FMA enabled and chosen at
//! run time when the processor has them (the build targets the x86-64 baseline: no
//! `target-cpu` in the build's flags). One configuration is the same kernel with `N` = 1; a
//! motion's states are the lanes of one pass ([`SphereWorld::motion_free`]: VAMP's "rake").
//!
//! Obstacles are tested in closed form: box (the squared distance from the centre to the box
//! in its frame), sphere, cylinder (radial and axial excess), capsule (distance to its segment),
//! half-space (height above the plane). A mesh obstacle is the world's shape of it (its hull,
//! its triangles, a closed mesh as a solid, or its convex parts), tested with the exact check's
//! ball-versus-shape intersection test per lane: the same shape the exact check uses, so no
//! geometry differs between the two checks, and the test runs only for the spheres of a link
//! whose bounding sphere meets the shape's box. A point cloud is its balls in their grid: per
//! lane, a sphere meets the cloud when a ball's centre lies within the two radii of its centre
//! ([`CloudGrid::any_within`](super::CloudGrid::any_within): the grid's cells around the sphere).
//!
//! The broad phase: each link's spheres have a bounding sphere; an obstacle is tested against a
//! link's spheres only in the lanes where that bounding sphere meets the obstacle's world box (or
//! reaches below a half-space's plane). Before that test, per link, the box of its bounding
//! sphere's centres over the lanes is tested against 8 obstacles at once (their boxes grown, when
//! the checker is built, by the link's radius, the obstacle's padding and a margin beyond the
//! `f32` rounding): only the obstacles it meets get the per-lane test, so that a link far from
//! most obstacles costs a few vector instructions (a pure prune: the same answers). A moving link of more than [`MOVING_GROUP`] spheres is
//! split when the checker is built into spatial groups (halved at the median of the longest
//! side of their centres' box, the spheres reordered so that each group's are contiguous), each
//! with its bounding sphere: where the link's bounding sphere is near an obstacle, each group's
//! bounding sphere is tested against the obstacle first (the same closed-form test), and only
//! the groups it meets are placed and tested sphere by sphere. Self-collision tests the sphere pairs of the link pairs
//! the world checks (its self pairs, the SRDF's and the computed disabled pairs left out),
//! after the same test on the two links' bounding spheres, and each sphere of the one link
//! against the other's bounding sphere before that link's spheres. Per check only the moving
//! links' bounding spheres are placed in the world; a link's spheres are placed when a test
//! first needs them (its bounding sphere meets an obstacle, a fixed link's tree leaf or a link
//! of its self pairs), so a link clear of everything costs its bounding sphere alone (a robot of
//! many spheres, such as Baxter's arms, places few of them per check). A batch stops when every
//! lane is in collision; a motion at its first state in collision.
//!
//! An obstacle's padding (its own, else the world's: [`CollisionWorld::padding`]) grows every
//! sphere and bounding sphere tested against it, so a configuration is in collision when a
//! sphere comes closer to the obstacle than the padding, as in the exact check; self pairs are
//! not padded.
//!
//! Links fixed to the world (a fixed base's links that no joint moves: a pedestal, a torso) are
//! in the same place in every configuration, so their spheres are placed once, in the world
//! frame, when the checker is built, and checked then against the obstacles and against the
//! other fixed links of their self pairs: any contact there makes every configuration collide
//! (a start inside it stays refused). Per configuration only the moving links are placed; a
//! self pair of a moving link and a fixed one walks a tree of bounding spheres over the fixed
//! link's spheres (halved at the median of the longest side of their centres' box, leaves of
//! up to [`FIXED_LEAF`] spheres) with the moving link's bounding sphere, then its spheres, so
//! that a fixed link of thousands of spheres costs the few leaves near the moving link.
//!
//! The `f32` rounding (of the link poses, the obstacles and the arithmetic: relative 6e-8, so
//! below 1 um within 10 m of the origin) is covered by [`F32_SLACK`], added to every radius.

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d_f64::shape::Ball;

use super::CollisionWorld;
use crate::error::{check_finite, unknown, Error, Result};
use crate::kinematics::KinematicModel;

/// Lanes of the batch kernel: configurations checked together.
pub const LANES: usize = 8;

/// A block of fewer rows than this is checked one row at a time.
pub const SHORT_BLOCK: usize = 3;

/// Added to every sphere radius (m) in the `f32` tests, so that rounding never hides a contact.
pub const F32_SLACK: f32 = 1e-5;

/// The most spheres of a fixed link in one leaf of its tree of bounding spheres.
pub const FIXED_LEAF: usize = 8;

/// The most spheres of a moving link in one group (a link of more spheres is split into
/// spatial groups, each with its bounding sphere, tested before its spheres).
pub const MOVING_GROUP: usize = 8;

/// Per-link spheres as struct-of-arrays: sphere i belongs to link `link[i]` (an index into the
/// kinematic model's links) with centre (`x[i]`, `y[i]`, `z[i]`) in that link's frame and radius
/// `radius[i]` (m). Sorted by link (the spheres of one link are contiguous, in the given order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SphereModel {
    /// Link index of each sphere.
    pub link: Vec<usize>,
    /// Centre x in the link frame.
    pub x: Vec<f64>,
    /// Centre y in the link frame.
    pub y: Vec<f64>,
    /// Centre z in the link frame.
    pub z: Vec<f64>,
    /// Radius (positive).
    pub radius: Vec<f64>,
}

impl SphereModel {
    /// Spheres from per-sphere link names (links of `model`), centres in the link frames and
    /// radii, checked: as many of each, known links, finite centres, positive finite radii.
    pub fn new(model: &KinematicModel, links: &[&str], centers: &[[f64; 3]], radii: &[f64]) -> Result<SphereModel> {
        let n = links.len();
        for (what, len) in [("centers", centers.len()), ("radii", radii.len())] {
            if len != n {
                return Err(Error::Shape { what: format!("spheres: {what} (one per link name)"), expected: n, got: len });
            }
        }
        let flat: Vec<f64> = centers.iter().flatten().copied().collect();
        check_finite("spheres: centers", &flat)?;
        check_finite("spheres: radii", radii)?;
        if let Some(i) = radii.iter().position(|&r| r <= 0.0) {
            return Err(Error::Invalid(format!("spheres: radii: element {i} must be positive, got {}", radii[i])));
        }
        let mut order: Vec<(usize, usize)> = Vec::with_capacity(n);
        for (i, name) in links.iter().enumerate() {
            order.push((model.link_index(name)?, i));
        }
        // stable: the spheres of one link keep their order
        order.sort_by_key(|&(l, _)| l);
        let mut m = SphereModel::default();
        for (l, i) in order {
            m.link.push(l);
            m.x.push(centers[i][0]);
            m.y.push(centers[i][1]);
            m.z.push(centers[i][2]);
            m.radius.push(radii[i]);
        }
        Ok(m)
    }

    /// The number of spheres.
    pub fn len(&self) -> usize {
        self.link.len()
    }

    /// True when there is no sphere.
    pub fn is_empty(&self) -> bool {
        self.link.is_empty()
    }
}

/// The spheres of one link, `start..end` of the model's, with a sphere bounding them (link frame).
/// `fixed`: the link is fixed to the world (no joint moves it).
#[derive(Clone, Debug)]
struct LinkSpheres {
    link: usize,
    start: usize,
    end: usize,
    center: [f32; 3],
    radius: f32,
    fixed: bool,
    /// The attached object (index into the world's [`CollisionWorld::attached`]) these spheres
    /// cover, on its holding link; None for the link's own.
    object: Option<usize>,
    /// A moving link's groups of spheres: `groups` of [`SphereWorld`] `g0..g1` (one group, the
    /// whole link, for a link of at most [`MOVING_GROUP`] spheres; none for a fixed link).
    g0: usize,
    g1: usize,
}

/// A group of a moving link's spheres, `start..end` (the checker's order: each link's spheres
/// reordered so that a group's are contiguous), and the sphere bounding them in the link frame
/// (its radius with two [`F32_SLACK`]: its own and one for its centre and its spheres' being
/// rounded to `f32` separately, so that the group's test is never tighter than its spheres').
#[derive(Clone, Debug)]
struct Group {
    center: [f32; 3],
    radius: f32,
    start: usize,
    end: usize,
}

/// Splits the spheres `order` (indices of `spheres`, reordered: each group contiguous) into
/// groups of at most [`MOVING_GROUP`], halving at the median of the centres along the longest
/// side of their box (as a fixed link's tree), and appends the groups, their runs starting at
/// `start`, to `groups`.
fn split_groups(spheres: &SphereModel, order: &mut [usize], start: usize, groups: &mut Vec<Group>) {
    let c = |i: usize| Point3::new(spheres.x[i], spheres.y[i], spheres.z[i]);
    if order.len() > MOVING_GROUP {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &i in order.iter() {
            for k in 0..3 {
                lo[k] = lo[k].min(c(i)[k]);
                hi[k] = hi[k].max(c(i)[k]);
            }
        }
        let axis = (0..3).max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b]))).unwrap_or(0);
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |&a, &b| c(a)[axis].total_cmp(&c(b)[axis]));
        let (left, right) = order.split_at_mut(mid);
        split_groups(spheres, left, start, groups);
        split_groups(spheres, right, start + mid, groups);
        return;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &i in order.iter() {
        for k in 0..3 {
            lo[k] = lo[k].min(c(i)[k] - spheres.radius[i]);
            hi[k] = hi[k].max(c(i)[k] + spheres.radius[i]);
        }
    }
    let center = Point3::new(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]));
    let reach = order.iter().map(|&i| (c(i) - center).norm() + spheres.radius[i]).fold(0.0, f64::max);
    groups.push(Group { center: f3(&center.coords), radius: (reach * (1.0 + 1e-6)) as f32 + 2.0 * F32_SLACK, start, end: start + order.len() });
}

/// A node of a fixed link's tree: the sphere bounding the fixed spheres `start..end` (world
/// frame, [`FixedSpheres`]' order, its radius with [`F32_SLACK`]); a leaf when it holds at most
/// [`FIXED_LEAF`] spheres, else its children are the next node and node `right`.
#[derive(Clone, Debug)]
struct FixedNode {
    center: [f32; 3],
    radius: f32,
    start: usize,
    end: usize,
    right: usize,
}

/// The spheres of the fixed links in the world frame (`f32`, struct of arrays), each link's a
/// contiguous run ordered by its tree, and the trees' nodes.
#[derive(Clone, Debug, Default)]
struct FixedSpheres {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    radius: Vec<f32>,
    nodes: Vec<FixedNode>,
    /// Per fixed link (an index into the world's `links`): its tree's root node.
    root: Vec<(usize, usize)>,
}

impl FixedSpheres {
    /// Adds the spheres of the fixed link `ls` at its world pose `pose` and their tree.
    fn add_link(&mut self, spheres: &SphereModel, ls: &LinkSpheres, pose: &Isometry3<f64>) {
        let world: Vec<(Point3<f64>, f64)> = (ls.start..ls.end)
            .map(|i| (pose * Point3::new(spheres.x[i], spheres.y[i], spheres.z[i]), spheres.radius[i]))
            .collect();
        let mut order: Vec<usize> = (0..world.len()).collect();
        let base = self.x.len();
        self.build(&world, &mut order, base);
        for &i in &order {
            let (c, r) = world[i];
            self.x.push(c.x as f32);
            self.y.push(c.y as f32);
            self.z.push(c.z as f32);
            self.radius.push(r as f32);
        }
    }

    /// The node of the spheres `order` (indices into `world`, which it reorders: each half
    /// after the split contiguous) whose run starts at `start` of the fixed spheres, and the
    /// nodes below it (pre-order); returns its index.
    fn build(&mut self, world: &[(Point3<f64>, f64)], order: &mut [usize], start: usize) -> usize {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &i in order.iter() {
            let (c, r) = world[i];
            for k in 0..3 {
                lo[k] = lo[k].min(c[k] - r);
                hi[k] = hi[k].max(c[k] + r);
            }
        }
        let center = Point3::new(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]));
        let reach = order.iter().map(|&i| (world[i].0 - center).norm() + world[i].1).fold(0.0, f64::max);
        let index = self.nodes.len();
        self.nodes.push(FixedNode {
            center: f3(&center.coords),
            radius: (reach * (1.0 + 1e-6)) as f32 + F32_SLACK,
            start,
            end: start + order.len(),
            right: 0,
        });
        if order.len() > FIXED_LEAF {
            // halve at the median of the centres along the longest side of their box
            let (mut clo, mut chi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &i in order.iter() {
                for k in 0..3 {
                    clo[k] = clo[k].min(world[i].0[k]);
                    chi[k] = chi[k].max(world[i].0[k]);
                }
            }
            let axis = (0..3).max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b]))).unwrap_or(0);
            let mid = order.len() / 2;
            order.select_nth_unstable_by(mid, |&a, &b| world[a].0[axis].total_cmp(&world[b].0[axis]));
            let (left, right) = order.split_at_mut(mid);
            self.build(world, left, start);
            let r = self.build(world, right, start + mid);
            self.nodes[index].right = r;
        }
        index
    }
}

/// An obstacle in the form the kernel tests (world frame, `f32`).
#[derive(Clone, Debug)]
enum Shape {
    Sphere { c: [f32; 3], r: f32 },
    /// `rt`: the rows of the world-to-box rotation; `t`: the centre; `h`: the half extents.
    Box { rt: [[f32; 3]; 3], t: [f32; 3], h: [f32; 3] },
    /// parry's cylinder: its axis along the local y of the pose.
    Cylinder { rt: [[f32; 3]; 3], t: [f32; 3], radius: f32, half_height: f32 },
    /// The segment from `a` to `a + ab` and the radius.
    Capsule { a: [f32; 3], ab: [f32; 3], r: f32 },
    /// {x : n.x <= offset}.
    Plane { n: [f32; 3], offset: f32 },
    /// Any other parry shape (a mesh's hull, triangles or parts): obstacle `index` of the world, in `f64`.
    Other { index: usize },
    /// A point cloud: obstacle `index` of the world, its [`CloudGrid`](super::CloudGrid).
    Cloud { index: usize },
}

#[derive(Clone, Debug)]
struct Compiled {
    shape: Shape,
    /// World box (none for a half-space).
    aabb: Option<([f32; 3], [f32; 3])>,
    /// The clearance the robot keeps from it (its padding, else the world's; m): every sphere
    /// and bounding sphere is grown by it against this obstacle.
    pad: f32,
}

/// [`PREFILTER`] obstacles' world boxes grown by the reach of one link's bounding sphere, as
/// arrays ([`SphereWorld::near_obstacles`]): `lo` and `hi` the corners of obstacle `o`'s box
/// (none: unbounded, as a half-space's) moved out by the link's radius, the obstacle's padding
/// and a margin (relative 1e-4, and 1e-5 m), in `f64` and then rounded outwards to `f32`.
#[derive(Clone, Debug)]
struct BoxChunk {
    lo: [[f32; PREFILTER]; 3],
    hi: [[f32; PREFILTER]; 3],
    /// The obstacles in this chunk (the first `count` entries; the chunk starts at obstacle
    /// `PREFILTER` times its index).
    count: usize,
}

/// Obstacles per [`BoxChunk`]: one AVX register of `f32`.
const PREFILTER: usize = 8;

/// The robot's spheres against the obstacles of a [`CollisionWorld`] (as it was when this was
/// built): see the module text.
#[derive(Clone)]
pub struct SphereWorld {
    /// The world the obstacles, the self pairs and the kinematics come from.
    pub world: Arc<CollisionWorld>,
    spheres: SphereModel,
    /// The spheres in the link frames (`f32`), each moving link's reordered by its groups.
    local: [Vec<f32>; 4],
    links: Vec<LinkSpheres>,
    /// The moving links' groups of spheres ([`LinkSpheres`] `g0..g1`).
    groups: Vec<Group>,
    /// Self pairs as indices into `links`.
    pairs: Vec<(usize, usize)>,
    /// The self pairs of two moving links.
    moving_pairs: Vec<(usize, usize)>,
    /// The self pairs of a moving link and a fixed one: the moving link (index into `links`)
    /// and the fixed one's root node.
    fixed_pairs: Vec<(usize, usize)>,
    fixed: FixedSpheres,
    /// A fixed link meets an obstacle or another fixed link of its self pairs: every
    /// configuration is in collision.
    fixed_hit: bool,
    obstacles: Vec<Compiled>,
    /// Per entry of `links` (its index times the chunks' count, plus the chunk's): the
    /// obstacles' boxes grown by the link's reach, in chunks, the prefilter of its obstacle tests.
    chunks: Vec<BoxChunk>,
    /// The joints that place every link with spheres (the kinematics' order, parents first),
    /// in `f32`.
    joints: Vec<LaneJoint>,
}

/// A joint of the kinematics for the lane kinematics: its origin's rotation (row-major) and
/// translation, and how it moves.
#[derive(Clone, Debug)]
struct LaneJoint {
    parent: usize,
    child: usize,
    rotation: [f32; 9],
    translation: [f32; 3],
    motion: LaneMotion,
}

#[derive(Clone, Debug)]
enum LaneMotion {
    Fixed,
    /// About the unit axis by the angle `multiplier * q[index] + offset`; `continuous`: the
    /// angle of (q[index], q[index + 1]) instead.
    Revolute { axis: [f32; 3], index: usize, multiplier: f64, offset: f64, continuous: bool },
    /// Along the unit axis by `multiplier * q[index] + offset`.
    Prismatic { axis: [f32; 3], index: usize, multiplier: f64, offset: f64 },
}

/// Buffers of a check of `N` configurations at once.
#[derive(Clone, Debug)]
pub struct SphereScratch<const N: usize> {
    /// For a short last block of a batch: its rows one at a time, or four lanes.
    one: Vec<SphereScratch<1>>,
    four: Vec<SphereScratch<4>>,
    /// Per link of the model (up to the last one with spheres): its rotation (row-major, 9)
    /// and translation (3), per lane.
    frames: Vec<[[f32; N]; 12]>,
    /// Per sphere: world centre per lane.
    centers: Vec<[[f32; N]; 3]>,
    /// Per link with spheres: world centre of its bounding sphere per lane.
    bounds: Vec<[[f32; N]; 3]>,
    /// Per link with spheres: are its groups' centres (`gbounds`) placed for these lanes?
    placed: Vec<bool>,
    /// Per group: world centre of its bounding sphere per lane (a link of several groups).
    gbounds: Vec<[[f32; N]; 3]>,
    /// Per group: are its spheres' `centers` placed for these lanes? A group's spheres are
    /// placed only when a test needs them ([`SphereWorld::place_group`]).
    gplaced: Vec<bool>,
    /// Per joint of the kinematics: its values per lane ([`joint_frame`]'s `a`).
    values: Vec<[[f32; N]; 2]>,
    state: Vec<f64>,
    dq: Vec<f64>,
}

impl<const N: usize> Default for SphereScratch<N> {
    fn default() -> Self {
        SphereScratch { one: Vec::new(), four: Vec::new(), frames: Vec::new(), centers: Vec::new(), bounds: Vec::new(), placed: Vec::new(), gbounds: Vec::new(), gplaced: Vec::new(), values: Vec::new(), state: Vec::new(), dq: Vec::new() }
    }
}

fn f3(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The rows of the inverse (transpose) of the pose's rotation, and its translation.
fn inverse_rows(pose: &Isometry3<f64>) -> ([[f32; 3]; 3], [f32; 3]) {
    let m = pose.rotation.to_rotation_matrix().into_inner();
    let rt = [0, 1, 2].map(|i| [m[(0, i)] as f32, m[(1, i)] as f32, m[(2, i)] as f32]);
    (rt, f3(&pose.translation.vector))
}

/// The spheres of an object attached to the robot ([`CollisionWorld::attach`]), covering it:
/// centres in the frame of the link that holds it, and radii (m).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AttachedSpheres {
    /// The attached object's name.
    pub name: String,
    /// Centres in the holding link's frame.
    pub centers: Vec<[f64; 3]>,
    /// Radii (positive).
    pub radii: Vec<f64>,
}

impl SphereWorld {
    /// The spheres against `world`'s obstacles and self pairs, for a world without attached
    /// objects: [`with_attached`](Self::with_attached) with none.
    pub fn new(world: Arc<CollisionWorld>, spheres: SphereModel) -> Result<SphereWorld> {
        Self::with_attached(world, spheres, &[])
    }

    /// The robot's spheres and those of each object attached to it (`objects`: one entry per
    /// attached object of `world`, by name) against `world`'s obstacles and self pairs. An
    /// attached object's spheres move with its link and are checked like a link's: against the
    /// obstacles and against the links of its self pairs (every link but its touch links).
    /// Refused ([`Error::Invalid`]): spheres on a link of another model, an attached object
    /// without spheres, spheres of an object the world does not hold (the known ones listed),
    /// non-finite centres or radii that are not positive.
    pub fn with_attached(world: Arc<CollisionWorld>, mut spheres: SphereModel, objects: &[AttachedSpheres]) -> Result<SphereWorld> {
        let model = &world.model;
        if let Some(&l) = spheres.link.iter().find(|&&l| l >= model.n_links()) {
            return Err(Error::Invalid(format!("spheres: link index {l} out of range (the model has {} links)", model.n_links())));
        }
        let mut links: Vec<LinkSpheres> = Vec::new();
        for i in 0..spheres.len() {
            match links.last_mut() {
                Some(ls) if ls.link == spheres.link[i] => ls.end = i + 1,
                _ => links.push(LinkSpheres { link: spheres.link[i], start: i, end: i + 1, center: [0.0; 3], radius: 0.0, fixed: false, object: None, g0: 0, g1: 0 }),
            }
        }
        if links.windows(2).any(|w| w[0].link >= w[1].link) {
            return Err(Error::Invalid("spheres: not sorted by link (build them with SphereModel::new)".into()));
        }
        // each attached object: its spheres after the robot's, one more entry of `links` on its
        // holding link; `attached_slot`: (its geometry in the world, its entry)
        let held: Vec<&str> = world.attached.iter().map(|a| a.name.as_str()).collect();
        if let Some(o) = objects.iter().find(|o| !held.contains(&o.name.as_str())) {
            return Err(unknown("attached object", &o.name, &held));
        }
        let mut attached_slot: Vec<(usize, usize)> = Vec::new();
        for (ai, a) in world.attached.iter().enumerate() {
            let mut given = objects.iter().filter(|o| o.name == a.name);
            let (Some(o), None) = (given.next(), given.next()) else {
                return Err(Error::Invalid(format!(
                    "spheres: attached object '{}' needs its spheres exactly once (the spheres cover the links alone)", a.name
                )));
            };
            if o.radii.is_empty() {
                return Err(Error::Invalid(format!("spheres: attached object '{}': no spheres", a.name)));
            }
            let link = model.link_names[a.link].as_str();
            let own = SphereModel::new(model, &vec![link; o.radii.len()], &o.centers, &o.radii)
                .map_err(|e| Error::Invalid(format!("attached object '{}': {e}", a.name)))?;
            let start = spheres.len();
            spheres.link.extend(own.link);
            spheres.x.extend(own.x);
            spheres.y.extend(own.y);
            spheres.z.extend(own.z);
            spheres.radius.extend(own.radius);
            attached_slot.push((a.geometry, links.len()));
            links.push(LinkSpheres { link: a.link, start, end: spheres.len(), center: [0.0; 3], radius: 0.0, fixed: false, object: Some(ai), g0: 0, g1: 0 });
        }
        for ls in &mut links {
            // the centre of the spheres' box, the radius reaching the farthest sphere
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for i in ls.start..ls.end {
                for (k, c) in [spheres.x[i], spheres.y[i], spheres.z[i]].into_iter().enumerate() {
                    lo[k] = lo[k].min(c - spheres.radius[i]);
                    hi[k] = hi[k].max(c + spheres.radius[i]);
                }
            }
            let c = Point3::new(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]));
            let r = (ls.start..ls.end)
                .map(|i| (Point3::new(spheres.x[i], spheres.y[i], spheres.z[i]) - c).norm() + spheres.radius[i])
                .fold(0.0, f64::max);
            ls.center = f3(&c.coords);
            ls.radius = (r * (1.0 + 1e-6)) as f32 + F32_SLACK;
        }
        // the link pairs the world checks for self-collision, among the entries with spheres: a
        // geometry's entry is its attached object's, else its link's (the robot's entries come
        // first, so `position` finds the link's own)
        let slot = |g: usize| match attached_slot.iter().find(|&&(geometry, _)| geometry == g) {
            Some(&(_, k)) => Some(k),
            None => links.iter().position(|ls| ls.link == world.geometries[g].link),
        };
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        if world.check_self {
            for &(ga, gb) in &world.self_pairs {
                if let (Some(a), Some(b)) = (slot(ga), slot(gb)) {
                    let p = (a.min(b), a.max(b));
                    if a != b && !pairs.contains(&p) {
                        pairs.push(p);
                    }
                }
            }
        }
        let mut obstacles = Vec::with_capacity(world.obstacles.len());
        for (index, o) in world.obstacles.iter().enumerate() {
            let s = &o.shape;
            let shape = if o.cloud.is_some() {
                Shape::Cloud { index }
            } else if let Some(b) = s.as_ball() {
                Shape::Sphere { c: f3(&o.pose.translation.vector), r: b.radius as f32 }
            } else if let Some(b) = s.as_cuboid() {
                let (rt, t) = inverse_rows(&o.pose);
                Shape::Box { rt, t, h: f3(&b.half_extents) }
            } else if let Some(c) = s.as_cylinder() {
                let (rt, t) = inverse_rows(&o.pose);
                Shape::Cylinder { rt, t, radius: c.radius as f32, half_height: c.half_height as f32 }
            } else if let Some(c) = s.as_capsule() {
                let (a, b) = (o.pose * c.segment.a, o.pose * c.segment.b);
                Shape::Capsule { a: f3(&a.coords), ab: f3(&(b - a)), r: c.radius as f32 }
            } else if let Some((n, offset)) = o.plane {
                Shape::Plane { n: f3(&n), offset: offset as f32 }
            } else {
                Shape::Other { index }
            };
            let aabb = o.aabb.map(|b| (f3(&b.mins.coords), f3(&b.maxs.coords)));
            // rounded up, so that the f32 padding is never below the f64 one
            let pad = world.obstacle_padding(index);
            let pad = (pad * (1.0 + 1e-6)) as f32;
            obstacles.push(Compiled { shape, aabb, pad });
        }
        let mut chunks = Vec::new();
        for ls in &links {
            for c in obstacles.chunks(PREFILTER) {
                let mut ch =
                    BoxChunk { lo: [[f32::NEG_INFINITY; PREFILTER]; 3], hi: [[f32::INFINITY; PREFILTER]; 3], count: c.len() };
                for (o, ob) in c.iter().enumerate() {
                    if let Some((lo, hi)) = &ob.aabb {
                        // beyond the f32 rounding of the reach and of box_near's arithmetic;
                        // moved out by 2^-22 of its size before the rounding to f32 (at most
                        // 2^-24 of it), so that the f32 corner is never inside the f64 one
                        let reach = (f64::from(ls.radius) + f64::from(ob.pad)) * (1.0 + 1e-4) + 1e-5;
                        let out = |x: f64, side: f64| (x + side * x.abs() * 2f64.powi(-22)) as f32;
                        for i in 0..3 {
                            ch.lo[i][o] = out(f64::from(lo[i]) - reach, -1.0);
                            ch.hi[i][o] = out(f64::from(hi[i]) + reach, 1.0);
                        }
                    }
                }
                chunks.push(ch);
            }
        }
        let link_ids: Vec<usize> = links.iter().map(|l| l.link).collect();
        let joints = lane_joints(model, model.joints_placing(&link_ids));
        // the links no joint moves (none on a floating base): their poses at any configuration
        let mut moves = vec![model.floating_base; model.n_links()];
        for j in &model.joints {
            moves[j.child] = moves[j.parent] || !matches!(j.motion, crate::kinematics::Motion::Fixed) || j.mimic.is_some();
        }
        let mut poses = Vec::new();
        model.forward_kinematics_prefix(&vec![0.0; model.nq], &mut poses, joints.len());
        let mut fixed = FixedSpheres::default();
        for (k, ls) in links.iter_mut().enumerate() {
            if !moves[ls.link] {
                ls.fixed = true;
                fixed.root.push((k, fixed.nodes.len()));
                fixed.add_link(&spheres, ls, &poses[ls.link]);
            }
        }
        // each moving link's spheres in spatial groups; `perm`: the checker's order of spheres
        let mut perm: Vec<usize> = (0..spheres.len()).collect();
        let mut groups = Vec::new();
        for ls in links.iter_mut().filter(|ls| !ls.fixed) {
            ls.g0 = groups.len();
            split_groups(&spheres, &mut perm[ls.start..ls.end], ls.start, &mut groups);
            ls.g1 = groups.len();
        }
        let local = [&spheres.x, &spheres.y, &spheres.z, &spheres.radius].map(|v| perm.iter().map(|&i| v[i] as f32).collect());
        let root_of = |k: usize| fixed.root.iter().find(|&&(l, _)| l == k).map(|&(_, r)| r);
        let mut moving_pairs = Vec::new();
        let mut fixed_pairs = Vec::new();
        let mut fixed_fixed = Vec::new();
        for &(a, b) in &pairs {
            match (root_of(a), root_of(b)) {
                (None, None) => moving_pairs.push((a, b)),
                (Some(r), None) => fixed_pairs.push((b, r)),
                (None, Some(r)) => fixed_pairs.push((a, r)),
                (Some(ra), Some(rb)) => fixed_fixed.push((ra, rb)),
            }
        }
        let mut sw = SphereWorld { world, spheres, local, links, groups, pairs, moving_pairs, fixed_pairs, fixed, fixed_hit: false, obstacles, chunks, joints };
        sw.fixed_hit = sw.fixed_collides(&fixed_fixed);
        Ok(sw)
    }

    /// The links fixed to the world (link indices of the model) that have spheres: placed once,
    /// checked against the obstacles when this was built (see the module text).
    pub fn fixed_links(&self) -> Vec<usize> {
        self.links.iter().filter(|ls| ls.fixed).map(|ls| ls.link).collect()
    }

    /// Does a fixed link's sphere meet an obstacle, or a sphere of another fixed link of a self
    /// pair (`fixed_fixed`: the pairs' root nodes)? The same closed-form tests as a
    /// configuration's, one sphere at a time.
    fn fixed_collides(&self, fixed_fixed: &[(usize, usize)]) -> bool {
        let f = &self.fixed;
        for i in 0..f.x.len() {
            let c = [[f.x[i]], [f.y[i]], [f.z[i]]];
            let r = f.radius[i] + F32_SLACK;
            for o in &self.obstacles {
                let r = r + o.pad;
                let near = match &o.aabb {
                    Some((lo, hi)) => box_near(lo, hi, &c, r * r, &[true]),
                    None => [true],
                };
                if near[0] && self.sphere_hits(o, &c, r, &near)[0] {
                    return true;
                }
            }
        }
        fixed_fixed.iter().any(|&(ra, rb)| {
            let (na, nb) = (&f.nodes[ra], &f.nodes[rb]);
            (na.start..na.end).any(|i| {
                (nb.start..nb.end).any(|j| {
                    let d2 = (f.x[i] - f.x[j]).powi(2) + (f.y[i] - f.y[j]).powi(2) + (f.z[i] - f.z[j]).powi(2);
                    let rr = f.radius[i] + f.radius[j] + 2.0 * F32_SLACK;
                    d2 <= rr * rr
                })
            })
        })
    }

    /// The spheres.
    pub fn spheres(&self) -> &SphereModel {
        &self.spheres
    }

    /// The link pairs tested for self-collision, as link indices of the model.
    pub fn self_link_pairs(&self) -> Vec<(usize, usize)> {
        self.pairs.iter().map(|&(a, b)| (self.links[a].link, self.links[b].link)).collect()
    }

    /// The pairs checked for self-collision by name: a link's, or an attached object's for its
    /// spheres.
    pub fn self_pair_names(&self) -> Vec<(String, String)> {
        let name = |k: usize| match self.links[k].object {
            Some(a) => self.world.attached[a].name.clone(),
            None => self.world.model.link_names[self.links[k].link].clone(),
        };
        self.pairs.iter().map(|&(a, b)| (name(a), name(b))).collect()
    }

    /// Is the checked configuration `q` in collision by the spheres (input checked: length,
    /// finite)? Joint limits are not part of the answer.
    pub fn in_collision(&self, q: &[f64]) -> Result<bool> {
        self.world.model.check_configuration(q)?;
        Ok(self.in_collision_unchecked(q, &mut SphereScratch::default()))
    }

    /// [`in_collision`](Self::in_collision) without input checks, reusing buffers.
    pub fn in_collision_unchecked(&self, q: &[f64], s: &mut SphereScratch<1>) -> bool {
        self.place([q], s);
        self.collide(s, [true], true)[0]
    }

    /// For each row of `qs` (checked configurations, n x nq): `out[i]` = in collision by the
    /// spheres. Rows are checked [`LANES`] at a time; a last block of fewer than
    /// [`SHORT_BLOCK`] rows one row at a time, one of at most 4 in four lanes (the lanes cost
    /// the same whether used or not: a planner's edges are often a few states).
    pub fn in_collision_batch(&self, qs: &[f64], out: &mut [bool], s: &mut SphereScratch<LANES>) {
        let nq = self.world.model.nq;
        for (rows, res) in qs.chunks(nq * LANES).zip(out.chunks_mut(LANES)) {
            let n = res.len();
            if n < SHORT_BLOCK {
                if s.one.is_empty() {
                    s.one.push(SphereScratch::default());
                }
                for (q, r) in rows.chunks(nq).zip(res.iter_mut()) {
                    *r = self.in_collision_unchecked(q, &mut s.one[0]);
                }
            } else if n <= 4 {
                if s.four.is_empty() {
                    s.four.push(SphereScratch::default());
                }
                self.block(rows, res, &mut s.four[0]);
            } else {
                self.block(rows, res, s);
            }
        }
    }

    /// Is any row of `qs` (checked configurations, n x nq) in collision by the spheres, and how
    /// many rows were checked to say so? The rows are checked in order, [`LANES`] at a time (a
    /// last block of fewer than [`SHORT_BLOCK`] rows one row at a time, one of at most 4 in
    /// four lanes), and the check stops at the first block with a row in collision, inside that
    /// block at the first lane found in collision (its rows count as checked): a caller that
    /// only needs to know whether all rows are free (an edge, a shortcut) puts the rows most
    /// likely to collide first.
    pub fn any_in_collision(&self, qs: &[f64], s: &mut SphereScratch<LANES>) -> (bool, usize) {
        let nq = self.world.model.nq;
        let mut checked = 0;
        for rows in qs.chunks(nq * LANES) {
            let n = rows.len() / nq;
            let hit = if n < SHORT_BLOCK {
                if s.one.is_empty() {
                    s.one.push(SphereScratch::default());
                }
                rows.chunks(nq).any(|q| self.in_collision_unchecked(q, &mut s.one[0]))
            } else if n <= 4 {
                if s.four.is_empty() {
                    s.four.push(SphereScratch::default());
                }
                self.block_any(rows, &mut s.four[0])
            } else {
                self.block_any(rows, s)
            };
            checked += n;
            if hit {
                return (true, checked);
            }
        }
        (false, checked)
    }

    /// Is any of the rows of `rows` (at most `N`, in `N` lanes as [`block`](Self::block)) in
    /// collision? Stops at the first lane found in collision.
    fn block_any<const N: usize>(&self, rows: &[f64], s: &mut SphereScratch<N>) -> bool {
        let nq = self.world.model.nq;
        let n = rows.len() / nq;
        let lane = |l: usize| &rows[l.min(n - 1) * nq..(l.min(n - 1) + 1) * nq];
        let mut live = [false; N];
        live[..n].fill(true);
        self.place(std::array::from_fn(lane), s);
        self.collide(s, live, true).iter().any(|&h| h)
    }

    /// The rows of `rows` (at most `N`) in `N` lanes, a short block repeating its last row in
    /// the idle lanes (their answers are dropped).
    fn block<const N: usize>(&self, rows: &[f64], res: &mut [bool], s: &mut SphereScratch<N>) {
        let nq = self.world.model.nq;
        let n = res.len();
        let lane = |l: usize| &rows[l.min(n - 1) * nq..(l.min(n - 1) + 1) * nq];
        let mut live = [false; N];
        live[..n].fill(true);
        self.place(std::array::from_fn(lane), s);
        let hit = self.collide(s, live, false);
        res.copy_from_slice(&hit[..n]);
    }

    /// Is every state of the motion from `a` to `b` (`a (+) t (b (-) a)` at t = k / m, k = 0..=m,
    /// the least m that makes consecutive states at most `resolution` apart in every
    /// coordinate of the tangent) free by the spheres? The states are the lanes of one pass,
    /// [`LANES`] at a time, stopping at the first block with a state in collision. `a`, `b`
    /// checked configurations; `resolution` > 0.
    pub fn motion_free(&self, a: &[f64], b: &[f64], resolution: f64, s: &mut SphereScratch<LANES>) -> bool {
        let m: &KinematicModel = &self.world.model;
        let (nq, nv) = (m.nq, m.nv);
        let mut dq = std::mem::take(&mut s.dq);
        dq.resize(nv, 0.0);
        m.difference(a, b, &mut dq);
        let span = dq.iter().fold(0.0f64, |x, d| x.max(d.abs()));
        let steps = ((span / resolution).ceil() as usize).max(1);
        let mut states = std::mem::take(&mut s.state);
        states.resize(LANES * nq, 0.0);
        let mut v = vec![0.0; nv];
        let mut free = true;
        let mut k0 = 0;
        while k0 <= steps && free {
            let n = (steps + 1 - k0).min(LANES);
            for l in 0..LANES {
                let t = (k0 + l.min(n - 1)) as f64 / steps as f64;
                for (vi, di) in v.iter_mut().zip(&dq) {
                    *vi = t * di;
                }
                m.integrate(a, &v, &mut states[l * nq..(l + 1) * nq]);
            }
            let mut live = [false; LANES];
            live[..n].fill(true);
            self.place(std::array::from_fn(|l| &states[l * nq..(l + 1) * nq]), s);
            free = !self.collide(s, live, true).iter().any(|&h| h);
            k0 += n;
        }
        s.dq = dq;
        s.state = states;
        free
    }

    /// Pose the links with spheres for each lane's configuration and place every sphere and
    /// every link's bounding sphere in the world. The kinematics run in `f32` across the lanes
    /// (the joint angles' sines and cosines in `f64`), every joint in one call of the AVX2
    /// kernel ([`place_spheres`](Self::place_spheres)); a floating base is placed by
    /// [`KinematicModel::base_pose`] (`f64`).
    fn place<const N: usize>(&self, qs: [&[f64]; N], s: &mut SphereScratch<N>) {
        let m = &self.world.model;
        let n_links = m.n_links();
        s.frames.resize(n_links, [[0.0; N]; 12]);
        let mut root = [[0.0f32; N]; 12];
        if m.floating_base {
            for l in 0..N {
                let p = KinematicModel::base_pose(qs[l]);
                let r = p.rotation.to_rotation_matrix().into_inner();
                for i in 0..3 {
                    for j in 0..3 {
                        root[3 * i + j][l] = r[(i, j)] as f32;
                    }
                    root[9 + i][l] = p.translation.vector[i] as f32;
                }
            }
        } else {
            for i in 0..3 {
                root[4 * i] = [1.0; N];
            }
        }
        s.frames[m.root] = root;
        // the joints' values per lane: the angle's cosine and sine, or the displacement
        s.values.resize(self.joints.len(), [[0.0; N]; 2]);
        for (j, a) in self.joints.iter().zip(s.values.iter_mut()) {
            match &j.motion {
                LaneMotion::Fixed => {}
                LaneMotion::Revolute { index, multiplier, offset, continuous, .. } => {
                    for l in 0..N {
                        let q = qs[l];
                        let t = if *continuous { q[index + 1].atan2(q[*index]) } else { multiplier * q[*index] + offset };
                        let (sn, cs) = sin_cos_f32(t);
                        a[0][l] = cs;
                        a[1][l] = sn;
                    }
                }
                LaneMotion::Prismatic { index, multiplier, offset, .. } => {
                    for l in 0..N {
                        a[0][l] = (multiplier * qs[l][*index] + offset) as f32;
                    }
                }
            }
        }
        dispatch_place(self, s);
    }

    /// The kernel of [`place`](Self::place) after the joints' values are written: the joints'
    /// frames (parents first), then each moving link's bounding sphere; its spheres wait until a test needs them ([`place_link`](Self::place_link)).
    #[inline(always)]
    fn place_spheres<const N: usize>(&self, s: &mut SphereScratch<N>) {
        for (j, a) in self.joints.iter().zip(&s.values) {
            if j.parent < j.child {
                let (before, after) = s.frames.split_at_mut(j.child);
                after[0] = joint_frame(j, &before[j.parent], a);
            } else {
                let parent = s.frames[j.parent];
                s.frames[j.child] = joint_frame(j, &parent, a);
            }
        }
        s.centers.resize(self.spheres.len(), [[0.0; N]; 3]);
        s.bounds.resize(self.links.len(), [[0.0; N]; 3]);
        s.placed.clear();
        s.placed.resize(self.links.len(), false);
        s.gbounds.resize(self.groups.len(), [[0.0; N]; 3]);
        s.gplaced.clear();
        s.gplaced.resize(self.groups.len(), false);
        for (k, ls) in self.links.iter().enumerate().filter(|(_, ls)| !ls.fixed) {
            put(&s.frames[ls.link], ls.center, &mut s.bounds[k]);
        }
    }

    /// Places the spheres of the moving link `k` (index into `links`) for the lanes of the last
    /// [`place`](Self::place), unless they are already: a link whose bounding sphere meets no
    /// obstacle and no link of its self pairs never needs them.
    #[inline(always)]
    fn place_link<const N: usize>(&self, s: &mut SphereScratch<N>, k: usize) {
        let ls = &self.links[k];
        for g in ls.g0..ls.g1 {
            self.place_group(s, ls.link, g);
        }
    }

    /// Places the centres of the groups of the moving link `k` (index into `links`), unless
    /// they are already or the link is one group (whose test would repeat the link's).
    #[inline(always)]
    fn place_groups<const N: usize>(&self, s: &mut SphereScratch<N>, k: usize) {
        let ls = &self.links[k];
        if s.placed[k] || ls.g1 - ls.g0 < 2 {
            return;
        }
        s.placed[k] = true;
        let f = &s.frames[ls.link];
        for g in ls.g0..ls.g1 {
            put(f, self.groups[g].center, &mut s.gbounds[g]);
        }
    }

    /// Places the spheres of group `g` of a moving link (`link`: its index in the model),
    /// unless they are already.
    #[inline(always)]
    fn place_group<const N: usize>(&self, s: &mut SphereScratch<N>, link: usize, g: usize) {
        if s.gplaced[g] {
            return;
        }
        s.gplaced[g] = true;
        let gr = &self.groups[g];
        let [x, y, z, _] = &self.local;
        let f = &s.frames[link];
        for i in gr.start..gr.end {
            put(f, [x[i], y[i], z[i]], &mut s.centers[i]);
        }
    }

    /// Which lanes are in collision (`live` lanes only). `any`: stop at the first lane in
    /// collision (else when every live lane is).
    fn collide<const N: usize>(&self, s: &mut SphereScratch<N>, live: [bool; N], any: bool) -> [bool; N] {
        dispatch_collide(self, s, live, any)
    }

    #[inline(always)]
    fn collide_kernel<const N: usize>(&self, s: &mut SphereScratch<N>, live: [bool; N], any: bool) -> [bool; N] {
        if self.fixed_hit {
            return live;
        }
        let mut hit = [false; N];
        let done = |hit: &[bool; N]| if any { hit.iter().any(|&h| h) } else { (0..N).all(|l| hit[l] || !live[l]) };
        let radius = &self.local[3];
        // the lane masks combine with `&` and `|` (no short circuit), so that each lane loop
        // stays one vector instruction per operation
        for (k, ls) in self.links.iter().enumerate().filter(|(_, ls)| !ls.fixed) {
            let bc = s.bounds[k];
            let bc = &bc;
            // lanes still to decide: live and not yet in collision
            let mut open: [bool; N] = std::array::from_fn(|l| live[l] & !hit[l]);
            // the box of the bounding sphere's centres over the lanes
            let mut lane_box = [[f32::INFINITY; 3], [f32::NEG_INFINITY; 3]];
            for i in 0..3 {
                lane_box[0][i] = bc[i].iter().fold(f32::INFINITY, |a, &c| a.min(c));
                lane_box[1][i] = bc[i].iter().fold(f32::NEG_INFINITY, |a, &c| a.max(c));
            }
            // f32::min and max skip a NaN: a lane placed at NaN (never from checked input) meets
            // every obstacle's box, as box_near then finds
            if bc.iter().flatten().any(|c| c.is_nan()) {
                lane_box = [[f32::NEG_INFINITY; 3], [f32::INFINITY; 3]];
            }
            let per_link = self.obstacles.len().div_ceil(PREFILTER);
            for (ci, chunk) in self.chunks[k * per_link..(k + 1) * per_link].iter().enumerate() {
                let mut todo = near_obstacles(chunk, &lane_box);
                while todo != 0 {
                    let o = &self.obstacles[ci * PREFILTER + todo.trailing_zeros() as usize];
                    todo &= todo - 1;
                    // lanes where the link's bounding sphere (grown by the obstacle's padding)
                    // meets the obstacle's box (or plane)
                    let reach = ls.radius + o.pad;
                    let mut near = match &o.aabb {
                        Some((lo, hi)) => box_near(lo, hi, bc, reach * reach, &open),
                        None => open,
                    };
                    if let Shape::Cloud { index } = &o.shape {
                        near = self.cloud_near(*index, bc, reach, near);
                    }
                    if !near.iter().fold(false, |a, &n| a | n) {
                        continue;
                    }
                    self.place_groups(s, k);
                    let several = ls.g1 - ls.g0 > 1;
                    for g in ls.g0..ls.g1 {
                        let gr = &self.groups[g];
                        // a group of a link of several: its bounding sphere first (it holds its
                        // spheres with a slack to spare: a pure prune)
                        let gnear = if several {
                            let h = self.sphere_hits(o, &s.gbounds[g], gr.radius + o.pad, &near);
                            let m: [bool; N] = std::array::from_fn(|l| h[l] & near[l]);
                            if !m.iter().fold(false, |a, &n| a | n) {
                                continue;
                            }
                            m
                        } else {
                            near
                        };
                        self.place_group(s, ls.link, g);
                        for i in gr.start..gr.end {
                            let h = self.sphere_hits(o, &s.centers[i], radius[i] + F32_SLACK + o.pad, &gnear);
                            for l in 0..N {
                                hit[l] |= h[l] & gnear[l];
                            }
                        }
                    }
                    if done(&hit) {
                        return hit;
                    }
                    for l in 0..N {
                        open[l] &= !hit[l];
                    }
                }
            }
        }
        for &(k, root) in &self.fixed_pairs {
            let open: [bool; N] = std::array::from_fn(|l| live[l] & !hit[l]);
            if !open.iter().fold(false, |a, &n| a | n) {
                break;
            }
            self.against_fixed(s, k, root, open, &mut hit);
            if done(&hit) {
                return hit;
            }
        }
        for &(a, b) in &self.moving_pairs {
            let (la, lb) = (&self.links[a], &self.links[b]);
            let (ca, cb) = (&s.bounds[a], &s.bounds[b]);
            let reach = la.radius + lb.radius;
            let mut d2 = [0.0f32; N];
            for i in 0..3 {
                let (pa, pb) = (&ca[i], &cb[i]);
                for l in 0..N {
                    let e = pa[l] - pb[l];
                    d2[l] += e * e;
                }
            }
            let near: [bool; N] = std::array::from_fn(|l| live[l] & !hit[l] & (d2[l] <= reach * reach));
            if !near.iter().fold(false, |a, &n| a | n) {
                continue;
            }
            self.place_link(s, a);
            self.place_link(s, b);
            let cb = s.bounds[b];
            for i in la.start..la.end {
                let p = &s.centers[i];
                // the lanes where sphere i reaches b's bounding sphere (with a second slack: the
                // bounding sphere's centre and the spheres' are rounded to f32 separately): a
                // prune no tighter than the pair test it spares
                let rb = radius[i] + 2.0 * F32_SLACK + lb.radius;
                let mut e2 = [0.0f32; N];
                for c in 0..3 {
                    for l in 0..N {
                        let e = p[c][l] - cb[c][l];
                        e2[l] += e * e;
                    }
                }
                let close: [bool; N] = std::array::from_fn(|l| near[l] & (e2[l] <= rb * rb));
                if !close.iter().fold(false, |a, &n| a | n) {
                    continue;
                }
                for j in lb.start..lb.end {
                    let q = &s.centers[j];
                    let rr = radius[i] + radius[j] + 2.0 * F32_SLACK;
                    for l in 0..N {
                        let d2 = (p[0][l] - q[0][l]) * (p[0][l] - q[0][l])
                            + (p[1][l] - q[1][l]) * (p[1][l] - q[1][l])
                            + (p[2][l] - q[2][l]) * (p[2][l] - q[2][l]);
                        hit[l] |= close[l] & (d2 <= rr * rr);
                    }
                }
            }
            if done(&hit) {
                return hit;
            }
        }
        hit
    }

    /// Sets `hit` in the lanes of `open` where a sphere of the moving link `k` (index into
    /// `links`) meets a sphere of the fixed link whose tree starts at node `root`: the nodes
    /// whose bounding sphere meets the link's, then per leaf each of the link's spheres against
    /// the leaf's bounding sphere and, where it reaches it, the leaf's spheres.
    #[inline(always)]
    fn against_fixed<const N: usize>(&self, s: &mut SphereScratch<N>, k: usize, root: usize, open: [bool; N], hit: &mut [bool; N]) {
        let ls = &self.links[k];
        let f = &self.fixed;
        let bc = s.bounds[k];
        let bc = &bc;
        let radius = &self.local[3];
        let within = |c: &[[f32; N]; 3], p: [f32; 3], reach: f32, mask: &[bool; N]| -> [bool; N] {
            let mut d2 = [0.0f32; N];
            for i in 0..3 {
                for l in 0..N {
                    let e = c[i][l] - p[i];
                    d2[l] += e * e;
                }
            }
            std::array::from_fn(|l| mask[l] & (d2[l] <= reach * reach))
        };
        // most calls end at the root: tested before the stack is set up
        let mask: [bool; N] = std::array::from_fn(|l| open[l] & !hit[l]);
        let rn = &f.nodes[root];
        if !within(bc, rn.center, ls.radius + rn.radius, &mask).iter().fold(false, |a, &n| a | n) {
            return;
        }
        let mut stack = [0usize; 64];
        stack[0] = root;
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let ni = stack[top];
            let node = &f.nodes[ni];
            let mask: [bool; N] = std::array::from_fn(|l| open[l] & !hit[l]);
            let near = within(bc, node.center, ls.radius + node.radius, &mask);
            if !near.iter().fold(false, |a, &n| a | n) {
                continue;
            }
            if node.end - node.start > FIXED_LEAF {
                // children: the next node and `right`; the tree is halved at the median, so the
                // stack holds at most one node per level (its depth is log2 of the spheres)
                stack[top] = node.right;
                stack[top + 1] = ni + 1;
                top += 2;
                continue;
            }
            self.place_link(s, k);
            for i in ls.start..ls.end {
                let c = &s.centers[i];
                // the sphere's own slack too, as in the pair test below: a prune may not be
                // tighter than the test it spares
                let reach = within(c, node.center, radius[i] + F32_SLACK + node.radius, &near);
                if !reach.iter().fold(false, |a, &n| a | n) {
                    continue;
                }
                for j in node.start..node.end {
                    let rr = radius[i] + f.radius[j] + 2.0 * F32_SLACK;
                    let h = within(c, [f.x[j], f.y[j], f.z[j]], rr, &reach);
                    for l in 0..N {
                        hit[l] |= h[l];
                    }
                }
            }
        }
    }

    /// Does the sphere (world centre per lane `c`, radius `r`) meet obstacle `o`, per lane?
    /// The lanes of `near` where the link's bounding sphere (centres `bc`, radius `r`) is not
    /// cleared by cloud obstacle `index`'s clearance field ([`CloudGrid::clearance`](super::CloudGrid::clearance):
    /// one lookup per lane instead of one per sphere of the link). The radius gets a second
    /// [`F32_SLACK`]: the link's centre and its spheres' are rounded to `f32` separately.
    #[inline(always)]
    fn cloud_near<const N: usize>(&self, index: usize, bc: &[[f32; N]; 3], r: f32, near: [bool; N]) -> [bool; N] {
        let Some(grid) = self.world.obstacles[index].shape.as_shape::<super::CloudGrid>() else { return near };
        let reach = f64::from(r + F32_SLACK) + grid.radius();
        std::array::from_fn(|l| near[l] && grid.clearance(&Point3::new(f64::from(bc[0][l]), f64::from(bc[1][l]), f64::from(bc[2][l]))) <= reach)
    }

    #[inline(always)]
    fn sphere_hits<const N: usize>(&self, o: &Compiled, c: &[[f32; N]; 3], r: f32, near: &[bool; N]) -> [bool; N] {
        let mut out = [false; N];
        match &o.shape {
            Shape::Sphere { c: oc, r: or } => {
                let rr = r + or;
                for l in 0..N {
                    let d2 = (c[0][l] - oc[0]).powi(2) + (c[1][l] - oc[1]).powi(2) + (c[2][l] - oc[2]).powi(2);
                    out[l] = d2 <= rr * rr;
                }
            }
            Shape::Box { rt, t, h } => {
                for l in 0..N {
                    let d = [c[0][l] - t[0], c[1][l] - t[1], c[2][l] - t[2]];
                    let mut d2 = 0.0;
                    for i in 0..3 {
                        let p = rt[i][0] * d[0] + rt[i][1] * d[1] + rt[i][2] * d[2];
                        let e = (p.abs() - h[i]).max(0.0);
                        d2 += e * e;
                    }
                    out[l] = d2 <= r * r;
                }
            }
            Shape::Cylinder { rt, t, radius, half_height } => {
                for l in 0..N {
                    let d = [c[0][l] - t[0], c[1][l] - t[1], c[2][l] - t[2]];
                    let p: [f32; 3] = std::array::from_fn(|i| rt[i][0] * d[0] + rt[i][1] * d[1] + rt[i][2] * d[2]);
                    let radial = (p[0] * p[0] + p[2] * p[2]).sqrt();
                    let er = (radial - radius).max(0.0);
                    let ey = (p[1].abs() - half_height).max(0.0);
                    out[l] = er * er + ey * ey <= r * r;
                }
            }
            Shape::Capsule { a, ab, r: cr } => {
                let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
                let inv = if len2 > 0.0 { 1.0 / len2 } else { 0.0 };
                let rr = r + cr;
                for l in 0..N {
                    let d = [c[0][l] - a[0], c[1][l] - a[1], c[2][l] - a[2]];
                    let t = ((d[0] * ab[0] + d[1] * ab[1] + d[2] * ab[2]) * inv).clamp(0.0, 1.0);
                    let e = [d[0] - t * ab[0], d[1] - t * ab[1], d[2] - t * ab[2]];
                    out[l] = e[0] * e[0] + e[1] * e[1] + e[2] * e[2] <= rr * rr;
                }
            }
            Shape::Plane { n, offset } => {
                for l in 0..N {
                    out[l] = n[0] * c[0][l] + n[1] * c[1][l] + n[2] * c[2][l] - offset <= r;
                }
            }
            Shape::Other { index } => {
                let ob = &self.world.obstacles[*index];
                let ball = Ball::new(r as f64 + 1e-9);
                for l in 0..N {
                    if near[l] {
                        let at = Isometry3::translation(c[0][l] as f64, c[1][l] as f64, c[2][l] as f64);
                        out[l] = super::geometry::intersects(&at, &ball, &ob.pose, &*ob.shape);
                    }
                }
            }
            Shape::Cloud { index } => match self.world.obstacles[*index].shape.as_shape::<super::CloudGrid>() {
                Some(grid) => {
                    for l in 0..N {
                        if near[l] {
                            out[l] = grid.any_within(&Point3::new(c[0][l] as f64, c[1][l] as f64, c[2][l] as f64), r as f64);
                        }
                    }
                }
                // a cloud is always a grid; anything else counts as touched (the safe side)
                None => out = *near,
            },
        }
        out
    }
}

/// The point `p` (link frame) in the world per lane, for the link's frames `f` (rotation
/// row-major, 9, and translation, 3, per lane).
#[inline(always)]
fn put<const N: usize>(f: &[[f32; N]; 12], p: [f32; 3], out: &mut [[f32; N]; 3]) {
    for i in 0..3 {
        for l in 0..N {
            out[i][l] = f[3 * i][l] * p[0] + f[3 * i + 1][l] * p[1] + f[3 * i + 2][l] * p[2] + f[9 + i][l];
        }
    }
}

/// The sine and cosine of the angle `t` (rad) in `f32`, within 2e-7 of the exact values (the
/// `f32` rounding of the link poses that [`F32_SLACK`] covers is of that order), without a call
/// to the `f64` library function: `t` reduced to |r| <= pi/4 by the nearest multiple of pi/2 (in
/// `f64`), then the Taylor series of degree 9 (sine) and 8 (cosine) in `f32` (their truncation
/// error below 3e-8 there), the quadrant selecting and signing them. Angles beyond 1e6 rad take
/// the library function.
#[inline(always)]
fn sin_cos_f32(t: f64) -> (f32, f32) {
    if !(t.abs() <= 1e6) {
        let (sn, cs) = t.sin_cos();
        return (sn as f32, cs as f32);
    }
    let x = t * std::f64::consts::FRAC_2_PI;
    let k = (x + 0.5f64.copysign(x)) as i64;
    let r = (t - k as f64 * std::f64::consts::FRAC_PI_2) as f32;
    let r2 = r * r;
    let sn = r + r * r2 * (-1.0 / 6.0 + r2 * (1.0 / 120.0 + r2 * (-1.0 / 5040.0 + r2 * (1.0 / 362_880.0))));
    let cs = 1.0 + r2 * (-0.5 + r2 * (1.0 / 24.0 + r2 * (-1.0 / 720.0 + r2 * (1.0 / 40_320.0))));
    // t = r + k pi/2: the quadrant k mod 4 rotates (sin r, cos r)
    let (s, c) = if k & 1 == 0 { (sn, cs) } else { (cs, -sn) };
    if k & 2 == 0 {
        (s, c)
    } else {
        (-s, -c)
    }
}

/// The lanes of `open` where a sphere of squared radius `r2` centred at `c` (per lane) meets the
/// box `lo`..`hi`: the squared distance from the centre to the box against `r2`.
#[inline(always)]
fn box_near<const N: usize>(lo: &[f32; 3], hi: &[f32; 3], c: &[[f32; N]; 3], r2: f32, open: &[bool; N]) -> [bool; N] {
    let mut d2 = [0.0f32; N];
    for i in 0..3 {
        let (a, b, ci) = (lo[i], hi[i], &c[i]);
        for l in 0..N {
            let e = (a - ci[l]).max(0.0) + (ci[l] - b).max(0.0);
            d2[l] += e * e;
        }
    }
    std::array::from_fn(|l| open[l] & (d2[l] <= r2))
}

/// The obstacles of `chunk` (bit `o` for its obstacle `o`) that the link's bounding sphere
/// may meet with its centre anywhere in the box `lane_box` (low and high corners): those whose
/// grown box ([`BoxChunk`]) meets `lane_box`. A pure prune of [`box_near`]'s test, which runs
/// after it: the margin exceeds the `f32` rounding of both tests (relative 6e-8 per operation,
/// below 1 um within 10 m of the origin), so that an obstacle left out is one [`box_near`]
/// finds beyond the reach of every lane's sphere.
#[inline(always)]
fn near_obstacles(chunk: &BoxChunk, lane_box: &[[f32; 3]; 2]) -> u32 {
    let [lo, hi] = lane_box;
    // the largest gap along an axis between the two boxes (the sign of a difference of floats
    // is exact), a NaN never taken
    #[cfg(target_arch = "x86_64")]
    let bits = {
        use std::arch::x86_64::{_mm_cmple_ps, _mm_loadu_ps, _mm_max_ps, _mm_movemask_ps, _mm_set1_ps, _mm_setzero_ps, _mm_sub_ps};
        let mut bits = 0u32;
        for h in 0..PREFILTER / 4 {
            // SAFETY: SSE is part of the x86-64 baseline; the loads read 4 of the 8 entries of
            // each array, at 0 or 4
            unsafe {
                let mut gap = _mm_set1_ps(f32::NEG_INFINITY);
                for i in 0..3 {
                    let below = _mm_sub_ps(_mm_loadu_ps(chunk.lo[i].as_ptr().add(4 * h)), _mm_set1_ps(hi[i]));
                    let above = _mm_sub_ps(_mm_set1_ps(lo[i]), _mm_loadu_ps(chunk.hi[i].as_ptr().add(4 * h)));
                    // maxps gives its second operand where either is NaN
                    gap = _mm_max_ps(_mm_max_ps(below, above), gap);
                }
                bits |= (_mm_movemask_ps(_mm_cmple_ps(gap, _mm_setzero_ps())) as u32) << (4 * h);
            }
        }
        bits
    };
    #[cfg(not(target_arch = "x86_64"))]
    let bits = {
        let mut gap = [f32::NEG_INFINITY; PREFILTER];
        for i in 0..3 {
            for (o, g) in gap.iter_mut().enumerate() {
                let (below, above) = (chunk.lo[i][o] - hi[i], lo[i] - chunk.hi[i][o]);
                let m = if below > above { below } else { above };
                *g = if m > *g { m } else { *g };
            }
        }
        let mut bits = 0u32;
        for (o, &g) in gap.iter().enumerate() {
            bits |= u32::from(g <= 0.0) << o;
        }
        bits
    };
    bits & ((1u32 << chunk.count) - 1)
}

/// The joints of `model` that [`KinematicModel::forward_kinematics_prefix`] would run (the first
/// `count`), in `f32` for the lanes.
fn lane_joints(model: &KinematicModel, count: usize) -> Vec<LaneJoint> {
    use crate::kinematics::Motion;
    let f = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
    model.joints[..count.min(model.joints.len())]
        .iter()
        .map(|j| {
            let r = j.origin.rotation.to_rotation_matrix().into_inner();
            let (index, multiplier, offset) = match j.mimic {
                None => (j.q_index, 1.0, 0.0),
                Some(m) => (m.q_index, m.multiplier, m.offset),
            };
            let motion = match &j.motion {
                Motion::Fixed => LaneMotion::Fixed,
                Motion::Revolute { axis } => LaneMotion::Revolute { axis: f(axis), index, multiplier, offset, continuous: false },
                Motion::Continuous { axis } => {
                    LaneMotion::Revolute { axis: f(axis), index: j.q_index, multiplier: 1.0, offset: 0.0, continuous: true }
                }
                Motion::Prismatic { axis } => LaneMotion::Prismatic { axis: f(axis), index, multiplier, offset },
            };
            LaneJoint {
                parent: j.parent,
                child: j.child,
                rotation: std::array::from_fn(|k| r[(k / 3, k % 3)] as f32),
                translation: f(&j.origin.translation.vector),
                motion,
            }
        })
        .collect()
}

/// The child frame of joint `j` per lane from its parent's `p` (rotation row-major, then
/// translation) and its values `a` (cosine and sine of the angle, or the displacement in `a[0]`):
/// parent * origin * motion.
#[inline(always)]
fn joint_frame<const N: usize>(j: &LaneJoint, p: &[[f32; N]; 12], a: &[[f32; N]; 2]) -> [[f32; N]; 12] {
    let (o, t0) = (&j.rotation, &j.translation);
    let mut c = [[0.0f32; N]; 12];
    // placed = parent * origin
    for i in 0..3 {
        for k in 0..3 {
            for l in 0..N {
                c[3 * i + k][l] = p[3 * i][l] * o[k] + p[3 * i + 1][l] * o[3 + k] + p[3 * i + 2][l] * o[6 + k];
            }
        }
        for l in 0..N {
            c[9 + i][l] = p[3 * i][l] * t0[0] + p[3 * i + 1][l] * t0[1] + p[3 * i + 2][l] * t0[2] + p[9 + i][l];
        }
    }
    match &j.motion {
        LaneMotion::Fixed => c,
        LaneMotion::Revolute { axis: u, .. } => {
            // R(u, t) = cos I + sin [u]x + (1 - cos) u u^T, per lane; the child's rotation c * R
            let mut out = c;
            for l in 0..N {
                let (cs, sn) = (a[0][l], a[1][l]);
                let v = 1.0 - cs;
                let rm = [
                    cs + v * u[0] * u[0], v * u[0] * u[1] - sn * u[2], v * u[0] * u[2] + sn * u[1],
                    v * u[1] * u[0] + sn * u[2], cs + v * u[1] * u[1], v * u[1] * u[2] - sn * u[0],
                    v * u[2] * u[0] - sn * u[1], v * u[2] * u[1] + sn * u[0], cs + v * u[2] * u[2],
                ];
                for i in 0..3 {
                    for k in 0..3 {
                        out[3 * i + k][l] = c[3 * i][l] * rm[k] + c[3 * i + 1][l] * rm[3 + k] + c[3 * i + 2][l] * rm[6 + k];
                    }
                }
            }
            out
        }
        LaneMotion::Prismatic { axis: u, .. } => {
            let mut out = c;
            for i in 0..3 {
                for l in 0..N {
                    let d = a[0][l];
                    out[9 + i][l] += d * (c[3 * i][l] * u[0] + c[3 * i + 1][l] * u[1] + c[3 * i + 2][l] * u[2]);
                }
            }
            out
        }
    }
}

/// [`SphereWorld::place_spheres`], compiled with AVX2 and FMA where the processor has them.
fn dispatch_place<const N: usize>(w: &SphereWorld, s: &mut SphereScratch<N>) {
    #[cfg(target_arch = "x86_64")]
    {
        if avx2() {
            #[target_feature(enable = "avx2,fma")]
            fn place_avx2<const N: usize>(w: &SphereWorld, s: &mut SphereScratch<N>) {
                w.place_spheres(s)
            }
            // SAFETY: the processor has AVX2 and FMA (checked at run time just above)
            return unsafe { place_avx2(w, s) };
        }
    }
    w.place_spheres(s)
}

/// [`SphereWorld::collide_kernel`], compiled with AVX2 and FMA where the processor has them.
fn dispatch_collide<const N: usize>(w: &SphereWorld, s: &mut SphereScratch<N>, live: [bool; N], any: bool) -> [bool; N] {
    #[cfg(target_arch = "x86_64")]
    {
        if avx2() {
            #[target_feature(enable = "avx2,fma")]
            fn collide_avx2<const N: usize>(w: &SphereWorld, s: &mut SphereScratch<N>, live: [bool; N], any: bool) -> [bool; N] {
                w.collide_kernel(s, live, any)
            }
            // SAFETY: the processor has AVX2 and FMA (checked at run time just above)
            return unsafe { collide_avx2(w, s, live, any) };
        }
    }
    w.collide_kernel(s, live, any)
}

#[cfg(target_arch = "x86_64")]
use crate::cpu::avx2_fma as avx2;

#[cfg(test)]
mod tests {
    use super::sin_cos_f32;

    #[test]
    fn f32_sine_and_cosine_are_within_2e_7_of_the_exact_ones() {
        let quarter = std::f64::consts::FRAC_PI_4;
        // a fine grid over +-20 rad, the quadrants' edges and their neighbours, huge angles
        let grid = (-200_000..=200_000).map(|i| i as f64 * 1e-4);
        let edges = (-40..=40).flat_map(|k| [-1e-12, 0.0, 1e-12].map(|e| k as f64 * quarter + e));
        for t in grid.chain(edges).chain([1e6, -1e6, 3.5e7, -2.0e9]) {
            let (s, c) = sin_cos_f32(t);
            let (es, ec) = t.sin_cos();
            assert!((s as f64 - es).abs() < 2e-7 && (c as f64 - ec).abs() < 2e-7, "t {t}: {s} {c} vs {es} {ec}");
        }
    }
}

//! Forward kinematics of a URDF tree, with an optional free-flyer base and locked joints.
//!
//! The configuration vector follows Pinocchio's convention, so the same `q` can be handed to
//! Pinocchio and to genplan: a free-flyer base takes 7 values `[x, y, z, qx, qy, qz, qw]`,
//! a revolute or prismatic joint one value, a continuous joint two (`cos`, `sin`).
//!
//! A joint with a URDF `<mimic>` follows its master as Pinocchio's mimic joints do (Pinocchio
//! 3.4 and later, `buildModelFromUrdf(..., mimic=True)`): it has no value in q; its value is
//! `multiplier * q_master + offset` and its velocity `multiplier * v_master` ([`Follows`]).
//! Only a revolute or prismatic joint following an earlier revolute or prismatic joint that
//! is not itself a mimic can be followed (what Pinocchio supports); other mimics are refused
//! by name. Locking a master locks its mimics at the values they follow; locking a mimic whose
//! master moves is refused.

use std::collections::HashMap;

use nalgebra::{DMatrix, Isometry3, Matrix3, Matrix6, Translation3, Unit, UnitQuaternion, Vector3, Vector6};

use crate::error::{check_finite, check_vector, unknown, Error, Result};
use crate::lie::{action, exp6, jlog6, log6, skew, stable_norm, unit_quaternion, unit_vector};
use crate::urdf::{self, JointType, Urdf, MAX_JOINT_POSITION, MIN_AXIS_NORM};

/// How a joint moves its child link, after its fixed origin transform.
#[derive(Debug, Clone)]
pub enum Motion {
    /// Rigid (a fixed joint or a locked one, with its locked transform).
    Fixed,
    /// Rotation about `axis` (one value in q).
    Revolute {
        /// Unit axis in the joint frame.
        axis: Unit<Vector3<f64>>,
    },
    /// Unbounded rotation about `axis` (two values in q: cos, sin).
    Continuous {
        /// Unit axis in the joint frame.
        axis: Unit<Vector3<f64>>,
    },
    /// Translation along `axis` (one value in q).
    Prismatic {
        /// Unit axis in the joint frame.
        axis: Unit<Vector3<f64>>,
    },
}

/// How a mimic joint follows its master (URDF `<mimic>`): its value is
/// `multiplier * q[q_index] + offset`, its velocity `multiplier * v[v_index]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Follows {
    /// The master (index into [`KinematicModel::joints`]; it comes before the mimic).
    pub joint: usize,
    /// The master's index in q.
    pub q_index: usize,
    /// The master's index in v.
    pub v_index: usize,
    /// Scale of the master's value.
    pub multiplier: f64,
    /// Added to the scaled value.
    pub offset: f64,
}

/// One edge of the tree: parent link -> child link.
#[derive(Debug, Clone)]
pub struct Joint {
    /// The URDF joint's name.
    pub name: String,
    /// Index of the parent link.
    pub parent: usize,
    /// Index of the child link.
    pub child: usize,
    /// Fixed placement of the joint frame in the parent link (a locked joint folds its
    /// locked motion in here).
    pub origin: Isometry3<f64>,
    /// How it moves.
    pub motion: Motion,
    /// First index of this joint in `q` (only for active joints; `usize::MAX` otherwise, a
    /// mimic joint included).
    pub q_index: usize,
    /// Index of this joint in the tangent space `v` (only for active joints, like `q_index`).
    pub v_index: usize,
    /// For a mimic joint (a revolute or prismatic [`motion`](Self::motion) without a
    /// coordinate of its own): the master it follows.
    pub mimic: Option<Follows>,
}

impl Joint {
    /// The coordinate that moves this revolute or prismatic joint, as `(q index, v index,
    /// multiplier, offset)`: its own `(q_index, v_index, 1, 0)`, or its master's for a mimic
    /// joint; None for a rigid joint and for a continuous one (whose q holds cos and sin).
    #[inline]
    pub fn driver(&self) -> Option<(usize, usize, f64, f64)> {
        match (&self.motion, self.mimic) {
            (Motion::Revolute { .. } | Motion::Prismatic { .. }, Some(f)) => Some((f.q_index, f.v_index, f.multiplier, f.offset)),
            (Motion::Revolute { .. } | Motion::Prismatic { .. }, None) => Some((self.q_index, self.v_index, 1.0, 0.0)),
            _ => None,
        }
    }

    /// The column index in v and the scale of this joint's velocity: `(v_index, 1)` for an
    /// active joint, the master's `(v_index, multiplier)` for a mimic joint; None for a rigid
    /// joint. What Jacobians add this joint's motion to.
    #[inline]
    pub fn velocity_column(&self) -> Option<(usize, f64)> {
        match (&self.motion, self.mimic) {
            (Motion::Fixed, _) => None,
            (_, Some(f)) => Some((f.v_index, f.multiplier)),
            (_, None) => Some((self.v_index, 1.0)),
        }
    }
}

/// Why `value` cannot be the locked value of the URDF joint `joint`: beyond
/// [`MAX_JOINT_POSITION`] in magnitude, or (a revolute or prismatic joint) outside its limits
/// (which are inclusive: a joint may be locked at a limit). None when it can.
pub fn locked_value_problem(joint: &urdf::Joint, value: f64) -> Option<String> {
    if !value.is_finite() {
        return Some(format!("{value} is not finite"));
    }
    if value.abs() > MAX_JOINT_POSITION {
        return Some(format!("{value:e} is too large (at most {MAX_JOINT_POSITION:e} in magnitude)"));
    }
    let bounded = matches!(joint.joint_type, JointType::Revolute | JointType::Prismatic);
    (bounded && !(joint.lower <= value && value <= joint.upper))
        .then(|| format!("{value} is outside its limits [{}, {}]", joint.lower, joint.upper))
}

/// Options that select which joints move and where the base is.
#[derive(Debug, Clone, Default)]
pub struct ModelOptions {
    /// Add a free-flyer joint (7 values in q) above the root link.
    pub floating_base: bool,
    /// Movable joints that are held at a value (default 0) and leave q.
    pub locked_joints: HashMap<String, f64>,
    /// The order of the active joints in q. `None`: depth-first order of the URDF tree, children
    /// in joint-name order (what Pinocchio's URDF parser does). When given it must name every movable
    /// joint that is not locked, once.
    pub joint_order: Option<Vec<String>>,
}

/// A kinematic tree: links in topological order (parent before child).
#[derive(Debug, Clone)]
pub struct KinematicModel {
    /// Link names, indexed like every per-link vector.
    pub link_names: Vec<String>,
    /// `joints[i]` moves link `joints[i].child`; ordered so that parents come first.
    pub joints: Vec<Joint>,
    /// Index of the root link.
    pub root: usize,
    /// A free-flyer joint sits above the root (q starts with [x, y, z, qx, qy, qz, qw]).
    pub floating_base: bool,
    /// Names of the active joints, in q order (without the free-flyer).
    pub active_joints: Vec<String>,
    /// Length of q.
    pub nq: usize,
    /// Dimension of the tangent space (velocities).
    pub nv: usize,
    /// Lower joint limit per q element (infinite where none; the free-flyer has none).
    pub lower: Vec<f64>,
    /// Upper joint limit per q element, like `lower`.
    pub upper: Vec<f64>,
    /// For each link: the index of the link whose pose moves it rigidly (its "body"): the
    /// child link of the nearest active joint above it, or the root.
    pub body_of_link: Vec<usize>,
    /// Parent link of each link (None for the root).
    pub parent_link: Vec<Option<usize>>,
    /// For each link: the active joints (indices into `joints`) between the root and it.
    pub active_ancestors: Vec<Vec<usize>>,
    /// Mass and centre of mass (link frame) of each link (zero mass for the links fixed to the
    /// world of a fixed-base robot, as in Pinocchio).
    pub masses: Vec<f64>,
    /// Centre of mass of each link, in the link frame.
    pub local_coms: Vec<Vector3<f64>>,
    /// Sum of `masses`.
    pub total_mass: f64,
    /// The locked joints and their values, sorted by name: the ones asked for, and the mimics
    /// of locked joints at the values they follow.
    pub locked: Vec<(String, f64)>,
    link_index: HashMap<String, usize>,
    /// q is a vector space with q = v coordinate by coordinate: no free-flyer, every moving
    /// joint that is not a mimic revolute or prismatic with its q index equal to its v index,
    /// and those indices exactly 0..nq = 0..nv. Then [`integrate`](Self::integrate) and
    /// [`difference`](Self::difference) are `q + v` and `q1 - q0` on whole slices (the same
    /// numbers as joint by joint), see [`euclidean`](Self::euclidean).
    euclidean: bool,
}

fn normalized_axis(joint: &str, axis: Vector3<f64>) -> Result<Unit<Vector3<f64>>> {
    unit_vector(&axis, MIN_AXIS_NORM)
        .ok_or_else(|| Error::Invalid(format!("joint '{joint}' has a zero or non-finite axis {:?}", axis.as_slice())))
}

/// The rotation of a free-flyer quaternion `q[3..7]` = (qx, qy, qz, qw), normalised without
/// overflow (components of 1e300 give a unit quaternion); the identity if it is zero or not
/// finite (which [`KinematicModel::check_configuration`] refuses).
fn base_rotation(q: &[f64]) -> UnitQuaternion<f64> {
    unit_quaternion(q[6], q[3], q[4], q[5], 0.0).unwrap_or_else(UnitQuaternion::identity)
}

/// True when the model's q is a vector space coordinate by coordinate
/// ([`KinematicModel::euclidean`]): no free-flyer, nq = nv, and the joints that are neither
/// fixed nor mimics (the ones [`KinematicModel::integrate`] and [`KinematicModel::difference`]
/// visit) are revolute or prismatic, each with its q index equal to its v index, those indices
/// being 0..nq once each.
fn euclidean_coordinates(floating_base: bool, joints: &[Joint], nq: usize, nv: usize) -> bool {
    if floating_base || nq != nv {
        return false;
    }
    let mut seen = vec![false; nq];
    for j in joints.iter().filter(|j| j.mimic.is_none()) {
        match j.motion {
            Motion::Fixed => {}
            Motion::Continuous { .. } => return false,
            Motion::Revolute { .. } | Motion::Prismatic { .. } => {
                if j.q_index != j.v_index || j.q_index >= nq || seen[j.q_index] {
                    return false;
                }
                seen[j.q_index] = true;
            }
        }
    }
    seen.iter().all(|&s| s)
}

/// A cycle of the joint graph, if any, as (joint names, link names) along it: following each
/// link's parent joint (`parent_joint`, at most one per link) to its parent link
/// (`parent_of_joint`) must end at a root. Linear in the number of links.
fn find_cycle(urdf: &Urdf, parent_joint: &[Option<usize>], parent_of_joint: &[usize]) -> Option<(Vec<String>, Vec<String>)> {
    const NEW: u8 = 0;
    const ON_PATH: u8 = 1;
    const DONE: u8 = 2;
    let mut state = vec![NEW; parent_joint.len()];
    for start in 0..parent_joint.len() {
        let mut path = Vec::new();
        let mut l = start;
        while state[l] == NEW {
            state[l] = ON_PATH;
            path.push(l);
            match parent_joint[l] {
                Some(ji) => l = parent_of_joint[ji],
                None => break,
            }
        }
        if state[l] == ON_PATH && parent_joint[l].is_some() {
            let from = path.iter().position(|&p| p == l).unwrap_or(0);
            let links = &path[from..];
            let joints = links.iter().filter_map(|&k| parent_joint[k]).map(|j| urdf.joints[j].name.clone()).collect();
            return Some((joints, links.iter().map(|&k| urdf.links[k].name.clone()).collect()));
        }
        for k in path {
            state[k] = DONE;
        }
    }
    None
}

/// The joint each URDF joint follows, for every joint with a `<mimic>` that moves: (index of
/// the master, the `<mimic>`); None for the others (a fixed joint's `<mimic>` is ignored, as
/// Pinocchio does). A mimic genplan cannot follow is refused by name: the master unknown or
/// itself, a joint that is not revolute or prismatic on either side, a master that is itself a
/// mimic, a master after the mimic in the tree order (`position_in_order`); unless the mimic
/// joint is locked (`locked`): then it is held at its locked value like any joint.
fn mimic_masters<'a>(
    urdf: &'a Urdf,
    joint_pos: &HashMap<&str, usize>,
    position_in_order: &[usize],
    locked: &HashMap<String, f64>,
) -> Result<Vec<Option<(usize, &'a urdf::Mimic)>>> {
    let one_value = |t: JointType| matches!(t, JointType::Revolute | JointType::Prismatic);
    let kind = |t: JointType| format!("{t:?}").to_lowercase();
    let known: Vec<&str> = urdf.joints.iter().map(|j| j.name.as_str()).collect();
    let mut out = vec![None; urdf.joints.len()];
    let mut refused: Vec<(&str, String)> = Vec::new(); // (mimic joint, why), every one at once
    for (ji, j) in urdf.joints.iter().enumerate() {
        let Some(m) = &j.mimic else { continue };
        if j.joint_type == JointType::Fixed {
            continue;
        }
        let why = if m.joint == j.name {
            Some("itself".to_string())
        } else if let Some(&mi) = joint_pos.get(m.joint.as_str()) {
            let master = &urdf.joints[mi];
            if !one_value(j.joint_type) {
                Some(format!("'{}' but is {}", m.joint, kind(j.joint_type)))
            } else if !one_value(master.joint_type) {
                Some(format!("'{}', which is {}", m.joint, kind(master.joint_type)))
            } else if let Some(mm) = &master.mimic {
                Some(format!("'{}', which mimics '{}' in turn", m.joint, mm.joint))
            } else if position_in_order[mi] > position_in_order[ji] {
                Some(format!("'{}', which comes after it in the tree", m.joint))
            } else {
                out[ji] = Some((mi, m));
                None
            }
        } else {
            let hint = match unknown("joint", &m.joint, &known) {
                Error::UnknownName { hint, .. } => hint,
                _ => String::new(),
            };
            Some(format!("'{}', which is not a joint of the URDF{hint}", m.joint))
        };
        // a locked mimic it cannot follow is held like any locked joint
        if let Some(why) = why.filter(|_| !locked.contains_key(&j.name)) {
            refused.push((j.name.as_str(), format!("joint '{}' mimics {why}", j.name)));
        }
    }
    if refused.is_empty() {
        return Ok(out);
    }
    let names: Vec<String> = refused.iter().map(|(n, _)| format!("\"{n}\"")).collect();
    let whys: Vec<&str> = refused.iter().map(|(_, w)| w.as_str()).collect();
    Err(urdf.error(format!(
        "{}. genplan (as Pinocchio) follows only a revolute or prismatic joint that mimics an earlier revolute or \
         prismatic joint, itself no mimic: lock {} to hold {} still (locked_joints = [{}]), or edit the <mimic>",
        whys.join("; "),
        if names.len() == 1 { "it" } else { "them" },
        if names.len() == 1 { "it" } else { "them" },
        names.join(", ")
    )))
}

/// The locked values with the mimics of locked masters added, each at the value it follows
/// (`multiplier * master + offset`). Refused: a locked mimic whose master is not locked, and a
/// locked mimic given a value other than the one it follows.
fn locked_with_mimics(
    urdf: &Urdf,
    masters: &[Option<(usize, &urdf::Mimic)>],
    given: &HashMap<String, f64>,
) -> Result<HashMap<String, f64>> {
    let mut locked = given.clone();
    for (ji, m) in masters.iter().enumerate() {
        let Some((mi, m)) = m else { continue };
        let (name, master) = (&urdf.joints[ji].name, &urdf.joints[*mi].name);
        match given.get(master) {
            None if given.contains_key(name) => {
                return Err(Error::Invalid(format!(
                    "locked joint '{name}' mimics '{master}', which is not locked: lock '{master}' (its mimic joints \
                     are locked with it), or neither"
                )))
            }
            None => {}
            Some(&v) => {
                let follows = m.multiplier * v + m.offset;
                if let Some(&x) = given.get(name) {
                    if (x - follows).abs() > 1e-9 * follows.abs().max(1.0) {
                        return Err(Error::Invalid(format!(
                            "locked joint '{name}' at {x}, but it follows '{master}' ({v} * {} + {} = {follows}): \
                             leave its value out (it is locked with its master)",
                            m.multiplier, m.offset
                        )));
                    }
                }
                locked.insert(name.clone(), follows);
            }
        }
    }
    Ok(locked)
}

impl KinematicModel {
    /// The tree of `urdf`, with the free-flyer, locked joints and q order of `options`.
    ///
    /// Refused: a URDF that [`Urdf::validate`] refuses; a joint whose parent or child link is
    /// unknown, or the same link; a link with two parent joints; joints that form a cycle (their
    /// links are not reachable from the root); other than exactly one root link; a locked value
    /// that is not finite or larger than [`MAX_JOINT_POSITION`] in magnitude, or outside the
    /// joint's limits ([`locked_value_problem`]); an active joint of a type the model does not
    /// support (floating, planar); a `<mimic>` the model cannot follow, a locked mimic whose
    /// master moves, a locked mimic at another value than the one it follows (see the module's
    /// documentation).
    pub fn from_urdf(urdf: &Urdf, options: &ModelOptions) -> Result<KinematicModel> {
        urdf.validate()?;
        let link_pos: HashMap<&str, usize> = urdf
            .links
            .iter()
            .enumerate()
            .map(|(i, l)| (l.name.as_str(), i))
            .collect();
        let link_names_all: Vec<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
        let mut parent_joint: Vec<Option<usize>> = vec![None; urdf.links.len()];
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); urdf.links.len()];
        let mut child_of_joint: Vec<usize> = Vec::with_capacity(urdf.joints.len());
        let mut parent_of_joint: Vec<usize> = Vec::with_capacity(urdf.joints.len());
        for (ji, j) in urdf.joints.iter().enumerate() {
            let p = *link_pos
                .get(j.parent.as_str())
                .ok_or_else(|| unknown("parent link", &j.parent, &link_names_all))?;
            let c = *link_pos
                .get(j.child.as_str())
                .ok_or_else(|| unknown("child link", &j.child, &link_names_all))?;
            if p == c {
                return Err(urdf.error(format!(
                    "joint '{}' has link '{}' as both parent and child (the joints must form a tree)",
                    j.name, j.child
                )));
            }
            if let Some(other) = parent_joint[c] {
                return Err(urdf.error(format!(
                    "link '{}' has two parent joints ('{}' and '{}')",
                    j.child, urdf.joints[other].name, j.name
                )));
            }
            parent_joint[c] = Some(ji);
            children[p].push(ji);
            parent_of_joint.push(p);
            child_of_joint.push(c);
        }
        if let Some((joints, links)) = find_cycle(urdf, &parent_joint, &parent_of_joint) {
            return Err(urdf.error(format!(
                "the joints '{}' form a cycle through the links '{}' (the joints must form a tree; \
                 these links are not reachable from a root)",
                joints.join("', '"),
                links.join("', '")
            )));
        }
        let roots: Vec<usize> = (0..urdf.links.len())
            .filter(|&i| parent_joint[i].is_none())
            .collect();
        if roots.len() != 1 {
            return Err(urdf.error(format!(
                "expected one root link (a link that is no joint's child), found {}: {:?}",
                roots.len(),
                roots.iter().map(|&i| &urdf.links[i].name).collect::<Vec<_>>()
            )));
        }
        let joint_names_all: Vec<&str> = urdf.joints.iter().map(|j| j.name.as_str()).collect();
        let joint_pos: HashMap<&str, usize> =
            urdf.joints.iter().enumerate().map(|(i, j)| (j.name.as_str(), i)).collect();
        let mut locked_names: Vec<(&String, &f64)> = options.locked_joints.iter().collect();
        locked_names.sort_by(|a, b| a.0.cmp(b.0)); // the first error is the same on every run
        for (name, &value) in locked_names {
            let Some(&ji) = joint_pos.get(name.as_str()) else {
                return Err(unknown("locked joint", name, &joint_names_all));
            };
            check_finite(&format!("locked joint '{name}' value"), &[value])?;
            if value.abs() > MAX_JOINT_POSITION {
                return Err(Error::Invalid(format!(
                    "locked joint '{name}': value {value:e} is too large (at most {MAX_JOINT_POSITION:e} in magnitude)"
                )));
            }
            if urdf.joints[ji].joint_type == JointType::Fixed {
                return Err(Error::Invalid(format!("locked joint '{name}' is a fixed joint: it does not move")));
            }
        }

        // Depth-first traversal gives the link order and the default joint order. Children are
        // visited in joint-name order: urdfdom keeps joints in a name-sorted map, so this is the
        // order Pinocchio's URDF parser produces.
        for c in children.iter_mut() {
            c.sort_by(|&a, &b| urdf.joints[a].name.cmp(&urdf.joints[b].name));
        }
        let mut order_links = Vec::with_capacity(urdf.links.len());
        let mut order_joints = Vec::with_capacity(urdf.joints.len());
        let mut stack = vec![roots[0]];
        while let Some(l) = stack.pop() {
            order_links.push(l);
            for &ji in children[l].iter().rev() {
                stack.push(child_of_joint[ji]);
            }
        }
        for &l in &order_links {
            if let Some(ji) = parent_joint[l] {
                order_joints.push(ji);
            }
        }
        // one root, no cycle: every link is reached once (checked above)
        if order_links.len() != urdf.links.len() {
            return Err(urdf.error("some links are not reachable from the root link".into()));
        }
        let mut new_index = vec![0; urdf.links.len()];
        for (new, &old) in order_links.iter().enumerate() {
            new_index[old] = new;
        }
        let mut position_in_order = vec![usize::MAX; urdf.joints.len()];
        for (k, &ji) in order_joints.iter().enumerate() {
            position_in_order[ji] = k;
        }
        let masters = mimic_masters(urdf, &joint_pos, &position_in_order, &options.locked_joints)?;
        // a locked value within the joint's limits (a mimic's, locked with its master, is the
        // one it follows: checked by locked_with_mimics)
        let mut given: Vec<(&String, &f64)> = options.locked_joints.iter().collect();
        given.sort_by(|a, b| a.0.cmp(b.0));
        for (name, &value) in given {
            let ji = joint_pos[name.as_str()];
            if masters[ji].is_none() {
                if let Some(problem) = locked_value_problem(&urdf.joints[ji], value) {
                    return Err(Error::Invalid(format!("locked joint '{name}' at {problem}")));
                }
            }
        }
        let locked = locked_with_mimics(urdf, &masters, &options.locked_joints)?;

        let is_active = |ji: usize| {
            let j = &urdf.joints[ji];
            j.joint_type != JointType::Fixed && !locked.contains_key(&j.name) && masters[ji].is_none()
        };
        let default_order: Vec<String> = order_joints
            .iter()
            .copied()
            .filter(|&ji| is_active(ji))
            .map(|ji| urdf.joints[ji].name.clone())
            .collect();
        let active_joints = match &options.joint_order {
            None => default_order,
            Some(given) => {
                let mut a = given.clone();
                let mut b = default_order.clone();
                a.sort();
                b.sort();
                if a != b {
                    return Err(Error::Invalid(format!(
                        "joint_order must list each active joint once; expected the set {:?}, got {:?}",
                        default_order, given
                    )));
                }
                given.clone()
            }
        };
        let base_nq = if options.floating_base { 7 } else { 0 };
        let mut q_index_of: HashMap<&str, usize> = HashMap::new();
        let mut v_index_of: HashMap<&str, usize> = HashMap::new();
        let mut nq = base_nq;
        let mut nv = if options.floating_base { 6 } else { 0 };
        let mut lower = vec![f64::NEG_INFINITY; base_nq];
        let mut upper = vec![f64::INFINITY; base_nq];
        for name in &active_joints {
            let Some(&ji) = joint_pos.get(name.as_str()) else {
                return Err(unknown("joint", name, &joint_names_all));
            };
            let j = &urdf.joints[ji];
            q_index_of.insert(name.as_str(), nq);
            v_index_of.insert(name.as_str(), nv);
            match j.joint_type {
                JointType::Revolute | JointType::Prismatic => {
                    nq += 1;
                    nv += 1;
                    lower.push(j.lower);
                    upper.push(j.upper);
                }
                JointType::Continuous => {
                    nq += 2;
                    nv += 1;
                    lower.extend([-1.0, -1.0]);
                    upper.extend([1.0, 1.0]);
                }
                other => {
                    return Err(Error::Invalid(format!(
                        "joint '{name}' of type {other:?} is not supported"
                    )))
                }
            }
        }

        let mut joints: Vec<Joint> = Vec::with_capacity(order_joints.len());
        for &ji in &order_joints {
            let j = &urdf.joints[ji];
            let active = is_active(ji);
            let axis = || normalized_axis(&j.name, j.axis);
            let motion_kind = match j.joint_type {
                JointType::Fixed => Motion::Fixed,
                JointType::Revolute => Motion::Revolute { axis: axis()? },
                JointType::Continuous => Motion::Continuous { axis: axis()? },
                JointType::Prismatic => Motion::Prismatic { axis: axis()? },
                other => {
                    return Err(Error::Invalid(format!(
                        "joint '{}' of type {other:?} is not supported",
                        j.name
                    )))
                }
            };
            let follows_active = masters[ji].is_some() && !locked.contains_key(&j.name);
            let (origin, motion) = if active || follows_active || j.joint_type == JointType::Fixed {
                (j.origin, motion_kind)
            } else {
                let value = locked.get(&j.name).copied().unwrap_or(0.0);
                let locked = match &motion_kind {
                    Motion::Revolute { axis } | Motion::Continuous { axis } => {
                        Isometry3::from_parts(
                            Translation3::identity(),
                            UnitQuaternion::from_axis_angle(axis, value),
                        )
                    }
                    Motion::Prismatic { axis } => Isometry3::from_parts(
                        Translation3::from(axis.into_inner() * value),
                        UnitQuaternion::identity(),
                    ),
                    Motion::Fixed => Isometry3::identity(),
                };
                (j.origin * locked, Motion::Fixed)
            };
            // a mimic joint that is not locked follows its (active) master, placed before it
            let mimic = match (&motion, masters[ji]) {
                (Motion::Fixed, _) | (_, None) => None,
                (_, Some((mi, m))) => {
                    let master = position_in_order[mi];
                    let mj = &joints[master];
                    Some(Follows { joint: master, q_index: mj.q_index, v_index: mj.v_index, multiplier: m.multiplier, offset: m.offset })
                }
            };
            joints.push(Joint {
                name: j.name.clone(),
                parent: new_index[parent_of_joint[ji]],
                child: new_index[child_of_joint[ji]],
                origin,
                q_index: q_index_of.get(j.name.as_str()).copied().unwrap_or(usize::MAX),
                v_index: v_index_of.get(j.name.as_str()).copied().unwrap_or(usize::MAX),
                motion,
                mimic,
            });
        }
        let link_names: Vec<String> = order_links
            .iter()
            .map(|&l| urdf.links[l].name.clone())
            .collect();
        let mut body_of_link: Vec<usize> = (0..link_names.len()).collect();
        for j in &joints {
            if matches!(j.motion, Motion::Fixed) {
                body_of_link[j.child] = body_of_link[j.parent];
            }
        }
        let link_index = link_names
            .iter()
            .enumerate()
            .map(|(i, n)| (n.clone(), i))
            .collect();
        let mut parent_link = vec![None; link_names.len()];
        let mut joint_of_link = vec![None; link_names.len()];
        for (ji, j) in joints.iter().enumerate() {
            parent_link[j.child] = Some(j.parent);
            joint_of_link[j.child] = Some(ji);
        }
        let mut active_ancestors: Vec<Vec<usize>> = vec![Vec::new(); link_names.len()];
        for l in 0..link_names.len() {
            let mut chain = match parent_link[l] {
                Some(p) => active_ancestors[p].clone(),
                None => Vec::new(),
            };
            if let Some(ji) = joint_of_link[l] {
                if !matches!(joints[ji].motion, Motion::Fixed) {
                    chain.push(ji);
                }
            }
            active_ancestors[l] = chain;
        }
        let (masses, local_coms): (Vec<f64>, Vec<Vector3<f64>>) = order_links
            .iter()
            .map(|&l| match urdf.links[l].inertial {
                Some(i) => (i.mass, i.com),
                None => (0.0, Vector3::zeros()),
            })
            .unzip();
        // As Pinocchio: on a fixed base, the links rigidly attached to the world do not count
        // towards the centre of mass (they belong to the universe, not to the robot's bodies).
        let masses: Vec<f64> = if options.floating_base {
            masses
        } else {
            masses
                .iter()
                .enumerate()
                .map(|(l, &m)| if body_of_link[l] == 0 { 0.0 } else { m })
                .collect()
        };
        let total_mass = masses.iter().sum();
        let mut locked: Vec<(String, f64)> = locked.into_iter().collect();
        locked.sort_by(|a, b| a.0.cmp(&b.0));
        let euclidean = euclidean_coordinates(options.floating_base, &joints, nq, nv);
        Ok(KinematicModel {
            link_names,
            joints,
            root: 0,
            floating_base: options.floating_base,
            active_joints,
            nq,
            nv,
            lower,
            upper,
            body_of_link,
            parent_link,
            active_ancestors,
            masses,
            local_coms,
            total_mass,
            locked,
            link_index,
            euclidean,
        })
    }

    /// q is a vector space coordinate by coordinate (no free-flyer, no continuous joint, each
    /// moving joint's q index its v index, covering 0..nq = 0..nv): [`integrate`](Self::integrate),
    /// [`difference`](Self::difference) and the planner's distances and interpolations are then
    /// element-wise on whole slices (`planning/space.rs`).
    pub fn euclidean(&self) -> bool {
        self.euclidean
    }

    /// Number of links.
    pub fn n_links(&self) -> usize {
        self.link_names.len()
    }

    /// Index of a link by name, or an error that lists the known names.
    pub fn link_index(&self, name: &str) -> Result<usize> {
        self.link_index.get(name).copied().ok_or_else(|| {
            let known: Vec<&str> = self.link_names.iter().map(String::as_str).collect();
            unknown("link", name, &known)
        })
    }

    /// Check a configuration: length nq, finite, a free-flyer quaternion that is not zero
    /// (norm below 1e-9; any larger finite norm is normalised, without overflow), and each
    /// revolute or prismatic joint's value at most [`MAX_JOINT_POSITION`] (1e16, the bound of
    /// its limits) in magnitude: beyond it a chain of prismatic joints can put a link past what
    /// an f64 holds. A continuous joint's (cos, sin) and the free-flyer base take any finite
    /// values.
    pub fn check_configuration(&self, q: &[f64]) -> Result<()> {
        check_vector("configuration q", q, self.nq)?;
        if self.floating_base {
            let n = stable_norm(&q[3..7]);
            if n < 1e-9 {
                return Err(Error::Invalid(
                    "configuration q: the base quaternion q[3..7] is zero".into(),
                ));
            }
        }
        let one_value = |j: &&Joint| matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. });
        let beyond = |j: &&Joint| q.get(j.q_index).is_some_and(|x| x.abs() > MAX_JOINT_POSITION);
        if let Some(j) = self.joints.iter().filter(one_value).find(beyond) {
            return Err(Error::Invalid(format!(
                "configuration q: joint '{}' (q[{}]) is at {:?}, beyond {MAX_JOINT_POSITION:e} in magnitude",
                j.name, j.q_index, q[j.q_index]
            )));
        }
        Ok(())
    }

    /// World pose of every link (indexed like `link_names`) for a checked configuration.
    /// `out` is resized to `n_links()`.
    pub fn forward_kinematics(&self, q: &[f64], out: &mut Vec<Isometry3<f64>>) -> Result<()> {
        self.check_configuration(q)?;
        self.forward_kinematics_unchecked(q, out);
        Ok(())
    }

    /// As [`forward_kinematics`](Self::forward_kinematics) for a q already checked by
    /// [`check_configuration`](Self::check_configuration).
    pub fn forward_kinematics_unchecked(&self, q: &[f64], out: &mut Vec<Isometry3<f64>>) {
        self.forward_kinematics_prefix(q, out, self.joints.len());
    }

    /// The number of leading joints (in [`joints`](Self::joints) order, parents first) that
    /// place every link of `links` (indices): what
    /// [`forward_kinematics_prefix`](Self::forward_kinematics_prefix) needs for their poses.
    pub fn joints_placing(&self, links: &[usize]) -> usize {
        let placing = |l: usize| self.joints.iter().position(|j| j.child == l).map_or(0, |p| p + 1);
        links.iter().map(|&l| placing(l)).max().unwrap_or(0)
    }

    /// As [`forward_kinematics_unchecked`](Self::forward_kinematics_unchecked) through the
    /// first `joints` joints only (at most all): the root and the links they move get their
    /// poses, the links of the later joints are left at the identity. With
    /// [`joints_placing`](Self::joints_placing), the poses of a few links (a hand) without the
    /// rest of the tree.
    #[inline]
    pub fn forward_kinematics_prefix(&self, q: &[f64], out: &mut Vec<Isometry3<f64>>, joints: usize) {
        out.clear();
        out.resize(self.link_names.len(), Isometry3::identity());
        if self.floating_base {
            out[self.root] = Self::base_pose(q);
        }
        for j in &self.joints[..joints.min(self.joints.len())] {
            // a revolute or prismatic joint's value: its own, or the one it follows
            let value = || match j.mimic {
                None => q[j.q_index],
                Some(f) => f.multiplier * q[f.q_index] + f.offset,
            };
            let motion = match &j.motion {
                Motion::Fixed => None,
                Motion::Revolute { axis } => Some(Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(axis, value()),
                )),
                Motion::Continuous { axis } => {
                    let angle = q[j.q_index + 1].atan2(q[j.q_index]);
                    Some(Isometry3::from_parts(
                        Translation3::identity(),
                        UnitQuaternion::from_axis_angle(axis, angle),
                    ))
                }
                Motion::Prismatic { axis } => Some(Isometry3::from_parts(
                    Translation3::from(axis.into_inner() * value()),
                    UnitQuaternion::identity(),
                )),
            };
            let placed = out[j.parent] * j.origin;
            out[j.child] = match motion {
                Some(m) => placed * m,
                None => placed,
            };
        }
    }
}

impl KinematicModel {
    /// Pose of the free-flyer base encoded in `q[0..7]` (its quaternion normalised without
    /// overflow).
    pub fn base_pose(q: &[f64]) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(q[0], q[1], q[2]), base_rotation(q))
    }

    fn write_base(q: &mut [f64], m: &Isometry3<f64>) {
        let t = m.translation.vector;
        let r = m.rotation.coords; // (x, y, z, w)
        q[..3].copy_from_slice(&[t.x, t.y, t.z]);
        q[3..7].copy_from_slice(&[r.x, r.y, r.z, r.w]);
    }

    /// Jacobian (6 x nv) of a link frame in its own (LOCAL) axes: the frame's linear velocity
    /// and angular velocity, expressed in the frame, as Pinocchio's `getFrameJacobian(LOCAL)`.
    /// `poses` are the link poses from [`forward_kinematics`](Self::forward_kinematics).
    pub fn frame_jacobian_local(&self, poses: &[Isometry3<f64>], link: usize, out: &mut DMatrix<f64>) {
        if out.nrows() != 6 || out.ncols() != self.nv {
            *out = DMatrix::zeros(6, self.nv);
        } else {
            out.fill(0.0);
        }
        let mf = &poses[link];
        let rf_t = mf.rotation.inverse();
        if self.floating_base {
            let ad = action(&(mf.inverse() * poses[self.root]));
            out.view_mut((0, 0), (6, 6)).copy_from(&ad);
        }
        for &ji in &self.active_ancestors[link] {
            let j = &self.joints[ji];
            let Some((v, scale)) = j.velocity_column() else { continue };
            let mj = &poses[j.child];
            let (lin, ang) = match &j.motion {
                Motion::Revolute { axis } | Motion::Continuous { axis } => {
                    let w = mj.rotation * axis.into_inner();
                    (w.cross(&(mf.translation.vector - mj.translation.vector)), w)
                }
                Motion::Prismatic { axis } => (mj.rotation * axis.into_inner(), Vector3::zeros()),
                Motion::Fixed => continue,
            };
            // a mimic joint adds its share to its master's column
            let (lin, ang) = (rf_t * lin * scale, rf_t * ang * scale);
            for k in 0..3 {
                out[(k, v)] += lin[k];
                out[(k + 3, v)] += ang[k];
            }
        }
    }

    /// Centre of mass in the world, and (if `jacobian` is given) its Jacobian (3 x nv), as
    /// Pinocchio's `jacobianCenterOfMass`.
    pub fn center_of_mass(&self, poses: &[Isometry3<f64>], jacobian: Option<&mut DMatrix<f64>>) -> Vector3<f64> {
        let n = self.link_names.len();
        // subtree mass and mass-weighted centre, accumulated from the leaves up
        let mut m_sub = self.masses.clone();
        let mut mc_sub: Vec<Vector3<f64>> = (0..n)
            .map(|l| (poses[l] * nalgebra::Point3::from(self.local_coms[l])).coords * self.masses[l])
            .collect();
        for l in (1..n).rev() {
            if let Some(p) = self.parent_link[l] {
                m_sub[p] += m_sub[l];
                let add = mc_sub[l];
                mc_sub[p] += add;
            }
        }
        let total = self.total_mass.max(f64::MIN_POSITIVE);
        let com = mc_sub[self.root] / total;
        if let Some(jac) = jacobian {
            if jac.nrows() != 3 || jac.ncols() != self.nv {
                *jac = DMatrix::zeros(3, self.nv);
            } else {
                jac.fill(0.0);
            }
            if self.floating_base {
                let mb = &poses[self.root];
                let rb = mb.rotation.to_rotation_matrix().into_inner();
                jac.view_mut((0, 0), (3, 3)).copy_from(&rb);
                let ang: Matrix3<f64> = -skew(&(com - mb.translation.vector)) * rb;
                jac.view_mut((0, 3), (3, 3)).copy_from(&ang);
            }
            for j in &self.joints {
                let Some((v, scale)) = j.velocity_column() else { continue };
                let mj = &poses[j.child];
                let col = match &j.motion {
                    Motion::Revolute { axis } | Motion::Continuous { axis } => {
                        let w = mj.rotation * axis.into_inner();
                        w.cross(&(mc_sub[j.child] - mj.translation.vector * m_sub[j.child])) / total
                    }
                    Motion::Prismatic { axis } => mj.rotation * axis.into_inner() * (m_sub[j.child] / total),
                    Motion::Fixed => continue,
                };
                for k in 0..3 {
                    jac[(k, v)] += scale * col[k];
                }
            }
        }
        com
    }

    /// q (+) v: Pinocchio's `integrate` (free-flyer: M exp6(v), joints: q + v).
    pub fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        if self.euclidean {
            let n = self.nq;
            for ((o, a), b) in out[..n].iter_mut().zip(&q[..n]).zip(&v[..n]) {
                *o = a + b;
            }
            return;
        }
        out.copy_from_slice(q);
        if self.floating_base {
            let m = Self::base_pose(q) * exp6(&Vector6::from_column_slice(&v[..6]));
            let mut m = m;
            m.rotation.renormalize();
            Self::write_base(out, &m);
        }
        for j in self.joints.iter().filter(|j| j.mimic.is_none()) {
            match j.motion {
                Motion::Revolute { .. } | Motion::Prismatic { .. } => out[j.q_index] += v[j.v_index],
                Motion::Continuous { .. } => {
                    let a = q[j.q_index + 1].atan2(q[j.q_index]) + v[j.v_index];
                    out[j.q_index] = a.cos();
                    out[j.q_index + 1] = a.sin();
                }
                Motion::Fixed => {}
            }
        }
    }

    /// q1 (-) q0 in the tangent space: Pinocchio's `difference(q0, q1)`.
    pub fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]) {
        if self.euclidean {
            let n = self.nv;
            for ((o, a), b) in out[..n].iter_mut().zip(&q0[..n]).zip(&q1[..n]) {
                *o = b - a;
            }
            return;
        }
        if self.floating_base {
            let d = log6(&(Self::base_pose(q0).inverse() * Self::base_pose(q1)));
            out[..6].copy_from_slice(d.as_slice());
        }
        for j in self.joints.iter().filter(|j| j.mimic.is_none()) {
            match j.motion {
                Motion::Revolute { .. } | Motion::Prismatic { .. } => out[j.v_index] = q1[j.q_index] - q0[j.q_index],
                Motion::Continuous { .. } => {
                    let a0 = q0[j.q_index + 1].atan2(q0[j.q_index]);
                    let a1 = q1[j.q_index + 1].atan2(q1[j.q_index]);
                    let mut d = a1 - a0;
                    if d > std::f64::consts::PI {
                        d -= 2.0 * std::f64::consts::PI;
                    } else if d < -std::f64::consts::PI {
                        d += 2.0 * std::f64::consts::PI;
                    }
                    out[j.v_index] = d;
                }
                Motion::Fixed => {}
            }
        }
    }

    /// d difference(q0, q1) / d q1 (nv x nv): identity but for the free-flyer block
    /// ([`difference_jacobian_base`](Self::difference_jacobian_base)).
    pub fn difference_jacobian(&self, q0: &[f64], q1: &[f64]) -> DMatrix<f64> {
        let mut out = DMatrix::identity(self.nv, self.nv);
        if let Some(j) = self.difference_jacobian_base(q0, q1) {
            out.view_mut((0, 0), (6, 6)).copy_from(&j);
        }
        out
    }

    /// The free-flyer's block of [`difference_jacobian`](Self::difference_jacobian) (its first 6
    /// rows and columns, Jlog6 of the relative base pose), or None without a free-flyer: every
    /// other entry is the identity's.
    pub fn difference_jacobian_base(&self, q0: &[f64], q1: &[f64]) -> Option<Matrix6<f64>> {
        self.floating_base.then(|| jlog6(&(Self::base_pose(q0).inverse() * Self::base_pose(q1))))
    }
}

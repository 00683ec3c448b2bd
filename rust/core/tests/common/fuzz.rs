//! Shared by the property tests `tests/fuzz_*.rs` (each includes it as `mod fuzz` with a
//! `#[path]`): the proptest configuration, a small XML tree that strategies mutate and write back
//! out, and the checks that a model the readers accepted is usable.
//!
//! Runs are reproducible: the seed is fixed unless `PROPTEST_RNG_SEED` is set, and the case
//! count is the test's unless `PROPTEST_CASES` is set. To search harder:
//! `PROPTEST_CASES=20000 PROPTEST_RNG_SEED=$RANDOM cargo test -p genplan-core --test fuzz_urdf`.
//! A failure prints the shrunk input; it becomes a named test (no regression files are written).

#![allow(dead_code)] // each test file uses its own part of this module

use genplan_core::kinematics::KinematicModel;
use nalgebra::Isometry3;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

/// The configuration of every fuzz test: `cases` cases (default), a fixed seed (default), no
/// regression files.
pub fn config(cases: u32) -> Config {
    let mut c = Config::default(); // reads the PROPTEST_* environment variables
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = cases;
    }
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x6765_6e70_6c61_6e);
    }
    c.failure_persistence = None;
    c
}

/// Numbers as a file may spell them, absurd ones included: not finite, at the edge of f64,
/// negative where only positive makes sense, not numbers at all.
pub const ABSURD: &[&str] = &[
    "0", "-0", "1", "-1", "0.5", "-3.5", "1e308", "-1e308", "1.7976931348623157e308", "1e309", "-1e309",
    "1e-308", "5e-324", "NaN", "nan", "inf", "-inf", "infinity", "+1", "", " ", "abc", "1,5", "0x10", "1_0",
    "1 2", "1 2 3 4", "1e", "--1", "1e3000000",
];

/// Triples of numbers, some absurd.
pub const ABSURD_TRIPLES: &[&str] = &[
    "0 0 0", "1 0 0", "0 0 1", "0.1 -0.2 0.3", "1e308 1e308 1e308", "-1e308 0 1e308", "1e200 0 0",
    "1e-200 0 0", "5e-324 0 0", "nan 0 0", "0 inf 0", "0 0 -inf", "1 2", "1 2 3 4", "a b c", "", "1e3 1e3 1e3",
];

/// Finite numbers of every magnitude (and sign), for configurations and settings. (The number
/// strategies are boxed: nested unboxed strategies make value trees so large that building one
/// overflows a test thread's stack in a debug build.)
pub fn finite() -> BoxedStrategy<f64> {
    prop_oneof![
        -10.0..10.0f64,
        Just(0.0),
        Just(-0.0),
        Just(1e-300),
        Just(5e-324),
        Just(1e300),
        Just(-1e300),
        Just(f64::MAX),
        Just(f64::MIN),
        any::<f64>().prop_filter("finite", |x| x.is_finite()),
    ]
    .boxed()
}

/// Any f64: finite ones of every magnitude, NaN and both infinities.
pub fn any_f64() -> BoxedStrategy<f64> {
    prop_oneof![
        4 => finite(),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
    ]
    .boxed()
}

/// A usize of every size: 0, 1, small, huge.
pub fn any_usize() -> BoxedStrategy<usize> {
    prop_oneof![Just(0usize), Just(1usize), 2usize..1000, Just(usize::MAX), any::<usize>()].boxed()
}

/// The default configuration of a model: 0 for a revolute or prismatic joint, angle 0
/// (cos, sin) = (1, 0) for a continuous one, the identity for a free-flyer.
pub fn neutral(model: &KinematicModel) -> Vec<f64> {
    let mut q = vec![0.0; model.nq];
    if model.floating_base {
        q[6] = 1.0;
    }
    for j in &model.joints {
        if matches!(j.motion, genplan_core::kinematics::Motion::Continuous { .. }) {
            q[j.q_index] = 1.0;
        }
    }
    q
}

/// Every pose is finite and rigid (a unit quaternion).
pub fn rigid_and_finite(poses: &[Isometry3<f64>]) -> Result<(), String> {
    for (i, p) in poses.iter().enumerate() {
        let t = p.translation.vector;
        let r = p.rotation.coords;
        if !t.iter().chain(r.iter()).all(|x| x.is_finite()) {
            return Err(format!("pose {i} is not finite: {p:?}"));
        }
        if (r.norm() - 1.0).abs() > 1e-9 {
            return Err(format!("pose {i} is not rigid (|quaternion| = {}): {p:?}", r.norm()));
        }
    }
    Ok(())
}

/// An XML element: what the strategies mutate, then write back out as text.
#[derive(Debug, Clone, PartialEq)]
pub struct El {
    /// The tag.
    pub tag: String,
    /// The attributes, in order.
    pub attrs: Vec<(String, String)>,
    /// The child elements (text and comments are dropped).
    pub children: Vec<El>,
}

impl El {
    /// The element tree of an XML document (its root element).
    pub fn parse(text: &str) -> El {
        fn convert(n: roxmltree::Node) -> El {
            El {
                tag: n.tag_name().name().to_string(),
                attrs: n.attributes().map(|a| (a.name().to_string(), a.value().to_string())).collect(),
                children: n.children().filter(|c| c.is_element()).map(convert).collect(),
            }
        }
        convert(roxmltree::Document::parse(text).expect("a well-formed seed document").root_element())
    }

    /// The element as XML text (attribute values escaped).
    pub fn write(&self) -> String {
        let mut out = String::new();
        self.write_into(&mut out);
        out
    }

    fn write_into(&self, out: &mut String) {
        out.push('<');
        out.push_str(&self.tag);
        for (k, v) in &self.attrs {
            let v = v.replace('&', "&amp;").replace('"', "&quot;").replace('<', "&lt;");
            out.push_str(&format!(" {k}=\"{v}\""));
        }
        if self.children.is_empty() {
            out.push_str("/>");
            return;
        }
        out.push('>');
        for c in &self.children {
            c.write_into(out);
        }
        out.push_str(&format!("</{}>", self.tag));
    }

    /// Number of elements below this one (itself not counted), in pre-order.
    pub fn count(&self) -> usize {
        self.children.iter().map(|c| 1 + c.count()).sum()
    }

    /// The `i`-th element below this one in pre-order, with its parent, as (parent, index in
    /// the parent's children).
    fn locate(&mut self, i: usize) -> Option<(&mut El, usize)> {
        let mut path = Vec::new();
        if !find_path(self, i, &mut 0, &mut path) {
            return None;
        }
        let k = path.pop()?;
        let mut el = self;
        for p in path {
            el = &mut el.children[p];
        }
        Some((el, k))
    }

    /// The `i`-th element below this one in pre-order (modulo the count), mutably.
    pub fn nth_mut(&mut self, i: usize) -> Option<&mut El> {
        let n = self.count();
        if n == 0 {
            return None;
        }
        let (parent, k) = self.locate(i % n)?;
        Some(&mut parent.children[k])
    }

    /// Apply one mutation (indices are taken modulo what exists).
    pub fn apply(&mut self, m: &Mutation) {
        let n = self.count();
        match *m {
            Mutation::Drop(i) if n > 0 => {
                if let Some((p, k)) = self.locate(i % n) {
                    p.children.remove(k);
                }
            }
            Mutation::Duplicate(i) if n > 0 => {
                if let Some((p, k)) = self.locate(i % n) {
                    let copy = p.children[k].clone();
                    p.children.insert(k, copy);
                }
            }
            Mutation::Move(i, j) if n > 1 => {
                if let Some((p, k)) = self.locate(i % n) {
                    let el = p.children.remove(k);
                    let n2 = self.count();
                    match (n2 > 0).then(|| self.nth_mut(j % n2)).flatten() {
                        Some(target) => target.children.push(el),
                        None => self.children.push(el),
                    }
                }
            }
            Mutation::RenameTag(i, t) if n > 0 => {
                if let Some(el) = self.nth_mut(i) {
                    el.tag = TAGS[t % TAGS.len()].to_string();
                }
            }
            Mutation::DropAttr(i, a) if n > 0 => {
                if let Some(el) = self.nth_mut(i) {
                    if !el.attrs.is_empty() {
                        let k = a % el.attrs.len();
                        el.attrs.remove(k);
                    }
                }
            }
            Mutation::RenameAttr(i, a, name) if n > 0 => {
                if let Some(el) = self.nth_mut(i) {
                    if !el.attrs.is_empty() {
                        let k = a % el.attrs.len();
                        let new = ATTRS[name % ATTRS.len()].to_string();
                        if !el.attrs.iter().any(|(n, _)| *n == new) {
                            el.attrs[k].0 = new;
                        }
                    }
                }
            }
            Mutation::SetAttr(i, a, v) if n > 0 => {
                if let Some(el) = self.nth_mut(i) {
                    let value = VALUES[v % VALUES.len()].to_string();
                    if el.attrs.is_empty() {
                        el.attrs.push((ATTRS[a % ATTRS.len()].to_string(), value));
                    } else {
                        let k = a % el.attrs.len();
                        el.attrs[k].1 = value;
                    }
                }
            }
            Mutation::AddAttr(i, a, v) if n > 0 => {
                if let Some(el) = self.nth_mut(i) {
                    let name = ATTRS[a % ATTRS.len()].to_string();
                    if !el.attrs.iter().any(|(n, _)| *n == name) {
                        el.attrs.push((name, VALUES[v % VALUES.len()].to_string()));
                    }
                }
            }
            Mutation::AddChild(i, t) => {
                let el = El { tag: TAGS[t % TAGS.len()].to_string(), attrs: Vec::new(), children: Vec::new() };
                match (n > 0).then(|| self.nth_mut(i)).flatten() {
                    Some(target) => target.children.push(el),
                    None => self.children.push(el),
                }
            }
            _ => {}
        }
    }
}

fn find_path(el: &El, target: usize, seen: &mut usize, path: &mut Vec<usize>) -> bool {
    for (k, c) in el.children.iter().enumerate() {
        path.push(k);
        if *seen == target {
            return true;
        }
        *seen += 1;
        if find_path(c, target, seen, path) {
            return true;
        }
        path.pop();
    }
    false
}

/// A structural change of an element tree (indices modulo what exists).
#[derive(Debug, Clone)]
pub enum Mutation {
    /// Remove the i-th element (and what it holds).
    Drop(usize),
    /// Insert a copy of the i-th element beside it.
    Duplicate(usize),
    /// Move the i-th element into the j-th.
    Move(usize, usize),
    /// Give the i-th element another tag.
    RenameTag(usize, usize),
    /// Remove an attribute of the i-th element.
    DropAttr(usize, usize),
    /// Rename an attribute of the i-th element.
    RenameAttr(usize, usize, usize),
    /// Set an attribute of the i-th element to one of [`VALUES`].
    SetAttr(usize, usize, usize),
    /// Add an attribute to the i-th element.
    AddAttr(usize, usize, usize),
    /// Add an empty element to the i-th one.
    AddChild(usize, usize),
}

/// Tags of URDF and SRDF files, and some that are neither.
pub const TAGS: &[&str] = &[
    "robot", "link", "joint", "parent", "child", "origin", "axis", "limit", "inertial", "mass", "inertia",
    "collision", "visual", "geometry", "box", "sphere", "cylinder", "capsule", "mesh", "transmission",
    "disable_collisions", "group_state", "group", "bogus",
];

/// Attribute names of URDF and SRDF files, and some that are neither.
pub const ATTRS: &[&str] = &[
    "name", "type", "link", "xyz", "rpy", "lower", "upper", "effort", "velocity", "value", "size", "radius",
    "length", "filename", "scale", "ixx", "ixy", "izz", "link1", "link2", "reason", "group", "bogus",
];

/// Attribute values: absurd numbers and triples, link and joint names (known and unknown),
/// joint types.
pub const VALUES: &[&str] = &[
    "0", "-1", "1e308", "-1e308", "1e309", "5e-324", "NaN", "inf", "-inf", "", "abc", "1 2", "0 0 0", "0 0 1",
    "1e308 1e308 1e308", "1e200 0 0", "nan 0 0", "0 inf 0", "1e-200 0 0", "world", "slider", "wheel", "bracket",
    "arm", "tip", "base", "l1", "l2", "nowhere", "lift", "spin", "mount", "elbow", "tipj", "fixed", "revolute",
    "continuous", "prismatic", "floating", "planar", "bogus", "package://x/y.stl", "missing.stl", "/dev/null",
];

/// A mutation, any kind.
pub fn mutation() -> impl Strategy<Value = Mutation> {
    let i = 0usize..64;
    prop_oneof![
        i.clone().prop_map(Mutation::Drop),
        i.clone().prop_map(Mutation::Duplicate),
        (i.clone(), 0usize..64).prop_map(|(a, b)| Mutation::Move(a, b)),
        (i.clone(), 0usize..64).prop_map(|(a, b)| Mutation::RenameTag(a, b)),
        (i.clone(), 0usize..8).prop_map(|(a, b)| Mutation::DropAttr(a, b)),
        (i.clone(), 0usize..8, 0usize..64).prop_map(|(a, b, c)| Mutation::RenameAttr(a, b, c)),
        (i.clone(), 0usize..8, 0usize..64).prop_map(|(a, b, c)| Mutation::SetAttr(a, b, c)),
        (i.clone(), 0usize..64, 0usize..64).prop_map(|(a, b, c)| Mutation::AddAttr(a, b, c)),
        (i, 0usize..64).prop_map(|(a, b)| Mutation::AddChild(a, b)),
    ]
}

// ---------------------------------------------------------------------------------------------
// What an accepted robot must allow, and the known gaps (each has a `finding_*` test in the file
// that reports it, which fails once the gap is closed: then its exemption here goes too).
// ---------------------------------------------------------------------------------------------

use std::sync::Arc;

use genplan_core::collision::CollisionWorld;
use genplan_core::planning::{Sampler, UniformSampler};
use genplan_core::projection::{self, Projector, Term, TermKind};
use genplan_core::kinematics::Motion;
use genplan_core::urdf::{Urdf, MAX_JOINT_POSITION};
use proptest::test_runner::TestCaseError;

/// Known gaps an input falls into; `Gaps::default()` (none) checks every property. No finding
/// is open (URDF-7, the last, is fixed): a new one adds its exemption here as a field.
#[derive(Debug, Clone, Copy, Default)]
pub struct Gaps {}

/// An accepted model is whole and usable: every URDF link in it, one q slot per active joint,
/// finite rigid poses at the default configuration and at `q` (when FK accepts it: exactly when
/// it fits and is finite, each revolute or prismatic value at most `urdf::MAX_JOINT_POSITION` in
/// magnitude and a free-flyer quaternion not zero), collision queries that answer, and the
/// native sampler and projector work on it.
pub fn check_robot(urdf: &Urdf, model: KinematicModel, q: &[f64], gaps: Gaps) -> Result<(), TestCaseError> {
    let Gaps {} = gaps; // none open: every property below is checked
    prop_assert_eq!(model.n_links(), urdf.links.len(), "every link of the URDF is in the model");
    prop_assert_eq!(model.lower.len(), model.nq);
    prop_assert_eq!(model.upper.len(), model.nq);
    let mut names = model.active_joints.clone();
    names.sort();
    names.dedup();
    prop_assert_eq!(names.len(), model.active_joints.len(), "each active joint once: {:?}", model.active_joints);
    let mut poses = Vec::new();
    let q0 = neutral(&model);
    if model.forward_kinematics(&q0, &mut poses).is_ok() {
        prop_assert_eq!(poses.len(), model.n_links());
        rigid_and_finite(&poses).map_err(|e| TestCaseError::fail(format!("FK at the default configuration: {e}")))?;
    }
    let q: Vec<f64> = q.iter().cycle().take(model.nq).copied().collect();
    // a revolute or prismatic joint beyond MAX_JOINT_POSITION (finding URDF-7, fixed: prismatic
    // joints at f64::MAX put a link past what an f64 holds, and FK answered Ok)
    let beyond = model.joints.iter().any(|j| {
        matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. })
            && q.get(j.q_index).is_some_and(|x| x.abs() > MAX_JOINT_POSITION)
    });
    match model.forward_kinematics(&q, &mut poses) {
        Ok(()) => {
            prop_assert!(q.iter().all(|x| x.is_finite()), "FK accepted a non-finite q {:?}", q);
            prop_assert!(!beyond, "FK accepted a joint value beyond {:e}: {:?}", MAX_JOINT_POSITION, q);
            rigid_and_finite(&poses).map_err(|e| TestCaseError::fail(format!("FK at q = {q:?}: {e}")))?;
        }
        Err(_) => prop_assert!(
            q.len() != model.nq || q.iter().any(|x| !x.is_finite()) || beyond || model.floating_base,
            "FK refused a finite q of the right length {:?}", q
        ),
    }
    let model = Arc::new(model);
    use_uniform_sampler(&model)?;
    use_projector(&model, &q0)?;
    if let Ok(world) = CollisionWorld::from_urdf(model, urdf, &[], None) {
        let _ = world.in_collision(&q0);
        if let Ok(d) = world.min_distance(&q0) {
            prop_assert!(!d.is_nan(), "min_distance at the default configuration is NaN");
        }
    }
    Ok(())
}

/// The native uniform sampler on an accepted model: refused, or finite samples within the
/// limits.
pub fn use_uniform_sampler(model: &Arc<KinematicModel>) -> Result<(), TestCaseError> {
    if let Ok(mut sampler) = UniformSampler::new(model.clone(), None, 7) {
        let mut out = vec![0.0; 3 * model.nq];
        prop_assert!(sampler.sample(3, &mut out).is_ok());
        for row in out.chunks(model.nq.max(1)) {
            prop_assert!(row.iter().all(|x| x.is_finite()), "a uniform sample is not finite: {:?}", row);
            for (i, x) in row.iter().enumerate() {
                prop_assert!(model.lower[i] <= *x && *x <= model.upper[i], "a uniform sample is outside the limits");
            }
        }
    }
    Ok(())
}

/// The native projector (joint limits, posture) on an accepted model, from `q0`: refused, or a
/// finite answer.
pub fn use_projector(model: &Arc<KinematicModel>, q0: &[f64]) -> Result<(), TestCaseError> {
    let terms = vec![Term { name: "limits".into(), kind: TermKind::JointLimits { margin: 1e-3 }, weight: 1.0, tolerance: 1e-3 }];
    let posture = vec![Term {
        name: "posture".into(),
        kind: TermKind::Posture { q_nom: None, weights: vec![1.0; model.nv], overrides: Vec::new() },
        weight: 1.0,
        tolerance: 1.0,
    }];
    if let Ok(projector) = Projector::new(model.clone(), terms, posture, projection::Settings::default()) {
        if let Ok(out) = projector.solve(q0, None) {
            prop_assert!(out.q.iter().all(|x| x.is_finite()), "the projector gave a non-finite q {:?}", out.q);
        }
    }
    Ok(())
}

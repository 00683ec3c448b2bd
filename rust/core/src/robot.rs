//! Robot descriptions as data: which files, which joints move, where the base is, which frames
//! matter.
//!
//! A [`RobotDescription`] is read from a robot file (TOML, [`RobotDescription::from_file`]) or
//! built from the same keys ([`RobotDescription::from_table`]); genplan's presets are robot files
//! shipped in the Python package (`python/genplan/presets/robots/*.toml`) and read by the same
//! code as a user's file. The Python side reads a description through `genplan._core` to build
//! the matching Pinocchio model, so Rust and Pinocchio always describe the same robot.
//!
//! The keys of a robot file (paths relative to the file, absolute, or `package://PKG/...`
//! resolved against the package folders):
//!
//! ```toml
//! name = "panda"                  # optional: the file's stem
//! urdf = "package://example-robot-data/robots/panda_description/urdf/panda.urdf"
//! collision_urdf = "..."          # optional: the URDF whose <collision> elements to use
//! srdf = "..."                    # optional: disabled pairs and named states
//! package_dirs = ["../meshes"]    # optional: where package:// URIs are looked up first
//! floating_base = false           # optional: a free-flyer root joint
//! locked_joints = ["finger_1"]    # optional: held at the reference state's value (or neutral) ...
//! # locked_joints = { finger_1 = 0.04 }   # ... or at the given values
//! reference_state = "default"     # optional: an SRDF group_state
//! merge_computed_pairs = false    # optional: skip the computed self-collision pairs too
//! mesh_shape = "hull"             # optional: the meshes as "hull" | "mesh" | "decomposed"
//! [frames]                        # optional: roles -> link names
//! hand = "panda_hand"
//! [[attached]]                    # optional: objects held by links (read by genplan.robots)
//! name = "tray"
//! link = "panda_hand"
//! box = { size = [0.3, 0.2, 0.02] }   # one shape table, a scene file's keys
//! ```
//!
//! [`RobotDescription::read`] checks a description against its files before anything is built
//! from it: what genplan uses must name what the files have (SRDF pairs and the reference
//! state's joints, locked joints, frames), locked and reference values lie within the joints'
//! limits, a collision URDF has the URDF's tree, mimic joints are ones the model can follow.
//! What genplan does not use but looks wrong (another group state naming unknown joints) is a
//! warning.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::collision::{CollisionWorld, MeshShape};
use crate::collision::allowed;
use crate::error::{unknown, Error, Result};
use crate::kinematics::{locked_value_problem, KinematicModel, ModelOptions, Motion};
use crate::srdf::Srdf;
use crate::urdf::{resolve_uri, JointType, Urdf};

/// The keys a robot file may hold.
pub const ROBOT_KEYS: [&str; 12] = [
    "name",
    "urdf",
    "collision_urdf",
    "srdf",
    "package_dirs",
    "floating_base",
    "locked_joints",
    "reference_state",
    "merge_computed_pairs",
    "mesh_shape",
    "frames",
    "attached",
];

/// Which joints are locked, and at what.
#[derive(Debug, Clone, PartialEq)]
pub enum LockedJoints {
    /// Held at their value in the reference state (their neutral value where it says nothing,
    /// [`neutral_value`]).
    FromReference(Vec<String>),
    /// Held at the given values.
    Values(Vec<(String, f64)>),
}

impl LockedJoints {
    /// True when no joint is locked.
    pub fn is_empty(&self) -> bool {
        match self {
            LockedJoints::FromReference(n) => n.is_empty(),
            LockedJoints::Values(v) => v.is_empty(),
        }
    }
}

/// A robot: its files (resolved to absolute paths that exist) and how to read them.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotDescription {
    /// The robot's name (the file's stem unless the file says otherwise).
    pub name: String,
    /// URDF for kinematics.
    pub urdf: PathBuf,
    /// URDF whose `<collision>` elements are the collision model (same kinematic tree).
    pub collision_urdf: PathBuf,
    /// SRDF: disabled collision pairs and named states. Without one, the pairs to skip are
    /// computed (`genplan_core::collision::allowed`).
    pub srdf: Option<PathBuf>,
    /// Folders where `package://PKG/...` resolves to `<dir>/PKG/...`, in search order.
    pub package_dirs: Vec<PathBuf>,
    /// The root joint is a free-flyer (q starts with [x, y, z, qx, qy, qz, qw]).
    pub floating_base: bool,
    /// Movable joints removed from q.
    pub locked_joints: LockedJoints,
    /// The SRDF group state that gives the default configuration and the locked values.
    pub reference_state: Option<String>,
    /// Skip the computed self-collision pairs ([`allowed::disabled_pairs`]) as well as the
    /// SRDF's: the remedy for an SRDF that leaves pairs in contact at the default
    /// configuration.
    pub merge_computed_pairs: bool,
    /// What the collision URDF's meshes become (default [`MeshShape::Hull`]).
    pub mesh_shape: MeshShape,
    /// Named frames: (role, link name), in the file's order.
    pub frames: Vec<(String, String)>,
    /// Objects attached to links (`[[attached]]` tables, in the file's order): each has a
    /// string `name` (unique) and `link`; the rest (the shape's table, the pose, mass, touch
    /// links) is read and checked by `genplan.robots`, which builds them with the scene file's
    /// shapes. A mesh's `path` is resolved here, as the file's other paths are.
    pub attached: Vec<toml::Table>,
    /// The robot file this came from, if any.
    pub source: Option<PathBuf>,
}

/// An error about a robot description: a [`Error::Parse`] naming its origin (file) and the key.
fn invalid(origin: &str, msg: String) -> Error {
    Error::Parse { what: origin.to_string(), msg }
}

fn string(origin: &str, key: &str, v: &toml::Value) -> Result<String> {
    v.as_str()
        .map(str::to_string)
        .ok_or_else(|| invalid(origin, format!("'{key}' must be a string, got {}", v.type_str())))
}

fn strings(origin: &str, key: &str, v: &toml::Value) -> Result<Vec<String>> {
    let arr = v
        .as_array()
        .ok_or_else(|| invalid(origin, format!("'{key}' must be a list of strings, got {}", v.type_str())))?;
    arr.iter().map(|x| string(origin, key, x)).collect()
}

/// The `[[attached]]` tables of a robot file: each with a non-empty string `name` (unique) and
/// `link`, a mesh's `path` (in any table of the entry) resolved against `base` and
/// `package_dirs`.
fn attached_tables(origin: &str, v: Option<&toml::Value>, base: Option<&Path>, package_dirs: &[PathBuf]) -> Result<Vec<toml::Table>> {
    let Some(v) = v else { return Ok(Vec::new()) };
    let rows = v
        .as_array()
        .filter(|a| a.iter().all(toml::Value::is_table))
        .ok_or_else(|| invalid(origin, format!("'attached' must be a list of [[attached]] tables, got {}", v.type_str())))?;
    let mut out: Vec<toml::Table> = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let mut t = row.as_table().expect("checked").clone();
        let at = format!("[[attached]] {}", i + 1);
        for key in ["name", "link"] {
            match t.get(key) {
                Some(toml::Value::String(s)) if !s.is_empty() => {}
                Some(x) => return Err(invalid(origin, format!("{at}: '{key}' must be a non-empty string, got {}", x.type_str()))),
                None => return Err(invalid(origin, format!("{at}: '{key}' is missing"))),
            }
        }
        let name = t["name"].as_str().expect("checked").to_string();
        if out.iter().any(|o| o["name"].as_str() == Some(name.as_str())) {
            return Err(invalid(origin, format!("{at}: the name '{name}' is taken by another attached object")));
        }
        for (key, sub) in t.iter_mut() {
            if let Some(toml::Value::String(p)) = sub.as_table_mut().and_then(|x| x.get_mut("path")) {
                let resolved = resolve_path(p, base, package_dirs).map_err(|e| invalid(origin, format!("{at} ('{name}'): {key}.path: {e}")))?;
                *p = resolved.to_string_lossy().into_owned();
            }
        }
        out.push(t);
    }
    Ok(out)
}

/// Resolve a path value: `package://PKG/rest` against `package_dirs` (the first that exists),
/// else relative to `base` ([`crate::urdf::resolve_uri`]).
pub fn resolve_path(value: &str, base: Option<&Path>, package_dirs: &[PathBuf]) -> Result<PathBuf> {
    resolve_uri(value, base, package_dirs, Path::exists).ok_or_else(|| {
        let dirs: Vec<String> = package_dirs.iter().map(|d| d.display().to_string()).collect();
        Error::Invalid(format!(
            "'{value}' is not under any package folder (searched: {})",
            if dirs.is_empty() { "none given".to_string() } else { dirs.join(", ") }
        ))
    })
}

impl RobotDescription {
    /// Read a robot file (TOML). `default_package_dirs` are searched after the file's own
    /// `package_dirs` (genplan passes example-robot-data's `share/` folder).
    pub fn from_file(path: impl AsRef<Path>, default_package_dirs: &[PathBuf]) -> Result<RobotDescription> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let origin = format!("robot file {}", path.display());
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| invalid(&origin, e.to_string().trim().to_string()))?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("robot").to_string();
        let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
        let base = base.map(|b| std::fs::canonicalize(b).unwrap_or_else(|_| b.to_path_buf()));
        let mut d = Self::from_table(&table, base.as_deref(), default_package_dirs, &origin, &stem)?;
        d.source = Some(path.to_path_buf());
        Ok(d)
    }

    /// Build from the keys of a robot file (see the module's documentation). Relative paths are
    /// relative to `base` (the current folder if None); `origin` names the input in errors;
    /// `default_name` is used when the table has no `name`.
    pub fn from_table(
        table: &toml::Table,
        base: Option<&Path>,
        default_package_dirs: &[PathBuf],
        origin: &str,
        default_name: &str,
    ) -> Result<RobotDescription> {
        for key in table.keys() {
            if !ROBOT_KEYS.contains(&key.as_str()) {
                return Err(invalid(origin, format!("unknown key '{key}' (known: {})", ROBOT_KEYS.join(", "))));
            }
        }
        let get = |k: &str| table.get(k);
        let name = match get("name") {
            Some(v) => string(origin, "name", v)?,
            None => default_name.to_string(),
        };
        if name.is_empty() {
            return Err(invalid(origin, "'name' is empty".into()));
        }
        // the name is part of cache file names and model cards
        if name == "." || name == ".." || name.chars().any(|c| c == '/' || c == '\\' || c.is_control()) {
            return Err(invalid(
                origin,
                format!("'name' '{}' cannot name a file (no '/', '\\', control characters, '.' or '..')", name.escape_debug()),
            ));
        }
        let mut package_dirs = Vec::new();
        if let Some(v) = get("package_dirs") {
            for s in strings(origin, "package_dirs", v)? {
                let p = resolve_path(&s, base, &[])?;
                if !p.is_dir() {
                    return Err(invalid(origin, format!("'package_dirs': {} is not a folder", p.display())));
                }
                package_dirs.push(p);
            }
        }
        package_dirs.extend(default_package_dirs.iter().cloned());
        let file = |key: &str, required: bool| -> Result<Option<PathBuf>> {
            let Some(v) = get(key) else {
                return if required { Err(invalid(origin, format!("'{key}' is missing (the robot's URDF)"))) } else { Ok(None) };
            };
            let s = string(origin, key, v)?;
            let p = resolve_path(&s, base, &package_dirs).map_err(|e| invalid(origin, format!("'{key}': {e}")))?;
            if !p.is_file() {
                return Err(invalid(origin, format!("'{key}': {} does not exist", p.display())));
            }
            Ok(Some(p))
        };
        let urdf = file("urdf", true)?.expect("required");
        let collision_urdf = file("collision_urdf", false)?.unwrap_or_else(|| urdf.clone());
        let srdf = file("srdf", false)?;
        let floating_base = match get("floating_base") {
            Some(v) => v
                .as_bool()
                .ok_or_else(|| invalid(origin, format!("'floating_base' must be true or false, got {}", v.type_str())))?,
            None => false,
        };
        let locked_joints = match get("locked_joints") {
            None => LockedJoints::FromReference(Vec::new()),
            Some(toml::Value::Table(t)) => {
                let mut values = Vec::new();
                for (k, v) in t {
                    let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).ok_or_else(|| {
                        invalid(origin, format!("'locked_joints.{k}' must be a number, got {}", v.type_str()))
                    })?;
                    if !x.is_finite() {
                        return Err(invalid(origin, format!("'locked_joints.{k}' is not finite")));
                    }
                    values.push((k.clone(), x));
                }
                LockedJoints::Values(values)
            }
            Some(v) => {
                let names = strings(origin, "locked_joints", v).map_err(|_| {
                    invalid(
                        origin,
                        format!("'locked_joints' must be a list of joint names or a table name = value, got {}", v.type_str()),
                    )
                })?;
                let mut seen = std::collections::HashSet::new();
                if let Some(twice) = names.iter().find(|n| !seen.insert(n.as_str())) {
                    return Err(invalid(origin, format!("'locked_joints' names '{twice}' twice")));
                }
                LockedJoints::FromReference(names)
            }
        };
        let reference_state = match get("reference_state") {
            Some(v) => Some(string(origin, "reference_state", v)?),
            None => None,
        };
        if reference_state.is_some() && srdf.is_none() {
            return Err(invalid(origin, "'reference_state' names an SRDF group state, but there is no 'srdf'".into()));
        }
        let mesh_shape = match get("mesh_shape") {
            Some(v) => MeshShape::from_name(&string(origin, "mesh_shape", v)?).map_err(|e| invalid(origin, format!("'mesh_shape': {e}")))?,
            None => MeshShape::Hull,
        };
        let merge_computed_pairs = match get("merge_computed_pairs") {
            Some(v) => v.as_bool().ok_or_else(|| {
                invalid(origin, format!("'merge_computed_pairs' must be true or false, got {}", v.type_str()))
            })?,
            None => false,
        };
        let mut frames = Vec::new();
        if let Some(v) = get("frames") {
            let t = v
                .as_table()
                .ok_or_else(|| invalid(origin, format!("'frames' must be a table role = link name, got {}", v.type_str())))?;
            for (role, link) in t {
                if role.trim().is_empty() {
                    return Err(invalid(origin, format!("frame role '{role}' is empty")));
                }
                frames.push((role.clone(), string(origin, &format!("frames.{role}"), link)?));
            }
        }
        let attached = attached_tables(origin, get("attached"), base, &package_dirs)?;
        Ok(RobotDescription {
            attached,
            name,
            urdf,
            collision_urdf,
            srdf,
            package_dirs,
            floating_base,
            locked_joints,
            reference_state,
            merge_computed_pairs,
            mesh_shape,
            frames,
            source: None,
        })
    }

    /// Where errors about this description point: its robot file, else its URDF.
    pub fn origin(&self) -> String {
        match &self.source {
            Some(p) => format!("robot file {}", p.display()),
            None => format!("robot '{}' ({})", self.name, self.urdf.display()),
        }
    }

    /// The SRDF, if the description has one.
    pub fn read_srdf(&self) -> Result<Option<Srdf>> {
        self.srdf.as_ref().map(Srdf::from_file).transpose()
    }

    /// `SRDF <path>`, as messages name it.
    fn srdf_what(&self) -> String {
        self.srdf.as_ref().map_or_else(|| "SRDF".to_string(), |p| format!("SRDF {}", p.display()))
    }

    /// The reference state's joint values (None without a `reference_state`); a state the SRDF
    /// does not have is an [`Error::UnknownName`] naming the robot file and the SRDF and
    /// listing the states it has.
    pub fn reference<'a>(&self, srdf: Option<&'a Srdf>) -> Result<Option<&'a HashMap<String, Vec<f64>>>> {
        let (Some(r), Some(s)) = (&self.reference_state, srdf) else { return Ok(None) };
        s.group_states.get(r).map(Some).ok_or_else(|| {
            let mut known: Vec<&str> = s.group_states.keys().map(String::as_str).collect();
            known.sort_unstable();
            unknown_in("group_state", r, &known, format!("(reference_state of {}) in {}", self.origin(), self.srdf_what()))
        })
    }

    /// Locked joint values as the description gives them: given, or from the SRDF's reference
    /// state (0 where it says nothing; [`read`](Self::read) holds such a joint at its
    /// [`neutral_value`] instead, and a mimic of a locked joint at the value it follows).
    /// The mimics of locked joints are added by the model
    /// ([`KinematicModel::from_urdf`]), at the values they follow.
    pub fn locked_values(&self, srdf: Option<&Srdf>) -> Result<HashMap<String, f64>> {
        let state = self.reference(srdf)?;
        Ok(match &self.locked_joints {
            LockedJoints::Values(v) => v.iter().cloned().collect(),
            LockedJoints::FromReference(names) => names
                .iter()
                .map(|j| {
                    let v = state.and_then(|s| s.get(j)).and_then(|v| v.first().copied()).unwrap_or(0.0);
                    (j.clone(), v)
                })
                .collect(),
        })
    }

    /// Where a locked joint's value comes from, as messages say it.
    fn locked_source(&self, joint: &str, srdf: Option<&Srdf>) -> String {
        match (&self.locked_joints, &self.reference_state) {
            (LockedJoints::Values(_), _) => String::new(),
            (LockedJoints::FromReference(_), Some(r)) if srdf.and_then(|s| s.group_states.get(r)).is_some_and(|s| s.contains_key(joint)) => {
                format!(" (group_state '{r}' of {})", self.srdf_what())
            }
            (LockedJoints::FromReference(_), _) => " (its neutral value)".to_string(),
        }
    }

    /// Read the files and check the description against them (see the module's
    /// documentation); the model, the default configuration and the warnings.
    ///
    /// Errors name the file at fault and the name or value: a URDF or SRDF that cannot be
    /// parsed (with the parser's reason), a collision URDF of another tree, a
    /// `<disable_collisions>` naming a link the URDF lacks, a `reference_state` the SRDF lacks
    /// or whose joints the URDF lacks (or with a value outside a joint's limits, or with the
    /// wrong number of values, or a mimic joint's value other than the one it follows), a
    /// locked joint that is unknown or at a value outside its limits, a mimic the model cannot
    /// follow, a frame naming no link or a role named like another link.
    pub fn read(&self) -> Result<RobotFiles> {
        let origin = self.origin();
        let urdf = Urdf::from_file(&self.urdf)?;
        let srdf = self.read_srdf()?;
        let mut warnings = Vec::new();
        if let Some(s) = &srdf {
            self.check_srdf_names(s, &urdf, &mut warnings)?;
        }
        let state = self.reference(srdf.as_ref())?;
        let mut locked = self.locked_values(srdf.as_ref())?;
        if let LockedJoints::FromReference(_) = self.locked_joints {
            for j in &urdf.joints {
                if !locked.contains_key(&j.name) || state.is_some_and(|s| s.contains_key(&j.name)) {
                    continue;
                }
                match &j.mimic {
                    // a listed mimic of a listed joint takes the value it follows (a value the
                    // state gives is checked against it by the model)
                    Some(m) if locked.contains_key(&m.joint) => {
                        locked.remove(&j.name);
                    }
                    // no value given: the joint's neutral one, as in the default configuration
                    _ => {
                        locked.insert(j.name.clone(), neutral_value(j));
                    }
                }
            }
        }
        let mut names: Vec<&String> = locked.keys().collect();
        names.sort();
        let joints: Vec<&str> = urdf.joints.iter().map(|j| j.name.as_str()).collect();
        for name in names {
            let Some(j) = urdf.joints.iter().find(|j| &j.name == name) else {
                return Err(unknown_in("joint", name, &joints, format!("(locked_joints of {origin}) in {}", urdf.what())));
            };
            if j.mimic.is_some() {
                continue; // a mimic's value is the one it follows (checked by the model)
            }
            if let Some(problem) = locked_value_problem(j, locked[name]) {
                let at = problem.replacen(' ', &format!("{} ", self.locked_source(name, srdf.as_ref())), 1);
                return Err(invalid(&origin, format!("locked joint '{name}' at {at}")));
            }
        }
        let options = ModelOptions { floating_base: self.floating_base, locked_joints: locked, joint_order: None };
        let model = KinematicModel::from_urdf(&urdf, &options).map_err(|e| in_file(e, &origin, &urdf.what()))?;
        let links: Vec<&str> = model.link_names.iter().map(String::as_str).collect();
        for (role, link) in &self.frames {
            if model.link_index(link).is_err() {
                return Err(unknown_in("link", link, &links, format!("(frame '{role}' of {}) in {}", origin, urdf.what())));
            }
            if role != link && model.link_index(role).is_ok() {
                return Err(invalid(
                    &origin,
                    format!("frame role '{role}' is the name of another link (it names '{link}'): rename the role"),
                ));
            }
        }
        let q_default = self.default_configuration(&model, &urdf, state, &mut warnings)?;
        let collision_urdf = if self.collision_urdf == self.urdf {
            None
        } else {
            let c = Urdf::from_file(&self.collision_urdf)?;
            if let Some(diff) = tree_difference(&urdf, &c) {
                return Err(invalid(
                    &origin,
                    format!(
                        "'collision_urdf' {} is not the tree of 'urdf' {}: {diff}",
                        self.collision_urdf.display(),
                        self.urdf.display()
                    ),
                ));
            }
            Some(c)
        };
        Ok(RobotFiles { model: Arc::new(model), urdf, collision_urdf, srdf, q_default, warnings })
    }

    /// The SRDF's names against the URDF's: a `<disable_collisions>` link or a joint of the
    /// reference state that the URDF lacks is an error; another group state's unknown joints
    /// are a warning. `root_joint` (the free-flyer's name) is known.
    fn check_srdf_names(&self, srdf: &Srdf, urdf: &Urdf, warnings: &mut Vec<String>) -> Result<()> {
        let links: Vec<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
        for (a, b) in &srdf.disabled_pairs {
            for l in [a, b] {
                if !links.contains(&l.as_str()) {
                    return Err(unknown_in("link", l, &links, format!("in <disable_collisions> of {}: not a link of {}", self.srdf_what(), urdf.what())));
                }
            }
        }
        let joints: Vec<&str> = urdf.joints.iter().map(|j| j.name.as_str()).collect();
        let mut states: Vec<(&String, &HashMap<String, Vec<f64>>)> = srdf.group_states.iter().collect();
        states.sort_by(|a, b| a.0.cmp(b.0));
        for (name, values) in states {
            let mut missing: Vec<&str> =
                values.keys().map(String::as_str).filter(|j| !joints.contains(j) && *j != FREE_FLYER).collect();
            if missing.is_empty() {
                continue;
            }
            missing.sort_unstable();
            if self.reference_state.as_deref() == Some(name.as_str()) {
                return Err(unknown_in("joint", missing[0], &joints, format!("in group_state '{name}' of {}: not a joint of {}", self.srdf_what(), urdf.what())));
            }
            const SHOWN: usize = 12;
            let more = if missing.len() > SHOWN { format!(", ... ({} in all)", missing.len()) } else { String::new() };
            let used = match &self.reference_state {
                Some(r) => format!("the reference state is '{r}'"),
                None => "no reference_state".to_string(),
            };
            warnings.push(format!(
                "{}: group_state '{name}' names joints unknown to {}: {}{more} (not used: {used})",
                self.srdf_what(),
                urdf.what(),
                missing[..missing.len().min(SHOWN)].join(", ")
            ));
        }
        Ok(())
    }

    /// The default configuration: the neutral one ([`neutral_value`]; a continuous joint at
    /// angle 0; the base at the origin) with the reference state's values of the active joints,
    /// each checked
    /// against the joint's limits; the state's values for a mimic joint must be those it
    /// follows, and each joint takes as many values as it has (1, or 7 for the free-flyer).
    fn default_configuration(
        &self,
        model: &KinematicModel,
        urdf: &Urdf,
        state: Option<&HashMap<String, Vec<f64>>>,
        warnings: &mut Vec<String>,
    ) -> Result<Vec<f64>> {
        let mut q = vec![0.0; model.nq];
        if model.floating_base {
            q[6] = 1.0;
        }
        for j in model.joints.iter().filter(|j| j.q_index != usize::MAX) {
            match j.motion {
                Motion::Continuous { .. } => q[j.q_index] = 1.0,
                _ => {
                    if let Some(u) = urdf.joints.iter().find(|u| u.name == j.name) {
                        q[j.q_index] = neutral_value(u);
                    }
                }
            }
        }
        let (Some(state), Some(r)) = (state, &self.reference_state) else { return Ok(q) };
        let what = format!("group_state '{r}' of {}", self.srdf_what());
        let mut entries: Vec<(&String, &Vec<f64>)> = state.iter().collect();
        entries.sort_by(|a, b| a.0.cmp(b.0));
        let arity = |name: &str, values: &[f64], n: usize| -> Result<()> {
            if values.len() == n {
                Ok(())
            } else {
                Err(invalid(&self.origin(), format!("{what} gives joint '{name}' {} values, but it takes {n}", values.len())))
            }
        };
        for (name, values) in entries.iter().copied() {
            if name == FREE_FLYER {
                if !model.floating_base {
                    warnings.push(format!("{what} places '{FREE_FLYER}', the free-flyer base, but the robot has none: ignored"));
                    continue;
                }
                arity(name, values, 7)?;
                q[..7].copy_from_slice(values);
                continue;
            }
            if urdf.joints.iter().any(|u| &u.name == name && u.joint_type == JointType::Fixed) {
                continue; // a fixed joint's value means nothing (as in Pinocchio)
            }
            let Some(j) = model.joints.iter().find(|j| &j.name == name) else { continue }; // known (checked)
            arity(name, values, 1)?;
            let x = values[0];
            if let Some(f) = j.mimic {
                let master = &model.joints[f.joint];
                let follows = f.multiplier * state.get(&master.name).and_then(|v| v.first().copied()).unwrap_or(0.0) + f.offset;
                if (x - follows).abs() > 1e-6 * follows.abs().max(1.0) {
                    return Err(invalid(
                        &self.origin(),
                        format!("{what} puts mimic joint '{name}' at {x}, but it follows '{}' (at {follows})", master.name),
                    ));
                }
                continue;
            }
            if j.q_index == usize::MAX {
                continue; // locked: its value was checked with the locked joints
            }
            match j.motion {
                Motion::Continuous { .. } => {
                    q[j.q_index] = x.cos();
                    q[j.q_index + 1] = x.sin();
                }
                _ => {
                    let (lo, hi) = (model.lower[j.q_index], model.upper[j.q_index]);
                    if !(lo <= x && x <= hi) {
                        return Err(invalid(
                            &self.origin(),
                            format!("{what} puts joint '{name}' at {x}, outside its limits [{lo}, {hi}]"),
                        ));
                    }
                    q[j.q_index] = x;
                }
            }
        }
        // e.g. a zero base quaternion
        model.check_configuration(&q).map_err(|e| invalid(&self.origin(), format!("{what}: {e}")))?;
        Ok(q)
    }

    /// Load the kinematic model and the collision world ([`read`](Self::read) checks the
    /// files first): the self-collision pairs are those of the SRDF (with
    /// `merge_computed_pairs`, also the computed ones, [`allowed::disabled_pairs`] at the
    /// default configuration), or all pairs on different bodies without an SRDF.
    pub fn load(&self) -> Result<(Arc<KinematicModel>, CollisionWorld)> {
        let files = self.read()?;
        let curdf = files.collision_urdf.as_ref().unwrap_or(&files.urdf);
        let mut srdf = files.srdf.clone();
        if self.merge_computed_pairs {
            let all = CollisionWorld::from_urdf_with(files.model.clone(), curdf, &self.package_dirs, None, self.mesh_shape)?;
            let computed = allowed::disabled_pairs(&all, &files.q_default, &allowed::Options::default())?;
            srdf.get_or_insert_with(Srdf::default).disabled_pairs.extend(computed.into_iter().map(|p| (p.a, p.b)));
        }
        let world = CollisionWorld::from_urdf_with(files.model.clone(), curdf, &self.package_dirs, srdf.as_ref(), self.mesh_shape)?;
        Ok((files.model, world))
    }
}

/// A joint's neutral value, where the default configuration puts it and a locked joint that
/// nothing gives a value is held: 0, or the middle of its limits when 0 is outside them (as
/// MoveIt's default positions).
pub fn neutral_value(joint: &crate::urdf::Joint) -> f64 {
    if joint.lower <= 0.0 && 0.0 <= joint.upper {
        0.0
    } else {
        0.5 * joint.lower + 0.5 * joint.upper
    }
}

/// The free-flyer joint's name in SRDF group states (Pinocchio's).
pub const FREE_FLYER: &str = "root_joint";

/// A robot description's files, read and checked ([`RobotDescription::read`]).
#[derive(Debug, Clone)]
pub struct RobotFiles {
    /// The kinematic model (its active joints in Pinocchio's order; locked joints and the
    /// mimics of locked joints in [`KinematicModel::locked`]).
    pub model: Arc<KinematicModel>,
    /// The URDF.
    pub urdf: Urdf,
    /// The collision URDF when it is another file (of the same tree).
    pub collision_urdf: Option<Urdf>,
    /// The SRDF, if any.
    pub srdf: Option<Srdf>,
    /// The default configuration (length nq): the reference state's values, else the neutral
    /// configuration.
    pub q_default: Vec<f64>,
    /// What loads but may not be meant (see the module's documentation), one message each.
    pub warnings: Vec<String>,
}

/// An [`Error::UnknownName`] of a name read at `place`, listing the known names.
fn unknown_in(kind: &'static str, name: &str, known: &[&str], place: String) -> Error {
    let hint = match unknown(kind, name, known) {
        Error::UnknownName { hint, .. } => hint,
        _ => String::new(),
    };
    Error::UnknownName { kind, name: name.to_string(), hint: format!(" {place}{hint}") }
}

/// An error of building the model from the URDF `what`, for the robot file `origin`: an unknown
/// name is an error of the URDF, a refused value (locked, mimic) one of the robot file.
fn in_file(e: Error, origin: &str, what: &str) -> Error {
    match e {
        // what the URDF's joints name (links, joints) and it lacks: the URDF is at fault
        e @ Error::UnknownName { .. } => Error::Parse { what: what.to_string(), msg: e.to_string() },
        Error::Invalid(msg) => invalid(origin, msg),
        other => other,
    }
}

/// The first difference between the kinematic trees of two URDFs, if any: the links' names,
/// and each joint's type, parent, child, origin and axis (what places the links: a collision
/// URDF's limits and mimics are not used).
fn tree_difference(a: &Urdf, b: &Urdf) -> Option<String> {
    let (la, lb): (BTreeSet<&str>, BTreeSet<&str>) =
        (a.links.iter().map(|l| l.name.as_str()).collect(), b.links.iter().map(|l| l.name.as_str()).collect());
    if let Some(l) = la.symmetric_difference(&lb).next() {
        return Some(format!("link '{l}' is in one and not the other"));
    }
    for ja in &a.joints {
        let Some(jb) = b.joints.iter().find(|j| j.name == ja.name) else {
            return Some(format!("joint '{}' is in one and not the other", ja.name));
        };
        let what = if ja.joint_type != jb.joint_type {
            "type"
        } else if ja.parent != jb.parent || ja.child != jb.child {
            "parent or child"
        } else if (ja.origin.inverse() * jb.origin).translation.vector.norm() > 1e-9 || ja.origin.rotation.angle_to(&jb.origin.rotation) > 1e-9 {
            "<origin>"
        } else if (ja.axis - jb.axis).norm() > 1e-9 {
            "<axis>"
        } else {
            continue;
        };
        return Some(format!("joint '{}' has another {what}", ja.name));
    }
    b.joints.iter().find(|j| !a.joints.iter().any(|x| x.name == j.name)).map(|j| format!("joint '{}' is in one and not the other", j.name))
}

/// The folders genplan searches for `package://` URIs by default: example-robot-data's
/// `share/` folder ([`find_robots_dir`]'s grandparent).
pub fn default_package_dirs() -> Result<Vec<PathBuf>> {
    Ok(package_dirs_for(&find_robots_dir()?))
}

/// `package://example-robot-data/robots/x` resolves under `<robots>/../..`.
pub fn package_dirs_for(robots_root: &Path) -> Vec<PathBuf> {
    robots_root
        .parent()
        .and_then(Path::parent)
        .map(|p| vec![p.to_path_buf()])
        .unwrap_or_default()
}

/// The presets' robot files: `$GENPLAN_PRESETS_DIR/robots`, else the Python package's
/// `python/genplan/presets/robots` in this source tree (for cargo tests and benches).
pub fn presets_dir() -> PathBuf {
    match std::env::var("GENPLAN_PRESETS_DIR") {
        Ok(d) => PathBuf::from(d).join("robots"),
        Err(_) => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../python/genplan/presets/robots"),
    }
}

/// The names of the preset robot files in [`presets_dir`], sorted.
pub fn preset_names() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(presets_dir())
        .map(|rd| {
            rd.flatten()
                .filter_map(|e| {
                    let p = e.path();
                    (p.extension()? == "toml").then(|| p.file_stem()?.to_str().map(str::to_string))?
                })
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

/// A preset by name, read from [`presets_dir`] with [`default_package_dirs`]; an unknown name
/// gets an error listing the known ones.
pub fn preset(name: &str) -> Result<RobotDescription> {
    let names = preset_names();
    if !names.iter().any(|n| n == name) {
        let known: Vec<&str> = names.iter().map(String::as_str).collect();
        return Err(crate::error::unknown("robot", name, &known));
    }
    RobotDescription::from_file(presets_dir().join(format!("{name}.toml")), &default_package_dirs()?)
}

/// Find example-robot-data's `robots/` folder without Python: `$GENPLAN_ROBOTS_DIR`, else the
/// `cmeel.prefix` of a virtualenv `.venv` in the current folder or one of its ancestors.
pub fn find_robots_dir() -> Result<PathBuf> {
    if let Ok(dir) = std::env::var("GENPLAN_ROBOTS_DIR") {
        let p = PathBuf::from(&dir);
        return if p.is_dir() {
            Ok(p)
        } else {
            Err(Error::Invalid(format!("GENPLAN_ROBOTS_DIR={dir} is not a folder")))
        };
    }
    let cwd = std::env::current_dir().map_err(|source| Error::Io {
        path: PathBuf::from("."),
        source,
    })?;
    for dir in cwd.ancestors() {
        let lib = dir.join(".venv").join("lib");
        let Ok(entries) = std::fs::read_dir(&lib) else { continue };
        for e in entries.flatten() {
            let p = e
                .path()
                .join("site-packages/cmeel.prefix/share/example-robot-data/robots");
            if p.is_dir() {
                return Ok(p);
            }
        }
    }
    Err(Error::Invalid(
        "example-robot-data not found: set GENPLAN_ROBOTS_DIR to its robots/ folder \
         (pip install example-robot-data; see README)"
            .into(),
    ))
}

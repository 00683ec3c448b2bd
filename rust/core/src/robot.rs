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
//! locked_joints = ["finger_1"]    # optional: held at the reference state's value (or 0) ...
//! # locked_joints = { finger_1 = 0.04 }   # ... or at the given values
//! reference_state = "default"     # optional: an SRDF group_state
//! [frames]                        # optional: roles -> link names
//! hand = "panda_hand"
//! ```

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::collision::CollisionWorld;
use crate::error::{Error, Result};
use crate::kinematics::{KinematicModel, ModelOptions};
use crate::srdf::Srdf;
use crate::urdf::{resolve_uri, Urdf};

/// The keys a robot file may hold.
pub const ROBOT_KEYS: [&str; 9] = [
    "name",
    "urdf",
    "collision_urdf",
    "srdf",
    "package_dirs",
    "floating_base",
    "locked_joints",
    "reference_state",
    "frames",
];

/// Which joints are locked, and at what.
#[derive(Debug, Clone, PartialEq)]
pub enum LockedJoints {
    /// Held at their value in the reference state (0 where it says nothing).
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
    /// Named frames: (role, link name), in the file's order.
    pub frames: Vec<(String, String)>,
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
            Some(v) => LockedJoints::FromReference(strings(origin, "locked_joints", v).map_err(|_| {
                invalid(
                    origin,
                    format!("'locked_joints' must be a list of joint names or a table name = value, got {}", v.type_str()),
                )
            })?),
        };
        let reference_state = match get("reference_state") {
            Some(v) => Some(string(origin, "reference_state", v)?),
            None => None,
        };
        if reference_state.is_some() && srdf.is_none() {
            return Err(invalid(origin, "'reference_state' names an SRDF group state, but there is no 'srdf'".into()));
        }
        let mut frames = Vec::new();
        if let Some(v) = get("frames") {
            let t = v
                .as_table()
                .ok_or_else(|| invalid(origin, format!("'frames' must be a table role = link name, got {}", v.type_str())))?;
            for (role, link) in t {
                frames.push((role.clone(), string(origin, &format!("frames.{role}"), link)?));
            }
        }
        Ok(RobotDescription {
            name,
            urdf,
            collision_urdf,
            srdf,
            package_dirs,
            floating_base,
            locked_joints,
            reference_state,
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

    /// Locked joint values: given, or from the SRDF's reference state (0 where it says nothing).
    pub fn locked_values(&self, srdf: Option<&Srdf>) -> Result<HashMap<String, f64>> {
        Ok(match &self.locked_joints {
            LockedJoints::Values(v) => v.iter().cloned().collect(),
            LockedJoints::FromReference(names) => {
                let state = match (&self.reference_state, srdf) {
                    (Some(r), Some(s)) => Some(s.group_states.get(r).ok_or_else(|| {
                        let mut known: Vec<&str> = s.group_states.keys().map(String::as_str).collect();
                        known.sort_unstable();
                        invalid(
                            &self.origin(),
                            format!("reference_state '{r}' is not a group state of the SRDF (known: {})", known.join(", ")),
                        )
                    })?),
                    _ => None,
                };
                names
                    .iter()
                    .map(|j| {
                        let v = state.and_then(|s| s.get(j)).and_then(|v| v.first().copied()).unwrap_or(0.0);
                        (j.clone(), v)
                    })
                    .collect()
            }
        })
    }

    /// The kinematic model options this description asks for.
    pub fn model_options(&self, srdf: Option<&Srdf>) -> Result<ModelOptions> {
        Ok(ModelOptions {
            floating_base: self.floating_base,
            locked_joints: self.locked_values(srdf)?,
            joint_order: None,
        })
    }

    /// Load the kinematic model and the collision world (self-collision pairs from the SRDF,
    /// or all pairs on different bodies when there is none).
    pub fn load(&self) -> Result<(Arc<KinematicModel>, CollisionWorld)> {
        let srdf = self.read_srdf()?;
        let urdf = Urdf::from_file(&self.urdf)?;
        let model = Arc::new(KinematicModel::from_urdf(&urdf, &self.model_options(srdf.as_ref())?)?);
        for (role, link) in &self.frames {
            model.link_index(link).map_err(|e| invalid(&self.origin(), format!("frame '{role}': {e}")))?;
        }
        let curdf = if self.collision_urdf == self.urdf { urdf } else { Urdf::from_file(&self.collision_urdf)? };
        let world = CollisionWorld::from_urdf(model.clone(), &curdf, &self.package_dirs, srdf.as_ref())?;
        Ok((model, world))
    }
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

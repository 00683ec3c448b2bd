//! Robot presets: which files, which joints move, where the base is, which frames matter.
//!
//! These presets are the single definition of genplan's robots: the Python side reads them
//! (through `genplan._core.robot_spec`) to build the matching Pinocchio model, so Rust and
//! Pinocchio always describe the same robot.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::collision::CollisionWorld;
use crate::error::{unknown, Error, Result};
use crate::kinematics::{KinematicModel, ModelOptions};
use crate::srdf::Srdf;
use crate::urdf::Urdf;

/// A robot of example-robot-data, described relative to its `robots/` folder.
#[derive(Debug, Clone)]
pub struct RobotSpec {
    /// The preset's name (one of [`ROBOT_NAMES`]).
    pub name: &'static str,
    /// URDF for kinematics (relative to the `robots/` folder).
    pub urdf: &'static str,
    /// URDF whose `<collision>` elements are the collision model (same kinematic tree).
    pub collision_urdf: &'static str,
    /// SRDF: disabled collision pairs and the reference state (relative to the `robots/` folder).
    pub srdf: &'static str,
    /// The root joint is a free-flyer (q starts with [x, y, z, qx, qy, qz, qw]).
    pub floating_base: bool,
    /// Movable joints removed from q, held at their value in `reference_state` (or 0).
    pub locked_joints: &'static [&'static str],
    /// The SRDF group state that gives the default configuration and the locked values.
    pub reference_state: &'static str,
    /// Named frames: (role, link name).
    pub frames: &'static [(&'static str, &'static str)],
}

/// The names [`RobotSpec::by_name`] knows.
pub const ROBOT_NAMES: [&str; 3] = ["panda", "talos", "ur5"];

impl RobotSpec {
    /// The preset called `name`; an unknown name gets an error listing the known ones.
    pub fn by_name(name: &str) -> Result<RobotSpec> {
        Ok(match name {
            "panda" => RobotSpec {
                name: "panda",
                urdf: "panda_description/urdf/panda.urdf",
                collision_urdf: "panda_description/urdf/panda_collision.urdf",
                srdf: "panda_description/srdf/panda.srdf",
                floating_base: false,
                locked_joints: &["panda_finger_joint1", "panda_finger_joint2"],
                reference_state: "default",
                frames: &[("hand", "panda_hand"), ("tcp", "panda_hand_tcp")],
            },
            "talos" => RobotSpec {
                name: "talos",
                urdf: "talos_data/robots/talos_reduced.urdf",
                collision_urdf: "talos_data/robots/talos_reduced.urdf",
                srdf: "talos_data/srdf/talos.srdf",
                floating_base: true,
                locked_joints: &[
                    "head_1_joint",
                    "head_2_joint",
                    "gripper_left_joint",
                    "gripper_right_joint",
                ],
                reference_state: "half_sitting",
                frames: &[
                    ("left_sole", "left_sole_link"),
                    ("right_sole", "right_sole_link"),
                    ("right_hand", "gripper_right_base_link"),
                    ("left_hand", "gripper_left_base_link"),
                ],
            },
            "ur5" => RobotSpec {
                name: "ur5",
                urdf: "ur_description/urdf/ur5_robot.urdf",
                collision_urdf: "ur_description/urdf/ur5_robot.urdf",
                srdf: "ur_description/srdf/ur5.srdf",
                floating_base: false,
                locked_joints: &[],
                reference_state: "",
                frames: &[("tool", "tool0"), ("ee", "ee_link")],
            },
            other => return Err(unknown("robot", other, &ROBOT_NAMES)),
        })
    }

    /// Locked joint values from the SRDF's reference state (0 where it says nothing).
    pub fn locked_values(&self, srdf: &Srdf) -> HashMap<String, f64> {
        let state = srdf.group_states.get(self.reference_state);
        self.locked_joints
            .iter()
            .map(|&j| {
                let v = state
                    .and_then(|s| s.get(j))
                    .and_then(|v| v.first().copied())
                    .unwrap_or(0.0);
                (j.to_string(), v)
            })
            .collect()
    }

    /// Load the kinematic model and the collision world from the `robots/` folder `root`.
    /// The package dir for `package://example-robot-data/...` is two levels above it.
    pub fn load(&self, root: &Path) -> Result<(Arc<KinematicModel>, CollisionWorld)> {
        let package_dirs = package_dirs_for(root);
        let srdf = Srdf::from_file(root.join(self.srdf))?;
        let urdf = Urdf::from_file(root.join(self.urdf))?;
        let options = ModelOptions {
            floating_base: self.floating_base,
            locked_joints: self.locked_values(&srdf),
            joint_order: None,
        };
        let model = Arc::new(KinematicModel::from_urdf(&urdf, &options)?);
        let curdf = if self.collision_urdf == self.urdf {
            urdf
        } else {
            Urdf::from_file(root.join(self.collision_urdf))?
        };
        let world = CollisionWorld::from_urdf(model.clone(), &curdf, &package_dirs, Some(&srdf))?;
        Ok((model, world))
    }
}

/// `package://example-robot-data/robots/x` resolves under `<robots>/../..`.
pub fn package_dirs_for(robots_root: &Path) -> Vec<PathBuf> {
    robots_root
        .parent()
        .and_then(Path::parent)
        .map(|p| vec![p.to_path_buf()])
        .unwrap_or_default()
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

//! The parts of an SRDF that genplan uses: disabled collision pairs and named group states.
//!
//! A group state's values are joint positions: the reader refuses one that is not a number, not
//! finite (`NaN`, `inf`, `1e999`) or larger than [`MAX_JOINT_POSITION`] in magnitude, naming the
//! group state and the joint. A URDF given as an SRDF (a `<link>` or `<joint>` under `<robot>`)
//! is refused. Whether the names it holds are the URDF's is checked when a robot is read
//! ([`RobotDescription::read`](crate::robot::RobotDescription::read)).

use std::collections::HashMap;
use std::path::Path;

use crate::error::{Error, Result};
use crate::urdf::MAX_JOINT_POSITION;

/// A parsed SRDF file.
#[derive(Debug, Clone, Default)]
pub struct Srdf {
    /// Link pairs whose collisions are never checked (`<disable_collisions>`).
    pub disabled_pairs: Vec<(String, String)>,
    /// `<group_state name=...>`: joint name to its values (one value, or 7 for a free-flyer),
    /// each finite and at most [`MAX_JOINT_POSITION`] in magnitude.
    pub group_states: HashMap<String, HashMap<String, Vec<f64>>>,
}

impl Srdf {
    /// Parse SRDF text.
    pub fn parse(text: &str) -> Result<Srdf> {
        let err = |msg: String| Error::Parse {
            what: "SRDF".into(),
            msg,
        };
        let doc = roxmltree::Document::parse(text).map_err(|e| err(e.to_string()))?;
        let robot = doc.root_element();
        if robot.tag_name().name() != "robot" {
            return Err(err(format!(
                "root element is <{}>, not <robot>",
                robot.tag_name().name()
            )));
        }
        let mut out = Srdf::default();
        for node in robot.children().filter(|n| n.is_element()) {
            match node.tag_name().name() {
                "disable_collisions" => {
                    let (a, b) = (node.attribute("link1"), node.attribute("link2"));
                    match (a, b) {
                        (Some(a), Some(b)) => {
                            out.disabled_pairs.push((a.to_string(), b.to_string()))
                        }
                        _ => return Err(err("<disable_collisions> lacks link1 or link2".into())),
                    }
                }
                // an SRDF's root holds no links or joints: this is a URDF given as the SRDF
                tag @ ("link" | "joint") => {
                    return Err(err(format!("<robot> has a <{tag}> element: this is a URDF, not an SRDF")));
                }
                "group_state" => {
                    let name = node.attribute("name").unwrap_or("").to_string();
                    let mut joints = HashMap::new();
                    for j in node
                        .children()
                        .filter(|c| c.is_element() && c.tag_name().name() == "joint")
                    {
                        let jn = j.attribute("name").unwrap_or("").to_string();
                        let values: std::result::Result<Vec<f64>, _> = j
                            .attribute("value")
                            .unwrap_or("")
                            .split_whitespace()
                            .map(str::parse::<f64>)
                            .collect();
                        let values = values.map_err(|e| {
                            err(format!("group_state '{name}', joint '{jn}': {e}"))
                        })?;
                        if let Some(x) = values.iter().find(|x| !x.is_finite()) {
                            return Err(err(format!(
                                "group_state '{name}', joint '{jn}': value {x} is not finite"
                            )));
                        }
                        if let Some(x) = values.iter().find(|x| x.abs() > MAX_JOINT_POSITION) {
                            return Err(err(format!(
                                "group_state '{name}', joint '{jn}': value {x:e} is too large \
                                 (at most {MAX_JOINT_POSITION:e} in magnitude)"
                            )));
                        }
                        joints.insert(jn, values);
                    }
                    out.group_states.insert(name, joints);
                }
                _ => {}
            }
        }
        Ok(out)
    }

    /// Read and parse an SRDF file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Srdf> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Srdf::parse(&text).map_err(|e| match e {
            Error::Parse { msg, .. } => Error::Parse {
                what: format!("SRDF {}", path.display()),
                msg,
            },
            other => other,
        })
    }
}

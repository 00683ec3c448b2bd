//! Robot files and descriptions (`genplan_core::robot`): reading a robot file or its keys as a
//! dict, reading the files it names into a model, the SRDF's disabled pairs read and written.

use std::path::PathBuf;

use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use genplan_core::collision::allowed;
use genplan_core::robot::{LockedJoints, RobotDescription};
use genplan_core::srdf::Srdf;

use crate::collision::PyCollisionWorld;
use crate::errors::{err, to_py, Kind};
use crate::kinematics::PyKinematicModel;

/// A Python value (str, bool, int, float, list, dict) as a TOML value, for
/// [`RobotDescription::from_table`]; `key` names it in errors.
fn toml_value(v: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyList, PyString, PyTuple};
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(v.extract()?));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(toml_table(d, key)?));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = v.try_iter()?.collect::<PyResult<_>>()?;
        return items.iter().map(|x| toml_value(x, key)).collect::<PyResult<Vec<_>>>().map(toml::Value::Array);
    }
    if let Ok(p) = v.extract::<PathBuf>() {
        return Ok(toml::Value::String(p.to_string_lossy().into_owned()));
    }
    Err(pyo3::exceptions::PyTypeError::new_err(format!(
        "{key}: expected a string, number, boolean, list or dict, got {}",
        v.get_type().name()?
    )))
}

fn toml_table(d: &Bound<'_, PyDict>, key: &str) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let k: String = k.extract().map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err(format!("{key}: keys must be strings"))
        })?;
        if v.is_none() {
            continue;
        }
        let sub = if key.is_empty() { k.clone() } else { format!("{key}.{k}") };
        t.insert(k, toml_value(&v, &sub)?);
    }
    Ok(t)
}

fn description_to_py<'py>(py: Python<'py>, r: &RobotDescription) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("name", &r.name)?;
    d.set_item("urdf", &r.urdf)?;
    d.set_item("collision_urdf", &r.collision_urdf)?;
    d.set_item("srdf", &r.srdf)?;
    d.set_item("package_dirs", &r.package_dirs)?;
    d.set_item("floating_base", r.floating_base)?;
    match &r.locked_joints {
        LockedJoints::FromReference(names) => d.set_item("locked_joints", names)?,
        LockedJoints::Values(v) => d.set_item("locked_joints", v.iter().cloned().collect::<std::collections::BTreeMap<_, _>>())?,
    }
    d.set_item("reference_state", &r.reference_state)?;
    if r.merge_computed_pairs {
        // only when asked for: a description without it is the one it was before the key existed
        // (data sets and caches identify a robot by its description)
        d.set_item("merge_computed_pairs", true)?;
    }
    if r.mesh_shape != genplan_core::collision::MeshShape::Hull {
        // only when not the default, as merge_computed_pairs
        d.set_item("mesh_shape", r.mesh_shape.name())?;
    }
    let frames = PyDict::new(py);
    for (role, link) in &r.frames {
        frames.set_item(role, link)?;
    }
    d.set_item("frames", frames)?;
    if !r.attached.is_empty() {
        // only when given, as merge_computed_pairs
        let rows: Vec<Bound<'py, PyAny>> = r.attached.iter().map(|t| toml_to_py(py, &toml::Value::Table(t.clone()))).collect::<PyResult<_>>()?;
        d.set_item("attached", rows)?;
    }
    d.set_item("source", &r.source)?;
    Ok(d)
}

/// A TOML value as plain Python data (dict, list, str, int, float, bool; a date as its text).
fn toml_to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::IntoPyObjectExt;
    Ok(match v {
        toml::Value::String(s) => s.into_bound_py_any(py)?,
        toml::Value::Integer(i) => i.into_bound_py_any(py)?,
        toml::Value::Float(f) => f.into_bound_py_any(py)?,
        toml::Value::Boolean(b) => b.into_bound_py_any(py)?,
        toml::Value::Datetime(d) => d.to_string().into_bound_py_any(py)?,
        toml::Value::Array(a) => a.iter().map(|x| toml_to_py(py, x)).collect::<PyResult<Vec<_>>>()?.into_bound_py_any(py)?,
        toml::Value::Table(t) => {
            let d = PyDict::new(py);
            for (k, x) in t {
                d.set_item(k, toml_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// A description dict (as [`description_to_py`] makes it: absolute paths) back to Rust.
pub(crate) fn description_from_py(d: &Bound<'_, PyDict>) -> PyResult<RobotDescription> {
    let fields = d.copy()?;
    let source: Option<PathBuf> = match fields.get_item("source")? {
        Some(v) if !v.is_none() => Some(v.extract()?),
        _ => None,
    };
    if fields.contains("source")? {
        fields.del_item("source")?;
    }
    let name: String = fields.get_item("name")?.map(|v| v.extract()).transpose()?.unwrap_or_default();
    let table = toml_table(&fields, "")?;
    let origin = source.as_ref().map(|p| format!("robot file {}", p.display())).unwrap_or_else(|| format!("robot '{name}'"));
    let mut r = RobotDescription::from_table(&table, None, &[], &origin, &name).map_err(to_py)?;
    r.source = source;
    Ok(r)
}

/// Read a robot file (TOML): its description as a dict with absolute paths
/// (`genplan_core::robot::RobotDescription`). `package_dirs` are searched after the file's own.
#[pyfunction]
fn read_robot_file<'py>(py: Python<'py>, path: PathBuf, package_dirs: Vec<PathBuf>) -> PyResult<Bound<'py, PyDict>> {
    let r = RobotDescription::from_file(&path, &package_dirs).map_err(to_py)?;
    description_to_py(py, &r)
}

/// A robot description from the keys of a robot file given as a dict (relative paths against
/// `base_dir`); `origin` names the input in errors, `default_name` is used without `name`.
#[pyfunction]
#[pyo3(signature = (fields, package_dirs, origin, default_name, base_dir=None))]
fn robot_description<'py>(
    py: Python<'py>,
    fields: &Bound<'py, PyDict>,
    package_dirs: Vec<PathBuf>,
    origin: &str,
    default_name: &str,
    base_dir: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let table = toml_table(fields, "")?;
    let r = RobotDescription::from_table(&table, base_dir.as_deref(), &package_dirs, origin, default_name).map_err(to_py)?;
    description_to_py(py, &r)
}

/// What [`read_robot`] gives: (model, default configuration, locked values, warnings).
type RobotRead<'py> = (PyKinematicModel, Bound<'py, numpy::PyArray1<f64>>, Bound<'py, PyDict>, Vec<String>);

/// Read a robot description's files and check it against them
/// (`genplan_core::robot::RobotDescription::read`), before Pinocchio reads them: the kinematic
/// model (active joints in Pinocchio's order), the default configuration (nq), the locked
/// values (the mimics of locked joints included) and the warnings (messages). Every error
/// names the file and the name or value at fault.
#[pyfunction]
fn read_robot<'py>(py: Python<'py>, description: &Bound<'py, PyDict>) -> PyResult<RobotRead<'py>> {
    let r = description_from_py(description)?;
    let files = py.detach(|| r.read()).map_err(to_py)?;
    let locked = PyDict::new(py);
    for (name, value) in &files.model.locked {
        locked.set_item(name, value)?;
    }
    Ok((PyKinematicModel { inner: files.model }, files.q_default.into_pyarray(py), locked, files.warnings))
}

/// The `<disable_collisions>` link pairs of an SRDF file.
#[pyfunction]
fn srdf_disabled_pairs(path: PathBuf) -> PyResult<Vec<(String, String)>> {
    Ok(Srdf::from_file(&path).map_err(to_py)?.disabled_pairs)
}

/// SRDF text holding `pairs` (link_a, link_b, reason) as `<disable_collisions>` and, if given,
/// the group state "default" (joint name, value).
#[pyfunction]
#[pyo3(signature = (robot_name, pairs, default_state=None))]
fn disabled_pairs_srdf(
    robot_name: &str,
    pairs: Vec<(String, String, String)>,
    default_state: Option<Vec<(String, f64)>>,
) -> PyResult<String> {
    let pairs = pairs
        .into_iter()
        .map(|(a, b, r)| {
            let reason = allowed::Reason::parse(&r).ok_or_else(|| {
                let known: Vec<&str> = allowed::Reason::ALL.iter().map(|r| r.as_str()).collect();
                err(Kind::UnknownName, format!("pairs: unknown reason '{r}' (known: {})", known.join(", ")))
            })?;
            Ok(allowed::DisabledPair { a, b, reason })
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok(allowed::srdf_text(robot_name, &pairs, default_state.as_deref()))
}

/// Load a robot file with the Rust core alone: (KinematicModel, CollisionWorld) (for tests).
#[pyfunction]
fn load_robot(py: Python<'_>, path: PathBuf, package_dirs: Vec<PathBuf>) -> PyResult<(PyKinematicModel, PyCollisionWorld)> {
    let (model, world) = py
        .detach(|| RobotDescription::from_file(&path, &package_dirs).and_then(|r| r.load()))
        .map_err(to_py)?;
    Ok((PyKinematicModel { inner: model }, PyCollisionWorld { inner: std::sync::Arc::new(world) }))
}

/// Register the robot-file functions on `genplan._core`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_robot_file, m)?)?;
    m.add_function(wrap_pyfunction!(robot_description, m)?)?;
    m.add_function(wrap_pyfunction!(read_robot, m)?)?;
    m.add_function(wrap_pyfunction!(load_robot, m)?)?;
    m.add_function(wrap_pyfunction!(srdf_disabled_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(disabled_pairs_srdf, m)?)
}

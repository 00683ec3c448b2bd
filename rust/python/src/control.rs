//! Bindings of `genplan_core::dynamics` and `genplan_core::control` (issue [controller]).
//!
//! * `Dynamics`: rigid-body dynamics of a fixed-base arm (mass matrix, bias forces, RNEA,
//!   forward dynamics, frame Jacobians and their time derivative), for cross-checks and users;
//! * `SpatulaSimulation`: the 1 kHz spatula controller + plant + pancake; `run` executes a whole
//!   trajectory in Rust with the GIL released and returns the log as numpy arrays;
//! * `pancake_phi`: eq. 16 as the loop computes it (cross-checked against the Python function).

use std::path::PathBuf;

use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use numpy::ndarray::{Array, Array1, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use genplan_core::control::{self, percentile, Disturbances, SimConfig, Simulation};
use genplan_core::dynamics::{Dynamics, Frame};
use genplan_core::urdf::Urdf;
use genplan_core::kinematics::ModelOptions;

use crate::to_py;

/// A (position (3,), rotation (3, 3)) pair of numpy arrays.
type PyPose<'py> = (Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>);

fn array<'py>(py: Python<'py>, shape: &[usize], data: Vec<f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    Ok(Array::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py))
}

fn dmatrix<'py>(py: Python<'py>, m: &DMatrix<f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let (r, c) = m.shape();
    array(py, &[r, c], (0..r).flat_map(|i| (0..c).map(move |k| m[(i, k)])).collect())
}

/// A 1-D float64 vector of length n from a numpy array.
fn vector(arr: &PyReadonlyArrayDyn<'_, f64>, n: usize, what: &str) -> PyResult<Vec<f64>> {
    if arr.shape() != [n] {
        return Err(crate::err(crate::Kind::Shape, format!("{what}: expected shape ({n},), got {:?}", arr.shape())));
    }
    Ok(arr.as_array().iter().copied().collect())
}

fn placement(offset: Option<[[f64; 4]; 4]>) -> PyResult<Isometry3<f64>> {
    match offset {
        None => Ok(Isometry3::identity()),
        Some(t) => {
            let r = Matrix3::from_fn(|i, j| t[i][j]);
            let err = (r.transpose() * r - Matrix3::identity()).amax();
            if !err.is_finite() || err > 1e-9 || (r.determinant() - 1.0).abs() > 1e-9 {
                return Err(crate::err(crate::Kind::Settings, "offset: the 3x3 block is not a rotation matrix"));
            }
            Ok(Isometry3::from_parts(
                Translation3::new(t[0][3], t[1][3], t[2][3]),
                UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r)),
            ))
        }
    }
}

/// Rigid-body dynamics of a fixed-base arm (q in Pinocchio's convention and joint order).
#[pyclass(name = "Dynamics", module = "genplan._core")]
pub(crate) struct PyDynamics {
    inner: Dynamics,
}

impl PyDynamics {
    fn frame(&self, link: &str, offset: Option<[[f64; 4]; 4]>) -> PyResult<Frame> {
        self.inner.frame(link, &placement(offset)?).map_err(to_py)
    }
}

#[pymethods]
impl PyDynamics {
    /// A fixed-base robot from its description (`genplan.Robot.description`: the dict of
    /// `read_robot_file` / `robot_description`).
    #[staticmethod]
    fn from_description(description: &Bound<'_, PyDict>) -> PyResult<Self> {
        let robot = crate::description_from_py(description)?;
        Ok(Self { inner: Dynamics::from_description(&robot).map_err(to_py)? })
    }

    /// From a URDF file (fixed base), optionally with locked joints.
    #[staticmethod]
    #[pyo3(signature = (urdf_path, locked_joints=None))]
    fn from_urdf(urdf_path: PathBuf, locked_joints: Option<std::collections::HashMap<String, f64>>) -> PyResult<Self> {
        let urdf = Urdf::from_file(&urdf_path).map_err(to_py)?;
        let options = ModelOptions { floating_base: false, locked_joints: locked_joints.unwrap_or_default(), joint_order: None };
        Ok(Self { inner: Dynamics::from_urdf(&urdf, &options).map_err(to_py)? })
    }

    #[getter]
    fn nq(&self) -> usize {
        self.inner.nq
    }
    #[getter]
    fn nv(&self) -> usize {
        self.inner.nv
    }
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.joint_names.clone()
    }
    #[getter]
    fn get_gravity(&self) -> [f64; 3] {
        self.inner.gravity.into()
    }
    #[setter]
    fn set_gravity(&mut self, g: [f64; 3]) -> PyResult<()> {
        genplan_core::error::check_finite("gravity", &g).map_err(to_py)?;
        self.inner.gravity = Vector3::from(g);
        Ok(())
    }
    /// Total mass of the moving bodies (kg).
    #[getter]
    fn moving_mass(&self) -> f64 {
        self.inner.moving_mass()
    }

    /// Add a rigid body to the link's body: mass, centre of mass and inertia about it, in the
    /// axes of the link frame moved by `offset` (4x4).
    #[pyo3(signature = (link, mass, com, inertia, offset=None))]
    fn add_inertia(&mut self, link: &str, mass: f64, com: [f64; 3], inertia: [[f64; 3]; 3], offset: Option<[[f64; 4]; 4]>) -> PyResult<()> {
        let f = self.frame(link, offset)?;
        self.inner
            .add_inertia(&f, mass, Vector3::from(com), Matrix3::from_fn(|i, j| inertia[i][j]))
            .map_err(to_py)
    }

    /// M(q), (nv, nv).
    fn mass_matrix<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let q = vector(&q, self.inner.nq, "q")?;
        let mut ws = self.inner.workspace();
        let mut m = DMatrix::zeros(self.inner.nv, self.inner.nv);
        self.inner.mass_matrix(&q, &mut ws, &mut m).map_err(to_py)?;
        dmatrix(py, &m)
    }

    /// C(q, v) v + g(q), (nv,) (Pinocchio's nonLinearEffects).
    fn nonlinear_effects<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>, v: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (q, v) = (vector(&q, self.inner.nq, "q")?, vector(&v, self.inner.nv, "v")?);
        let mut ws = self.inner.workspace();
        let mut out = vec![0.0; self.inner.nv];
        self.inner.nonlinear_effects(&q, &v, &mut ws, &mut out).map_err(to_py)?;
        array(py, &[out.len()], out)
    }

    /// g(q), (nv,).
    fn gravity_torque<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let q = vector(&q, self.inner.nq, "q")?;
        let mut ws = self.inner.workspace();
        let mut out = vec![0.0; self.inner.nv];
        self.inner.gravity_torque(&q, &mut ws, &mut out).map_err(to_py)?;
        array(py, &[out.len()], out)
    }

    /// tau = M a + C v + g, (nv,).
    fn rnea<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>, v: PyReadonlyArrayDyn<'py, f64>, a: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let nv = self.inner.nv;
        let (q, v, a) = (vector(&q, self.inner.nq, "q")?, vector(&v, nv, "v")?, vector(&a, nv, "a")?);
        let mut ws = self.inner.workspace();
        let mut out = vec![0.0; nv];
        self.inner.rnea(&q, &v, &a, &mut ws, &mut out).map_err(to_py)?;
        array(py, &[nv], out)
    }

    /// qdd = M^-1 (tau - C v - g), (nv,).
    fn forward_dynamics<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>, v: PyReadonlyArrayDyn<'py, f64>, tau: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let nv = self.inner.nv;
        let (q, v, tau) = (vector(&q, self.inner.nq, "q")?, vector(&v, nv, "v")?, vector(&tau, nv, "tau")?);
        let mut ws = self.inner.workspace();
        let mut out = vec![0.0; nv];
        self.inner.forward_dynamics(&q, &v, &tau, &mut ws, &mut out).map_err(to_py)?;
        array(py, &[nv], out)
    }

    /// World placement (4x4) of a link frame (moved by `offset`).
    #[pyo3(signature = (q, link, offset=None))]
    fn frame_placement<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>, link: &str, offset: Option<[[f64; 4]; 4]>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let q = vector(&q, self.inner.nq, "q")?;
        let f = self.frame(link, offset)?;
        self.inner.check_state(&q, None).map_err(to_py)?;
        let mut ws = self.inner.workspace();
        self.inner.update_kinematics_unchecked(&q, None, &mut ws);
        let h = self.inner.frame_isometry(&f, &ws).to_homogeneous();
        array(py, &[4, 4], (0..4).flat_map(|i| (0..4).map(move |k| h[(i, k)])).collect())
    }

    /// Jacobian (6, nv) of a link frame, LOCAL_WORLD_ALIGNED (rows [v; w]).
    #[pyo3(signature = (q, link, offset=None))]
    fn frame_jacobian<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>, link: &str, offset: Option<[[f64; 4]; 4]>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let q = vector(&q, self.inner.nq, "q")?;
        let f = self.frame(link, offset)?;
        let mut ws = self.inner.workspace();
        let mut j = DMatrix::zeros(6, self.inner.nv);
        self.inner.frame_jacobian(&q, &f, &mut ws, &mut j).map_err(to_py)?;
        dmatrix(py, &j)
    }

    /// d/dt of the LOCAL_WORLD_ALIGNED Jacobian at (q, v), (6, nv).
    #[pyo3(signature = (q, v, link, offset=None))]
    fn frame_jacobian_time_variation<'py>(&self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>, v: PyReadonlyArrayDyn<'py, f64>, link: &str, offset: Option<[[f64; 4]; 4]>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (q, v) = (vector(&q, self.inner.nq, "q")?, vector(&v, self.inner.nv, "v")?);
        let f = self.frame(link, offset)?;
        let mut ws = self.inner.workspace();
        let mut j = DMatrix::zeros(6, self.inner.nv);
        self.inner.frame_jacobian_time_variation(&q, &v, &f, &mut ws, &mut j).map_err(to_py)?;
        dmatrix(py, &j)
    }

    /// (kinetic, potential) energy at (q, v).
    fn energy(&self, q: PyReadonlyArrayDyn<'_, f64>, v: PyReadonlyArrayDyn<'_, f64>) -> PyResult<(f64, f64)> {
        let (q, v) = (vector(&q, self.inner.nq, "q")?, vector(&v, self.inner.nv, "v")?);
        self.inner.check_state(&q, Some(&v)).map_err(to_py)?;
        let mut ws = self.inner.workspace();
        self.inner.update_kinematics_unchecked(&q, Some(&v), &mut ws);
        Ok((self.inner.kinetic_energy_from_kinematics(&ws), self.inner.potential_energy_from_kinematics(&ws)))
    }

    fn __repr__(&self) -> String {
        format!(
            "Dynamics(nq={}, nv={}, bodies={}, moving_mass={:.3} kg)",
            self.inner.nq,
            self.inner.nv,
            self.inner.n_bodies(),
            self.inner.moving_mass()
        )
    }
}

// ---------------------------------------------------------------------------------------------
// configuration from nested dicts (unknown keys are errors, so typos do not pass silently)
// ---------------------------------------------------------------------------------------------

fn check_keys(d: &Bound<'_, PyDict>, allowed: &[&str], what: &str) -> PyResult<()> {
    for k in d.keys() {
        let k: String = k.extract().map_err(|_| crate::err(crate::Kind::Settings, format!("{what}: keys must be strings")))?;
        if !allowed.contains(&k.as_str()) {
            return Err(crate::err(crate::Kind::Settings, format!("{what}: unknown key '{k}' (known: {})", allowed.join(", "))));
        }
    }
    Ok(())
}

fn sub<'py>(d: &Bound<'py, PyDict>, key: &str) -> PyResult<Option<Bound<'py, PyDict>>> {
    match d.get_item(key)? {
        None => Ok(None),
        Some(v) if v.is_none() => Ok(None),
        Some(v) => Ok(Some(v.cast_into::<PyDict>().map_err(|_| crate::err(crate::Kind::Settings, format!("config: '{key}' must be a dict")))?)),
    }
}

fn config_from_dict(nv: usize, d: Option<Bound<'_, PyDict>>) -> PyResult<SimConfig> {
    let mut c = SimConfig::new(nv);
    let Some(d) = d else { return Ok(c) };
    check_keys(&d, &["controller", "disturbances", "setup", "pancake", "substeps", "settle_ticks", "limits"], "config")?;
    c.substeps = crate::get_or(&d, "substeps", c.substeps, "config")?;
    c.settle_ticks = crate::get_or(&d, "settle_ticks", c.settle_ticks, "config")?;
    if let Some(x) = sub(&d, "controller")? {
        let w = "config.controller";
        check_keys(&x, &["kpp", "kpr", "kvp", "kvr", "dt", "dob", "dob_cutoff_hz", "model_compensation", "velocity_feedforward", "acceleration_feedforward", "singular_det", "max_damping", "torque_limit"], w)?;
        let k = &mut c.controller;
        k.gains.kpp = crate::get_or(&x, "kpp", k.gains.kpp, w)?;
        k.gains.kpr = crate::get_or(&x, "kpr", k.gains.kpr, w)?;
        k.gains.kvp = crate::get_or(&x, "kvp", k.gains.kvp, w)?;
        k.gains.kvr = crate::get_or(&x, "kvr", k.gains.kvr, w)?;
        k.dt = crate::get_or(&x, "dt", k.dt, w)?;
        k.dob = crate::get_or(&x, "dob", k.dob, w)?;
        k.dob_cutoff_hz = crate::get_or(&x, "dob_cutoff_hz", k.dob_cutoff_hz, w)?;
        k.model_compensation = crate::get_or(&x, "model_compensation", k.model_compensation, w)?;
        k.velocity_feedforward = crate::get_or(&x, "velocity_feedforward", k.velocity_feedforward, w)?;
        k.acceleration_feedforward = crate::get_or(&x, "acceleration_feedforward", k.acceleration_feedforward, w)?;
        k.singular_det = crate::get_or(&x, "singular_det", k.singular_det, w)?;
        k.max_damping = crate::get_or(&x, "max_damping", k.max_damping, w)?;
        k.torque_limit = crate::get_or(&x, "torque_limit", k.torque_limit.clone(), w)?;
    }
    if let Some(x) = sub(&d, "disturbances")? {
        let w = "config.disturbances";
        check_keys(&x, &["coulomb", "viscous", "friction_velocity", "offset", "payload_mass", "payload_com"], w)?;
        let k = &mut c.disturbances;
        k.coulomb = crate::get_or(&x, "coulomb", k.coulomb.clone(), w)?;
        k.viscous = crate::get_or(&x, "viscous", k.viscous.clone(), w)?;
        k.friction_velocity = crate::get_or(&x, "friction_velocity", k.friction_velocity, w)?;
        k.offset = crate::get_or(&x, "offset", k.offset.clone(), w)?;
        k.payload_mass = crate::get_or(&x, "payload_mass", k.payload_mass, w)?;
        k.payload_com = crate::get_or(&x, "payload_com", k.payload_com, w)?;
    }
    if let Some(x) = sub(&d, "setup")? {
        let w = "config.setup";
        check_keys(&x, &["tool_link", "spatula_length", "spatula_mass", "spatula_com", "origin", "attitude", "q_seed"], w)?;
        let k = &mut c.setup;
        k.tool_link = crate::get_or(&x, "tool_link", k.tool_link.clone(), w)?;
        k.spatula_length = crate::get_or(&x, "spatula_length", k.spatula_length, w)?;
        k.spatula_mass = crate::get_or(&x, "spatula_mass", k.spatula_mass, w)?;
        k.spatula_com = crate::get_or(&x, "spatula_com", k.spatula_com, w)?;
        k.origin = crate::get_or(&x, "origin", k.origin, w)?;
        k.attitude = crate::get_or(&x, "attitude", k.attitude, w)?;
        k.q_seed = crate::get_or(&x, "q_seed", k.q_seed.clone(), w)?;
    }
    if let Some(x) = sub(&d, "pancake")? {
        let w = "config.pancake";
        check_keys(&x, &["mu_static", "mu_kinetic", "blade_half_length"], w)?;
        let k = &mut c.pancake;
        k.mu_static = crate::get_or(&x, "mu_static", k.mu_static, w)?;
        k.mu_kinetic = crate::get_or(&x, "mu_kinetic", k.mu_kinetic, w)?;
        k.blade_half_length = crate::get_or(&x, "blade_half_length", k.blade_half_length, w)?;
    }
    if let Some(x) = sub(&d, "limits")? {
        let w = "config.limits";
        check_keys(&x, &["torque", "velocity"], w)?;
        let k = &mut c.limits;
        k.torque = crate::get_or(&x, "torque", k.torque.clone(), w)?;
        k.velocity = crate::get_or(&x, "velocity", k.velocity.clone(), w)?;
    }
    Ok(c)
}

/// The torque and speed limits `(torque, velocity)` as a dict of lists.
fn limits_dict<'py>(py: Python<'py>, torque: Option<&[f64]>, velocity: Option<&[f64]>) -> PyResult<Bound<'py, PyDict>> {
    let k = PyDict::new(py);
    k.set_item("torque", torque.map(<[f64]>::to_vec))?;
    k.set_item("velocity", velocity.map(<[f64]>::to_vec))?;
    Ok(k)
}

fn config_to_dict<'py>(py: Python<'py>, c: &SimConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let k = PyDict::new(py);
    let cc = &c.controller;
    k.set_item("kpp", cc.gains.kpp)?;
    k.set_item("kpr", cc.gains.kpr)?;
    k.set_item("kvp", cc.gains.kvp)?;
    k.set_item("kvr", cc.gains.kvr)?;
    k.set_item("dt", cc.dt)?;
    k.set_item("dob", cc.dob)?;
    k.set_item("dob_cutoff_hz", cc.dob_cutoff_hz)?;
    k.set_item("model_compensation", cc.model_compensation)?;
    k.set_item("velocity_feedforward", cc.velocity_feedforward)?;
    k.set_item("acceleration_feedforward", cc.acceleration_feedforward)?;
    k.set_item("singular_det", cc.singular_det)?;
    k.set_item("max_damping", cc.max_damping)?;
    k.set_item("torque_limit", cc.torque_limit.clone())?;
    d.set_item("controller", k)?;
    let k = PyDict::new(py);
    let dd = &c.disturbances;
    k.set_item("coulomb", dd.coulomb.clone())?;
    k.set_item("viscous", dd.viscous.clone())?;
    k.set_item("friction_velocity", dd.friction_velocity)?;
    k.set_item("offset", dd.offset.clone())?;
    k.set_item("payload_mass", dd.payload_mass)?;
    k.set_item("payload_com", dd.payload_com.to_vec())?;
    d.set_item("disturbances", k)?;
    let k = PyDict::new(py);
    let s = &c.setup;
    k.set_item("tool_link", s.tool_link.clone())?;
    k.set_item("spatula_length", s.spatula_length)?;
    k.set_item("spatula_mass", s.spatula_mass)?;
    k.set_item("spatula_com", s.spatula_com)?;
    k.set_item("origin", s.origin.to_vec())?;
    k.set_item("attitude", s.attitude.to_vec())?;
    k.set_item("q_seed", s.q_seed.clone())?;
    d.set_item("setup", k)?;
    let k = PyDict::new(py);
    k.set_item("mu_static", c.pancake.mu_static)?;
    k.set_item("mu_kinetic", c.pancake.mu_kinetic)?;
    k.set_item("blade_half_length", c.pancake.blade_half_length)?;
    d.set_item("pancake", k)?;
    d.set_item("substeps", c.substeps)?;
    d.set_item("settle_ticks", c.settle_ticks)?;
    d.set_item("limits", limits_dict(py, c.limits.torque.as_deref(), c.limits.velocity.as_deref())?)?;
    Ok(d)
}

/// The default configuration (nested dict) and the reference disturbances of the benchmark.
#[pyfunction]
fn spatula_defaults<'py>(py: Python<'py>) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let mut c = SimConfig::new(6);
    let defaults = config_to_dict(py, &c)?;
    c.disturbances = Disturbances::reference();
    let reference = config_to_dict(py, &c)?.get_item("disturbances")?.ok_or_else(|| PyValueError::new_err("internal"))?;
    Ok((defaults, reference.cast_into::<PyDict>()?))
}

/// The 1 kHz spatula controller of the seq2seq paper on a simulated arm, with the pancake.
#[pyclass(name = "SpatulaSimulation", module = "genplan._core")]
pub(crate) struct PySpatulaSimulation {
    inner: Simulation,
}

#[pymethods]
impl PySpatulaSimulation {
    /// `robot`: a fixed-base 6-joint robot's description (`genplan.Robot.description`, e.g. the
    /// "ur5" preset's); `config`: nested dict of overrides (see `spatula_defaults()`).
    #[new]
    #[pyo3(signature = (robot, config=None))]
    fn new(robot: &Bound<'_, PyDict>, config: Option<Bound<'_, PyDict>>) -> PyResult<Self> {
        let robot = crate::description_from_py(robot)?;
        let arm = Dynamics::from_description(&robot).map_err(to_py)?;
        let cfg = config_from_dict(arm.nv, config)?;
        Ok(Self { inner: Simulation::new(&arm, cfg).map_err(to_py)? })
    }

    /// The configuration in use (nested dict).
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        config_to_dict(py, &self.inner.config())
    }

    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.nominal.joint_names.clone()
    }

    /// The joint limits every tick is checked against: {"torque": [...], "velocity": [...]}
    /// (the configuration's, else the robot model's URDF limits).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (torque, velocity) = self.inner.limits();
        limits_dict(py, Some(torque), Some(velocity))
    }

    /// Command pose (position (3,), rotation (3, 3)) of a paper pose [y, z, theta] (eq. 23).
    fn command_pose<'py>(&self, py: Python<'py>, p: [f64; 3]) -> PyResult<PyPose<'py>> {
        genplan_core::error::check_finite("p", &p).map_err(to_py)?;
        let (pos, r) = self.inner.command_pose(p);
        Ok((array(py, &[3], pos.as_slice().to_vec())?, dmatrix(py, &DMatrix::from_iterator(3, 3, r.iter().copied()))?))
    }

    /// World pose of the spatula frame at q: (position (3,), rotation (3, 3)).
    fn spatula_pose<'py>(&mut self, py: Python<'py>, q: PyReadonlyArrayDyn<'py, f64>) -> PyResult<PyPose<'py>> {
        let q = vector(&q, 6, "q")?;
        let (pos, r) = self.inner.spatula_pose(&q).map_err(to_py)?;
        Ok((array(py, &[3], pos.as_slice().to_vec())?, dmatrix(py, &DMatrix::from_iterator(3, 3, r.iter().copied()))?))
    }

    /// Check a trajectory (K, 3) as `run` does and return the initial configuration (nq,):
    /// raises ValueError naming the first bad or unreachable row.
    fn check_trajectory<'py>(&mut self, py: Python<'py>, trajectory: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let traj = trajectory_rows(&trajectory)?;
        let sim = &mut self.inner;
        let (_, q0) = py.detach(|| sim.prepare(&traj)).map_err(to_py)?;
        array(py, &[q0.len()], q0)
    }

    /// Execute a trajectory (K, 3) of [y, z, theta] rows at dt. `motion_len`: rows of the motion
    /// proper (the rest is a tail; slip and phi verdicts cover the motion). `paced`: tick on the
    /// wall clock. `stop_at_limit`: end the run at the first tick over a joint limit. Returns a
    /// dict of numpy arrays and a 'summary' dict (its 'limit_violation': the first tick over a
    /// limit, or None). The loop runs in Rust without the GIL.
    #[pyo3(signature = (trajectory, motion_len=None, paced=false, stop_at_limit=false))]
    fn run<'py>(&mut self, py: Python<'py>, trajectory: PyReadonlyArrayDyn<'py, f64>, motion_len: Option<usize>, paced: bool, stop_at_limit: bool) -> PyResult<Bound<'py, PyDict>> {
        let traj = trajectory_rows(&trajectory)?;
        let sim = &mut self.inner;
        // Ctrl-C: the loop asks every few hundred ticks; the pending exception is raised as is
        let mut interrupt: Option<PyErr> = None;
        let result = py.detach(|| {
            sim.run_with(&traj, motion_len, paced, stop_at_limit, &mut || match Python::attach(|py| py.check_signals()) {
                Ok(()) => false,
                Err(e) => {
                    interrupt = Some(e);
                    true
                }
            })
        });
        if let Some(e) = interrupt {
            return Err(e);
        }
        let run = result.map_err(to_py)?;
        let log = run.log;
        let (n, nv) = (log.n, log.nv);
        let d = PyDict::new(py);
        d.set_item("t", array(py, &[n], log.t)?)?;
        d.set_item("p_cmd", array(py, &[n, 3], log.paper_cmd)?)?;
        d.set_item("p", array(py, &[n, 3], log.paper)?)?;
        d.set_item("position_cmd", array(py, &[n, 3], log.pos_cmd)?)?;
        d.set_item("position", array(py, &[n, 3], log.pos)?)?;
        d.set_item("rotation", array(py, &[n, 3, 3], log.rot)?)?;
        d.set_item("error_position", array(py, &[n], log.err_pos)?)?;
        d.set_item("error_rotation", array(py, &[n], log.err_rot)?)?;
        d.set_item("q", array(py, &[n, nv], log.q)?)?;
        d.set_item("v", array(py, &[n, nv], log.v)?)?;
        d.set_item("tau", array(py, &[n, nv], log.tau)?)?;
        d.set_item("tau_dis_hat", array(py, &[n, nv], log.tau_dis_hat)?)?;
        d.set_item("tau_dis", array(py, &[n, nv], log.tau_dis)?)?;
        d.set_item("acceleration", array(py, &[n, 6], log.acc)?)?;
        d.set_item("phi", array(py, &[n], log.phi)?)?;
        d.set_item("slide", array(py, &[n], log.slide)?)?;
        d.set_item("normal", array(py, &[n], log.normal)?)?;
        d.set_item("pancake_mode", Array1::from_vec(log.pancake_mode).into_pyarray(py))?;
        d.set_item("damped", Array1::from_vec(log.damped).into_pyarray(py))?;
        d.set_item("det_j", array(py, &[n], log.det_j)?)?;
        d.set_item("motion_start", run.motion_start)?;
        d.set_item("motion_end", run.motion_end)?;
        let s = &run.summary;
        let sd = PyDict::new(py);
        sd.set_item("ticks", s.ticks)?;
        sd.set_item("us_per_tick", s.us_per_tick)?;
        sd.set_item("max_error_position", s.max_err_pos)?;
        sd.set_item("max_error_rotation", s.max_err_rot)?;
        sd.set_item("rms_error_position", s.rms_err_pos)?;
        sd.set_item("rms_error_rotation", s.rms_err_rot)?;
        sd.set_item("max_abs_phi", s.max_abs_phi)?;
        sd.set_item("slipped", s.slipped)?;
        sd.set_item("first_slip_time", s.first_slip_time)?;
        sd.set_item("left_time", s.left_time)?;
        sd.set_item("max_abs_slide", s.max_abs_slide)?;
        sd.set_item("damped_ticks", s.damped_ticks)?;
        sd.set_item("first_damped_time", s.first_damped_time)?;
        sd.set_item("min_abs_det_j", s.min_abs_det_j)?;
        sd.set_item("saturated_ticks", s.saturated_ticks)?;
        sd.set_item("max_abs_tau", s.max_abs_tau.clone())?;
        sd.set_item("max_abs_v", s.max_abs_v.clone())?;
        sd.set_item("limit_ticks", s.limit_ticks)?;
        sd.set_item("stopped_at_limit", s.stopped_at_limit)?;
        let violation = match &s.limit_violation {
            None => None,
            Some(v) => {
                let vd = PyDict::new(py);
                vd.set_item("time", v.time)?;
                vd.set_item("tick", v.tick)?;
                vd.set_item("joint", &self.inner.nominal.joint_names[v.joint])?;
                vd.set_item("quantity", v.quantity())?;
                vd.set_item("value", v.value)?;
                vd.set_item("limit", v.limit)?;
                vd.set_item("unit", v.unit)?;
                vd.set_item("message", v.describe(&self.inner.nominal.joint_names))?;
                Some(vd)
            }
        };
        sd.set_item("limit_violation", violation)?;
        if paced {
            let j = PyDict::new(py);
            for (name, xs) in [("lateness", &log.lateness), ("compute", &log.compute)] {
                j.set_item(format!("{name}_p50_us"), percentile(xs, 50.0) * 1e6)?;
                j.set_item(format!("{name}_p99_us"), percentile(xs, 99.0) * 1e6)?;
                j.set_item(format!("{name}_max_us"), xs.iter().copied().fold(0.0, f64::max) * 1e6)?;
            }
            let period = self.inner.config().controller.dt;
            j.set_item("overruns", log.compute.iter().zip(&log.lateness).filter(|(c, l)| **c + **l > period).count())?;
            sd.set_item("jitter", j)?;
            d.set_item("lateness", array(py, &[log.lateness.len()], log.lateness)?)?;
            d.set_item("compute", array(py, &[log.compute.len()], log.compute)?)?;
        }
        d.set_item("summary", sd)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let c = &self.inner.config();
        format!(
            "SpatulaSimulation(dob={}, dt={}, payload_mass={}, substeps={}, settle_ticks={})",
            c.controller.dob, c.controller.dt, c.disturbances.payload_mass, c.substeps, c.settle_ticks
        )
    }
}

fn trajectory_rows(arr: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<f64>> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != 3 || shape[0] < 2 {
        return Err(crate::err(crate::Kind::Shape, format!(
            "trajectory: expected shape (K, 3) with K >= 2 rows [y, z, theta], got {shape:?}"
        )));
    }
    Ok(arr.as_array().iter().copied().collect())
}

/// eq. 16 as the control loop computes it: phi for each (theta, a_y, a_z), gravity g.
#[pyfunction]
#[pyo3(signature = (theta, acc, g=9.8))]
fn pancake_phi<'py>(py: Python<'py>, theta: PyReadonlyArrayDyn<'py, f64>, acc: PyReadonlyArrayDyn<'py, f64>, g: f64) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let n = theta.len();
    if acc.shape() != [n, 2] || theta.shape().len() != 1 {
        return Err(crate::err(crate::Kind::Shape, format!(
            "pancake_phi: expected theta (n,) and acc (n, 2), got {:?} and {:?}",
            theta.shape(),
            acc.shape()
        )));
    }
    let th = theta.as_array();
    let a = acc.as_array();
    let out: Vec<f64> = (0..n).map(|i| control::phi(th[i], a[[i, 0]], a[[i, 1]], g)).collect();
    array(py, &[n], out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDynamics>()?;
    m.add_class::<PySpatulaSimulation>()?;
    m.add_function(wrap_pyfunction!(spatula_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(pancake_phi, m)?)?;
    Ok(())
}

//! Bindings of `genplan_core::dynamics` and `genplan_core::control`.
//!
//! * `Dynamics`: rigid-body dynamics of a fixed-base arm (mass matrix, bias forces, RNEA,
//!   forward dynamics, frame Jacobians and their time derivative), for cross-checks and users;
//! * the settings of a run, defined once in the core and exposed as typed, immutable classes
//!   (`ControllerSettings`, `Disturbances`, `Payload`, `JointLimits`, `SpatulaSetup`,
//!   `PancakeSettings`; `settings_class!`) and its summaries (`RunSummary`, `PancakeSummary`;
//!   `record_class!`);
//! * `Simulation`: the 1 kHz loop for any fixed-base robot; `run` checks a joint trajectory and
//!   executes it in Rust with the GIL released (Ctrl-C polled), returning the log as numpy
//!   arrays;
//! * `SpatulaSimulation`: the seq2seq paper's spatula configuration of the same loop;
//! * `pancake_phi`: eq. 16 as the loop computes it (cross-checked against the Python function).

use std::path::PathBuf;

use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use numpy::ndarray::{Array, Array1, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use genplan_core::control::{
    self, percentile, reference_disturbances, ControlSpace, ControllerSettings, Disturbances, JointLimits, LimitPolicy, LimitViolation,
    PancakeSettings, PancakeSummary, Payload, Reference, ReferenceError, Run, SimConfig, Simulation, Spatula, SpatulaConfig,
    SpatulaSetup, Summary,
};
use genplan_core::dynamics::{Dynamics, Frame};
use genplan_core::kinematics::ModelOptions;
use genplan_core::urdf::Urdf;

use crate::settings::{record_class, settings_class, Field};
use crate::errors::{err, to_py, Kind};

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
        return Err(err(Kind::Shape, format!("{what}: expected shape ({n},), got {:?}", arr.shape())));
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
                return Err(crate::errors::err(Kind::Settings, "offset: the 3x3 block is not a rotation matrix"));
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
        let robot = crate::robot::description_from_py(description)?;
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
// settings, defined once in the core
// ---------------------------------------------------------------------------------------------

/// A Python name <-> core enum table.
fn named<T: Copy + PartialEq>(v: &Bound<'_, PyAny>, what: &str, names: &[(&'static str, T)]) -> PyResult<T> {
    let name: Option<String> = v.extract().ok();
    name.as_deref()
        .and_then(|n| names.iter().find(|(k, _)| *k == n).map(|(_, t)| *t))
        .ok_or_else(|| {
            let known = names.iter().map(|(n, _)| format!("'{n}'")).collect::<Vec<_>>().join(", ");
            let shown = v.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
            err(Kind::Settings, format!("{what}: expected one of {known}, got {shown}"))
        })
}

impl Field for ControlSpace {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        named(v, what, &ControlSpace::NAMES)
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(pyo3::types::PyString::new(py, self.name()).into_any())
    }
}

impl Field for LimitPolicy {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        named(v, what, &LimitPolicy::NAMES)
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(pyo3::types::PyString::new(py, self.name()).into_any())
    }
}

settings_class!(
    /// A rigid body a robot holds: mass (kg), centre of mass (m) and inertia about it (kg m^2)
    /// in the frame of `link` (None: the controller's frame). Immutable: `replace(**changes)`.
    PyPayload,
    "Payload",
    Payload,
    |s: &Payload| s.validate().map_err(to_py),
    [link, mass, com, inertia]
);

impl Field for Payload {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        match v.cast::<PyPayload>() {
            Ok(p) => Ok(p.get().inner.clone()),
            Err(_) => {
                let shown = v.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
                Err(err(Kind::Settings, format!("{what}: expected a Payload or None, got {shown}")))
            }
        }
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(Bound::new(py, PyPayload { inner: self.clone() })?.into_any())
    }
}

settings_class!(
    /// The 1 kHz controller (the seq2seq paper's Fig. 10 for any robot): task space on a frame
    /// (free axes, per-axis gains) or joint space, the disturbance observer, model compensation
    /// and the period. Defaults: the paper's gains and 2 Hz observer, with the reference's
    /// acceleration fed forward. Immutable: `replace(**changes)`.
    PyControllerSettings,
    "ControllerSettings",
    ControllerSettings,
    |s: &ControllerSettings| s.validate().map_err(to_py),
    [space, frame, frame_offset, axes, kp, kv, joint_kp, joint_kv, posture_kp, posture_kv, dob, dob_cutoff_hz,
     model_compensation, velocity_feedforward, acceleration_feedforward, singular_det, max_damping, dt],
    {
        /// The paper's loop (Section 5.1): the defaults without the acceleration feed-forward.
        #[staticmethod]
        fn paper() -> Self {
            Self { inner: ControllerSettings::paper() }
        }
    }
);

settings_class!(
    /// What the true plant has that the controller's model lacks: joint friction, a torque
    /// offset (per joint; none: 0) and a payload. Immutable: `replace(**changes)`.
    PyDisturbances,
    "Disturbances",
    Disturbances,
    |s: &Disturbances| s.validate().map_err(to_py),
    [coulomb, viscous, friction_velocity, offset, payload],
    {
        /// Deprecated: `genplan.pancake.control.reference_disturbances()` (the seq2seq
        /// experiment's deviations, for the UR5).
        #[staticmethod]
        fn reference(py: Python<'_>) -> PyResult<Self> {
            let msg = "Disturbances.reference() is deprecated: use genplan.pancake.control.reference_disturbances()";
            py.import("warnings")?.call_method1("warn", (msg, py.get_type::<pyo3::exceptions::PyDeprecationWarning>(), 2))?;
            Ok(Self { inner: reference_disturbances() })
        }
    }
);

settings_class!(
    /// The joint limits a run is checked against (None: the URDF's) and what a tick over one
    /// does: "log", "saturate" (clip the torque) or "stop". Immutable: `replace(**changes)`.
    PyJointLimits,
    "JointLimits",
    JointLimits,
    |s: &JointLimits| s.validate().map_err(to_py),
    [torque, velocity, policy]
);

settings_class!(
    /// Where the seq2seq paper's spatula task sits on the arm (eq. 23). Immutable.
    PySpatulaSetup,
    "SpatulaSetup",
    SpatulaSetup,
    |s: &SpatulaSetup| s.validate().map_err(to_py),
    [tool_link, spatula_length, spatula_mass, spatula_com, origin, attitude, q_seed]
);

settings_class!(
    /// The pancake's friction on the blade and the blade's half length. Immutable.
    PyPancakeSettings,
    "PancakeSettings",
    PancakeSettings,
    |s: &PancakeSettings| s.validate().map_err(to_py),
    [mu_static, mu_kinetic, blade_half_length]
);

record_class!(
    /// Summary numbers of a run (read-only): errors of the frame after the settle phase (m,
    /// rad), of the joints, damped and saturated ticks, largest torques and speeds per joint,
    /// their largest ratios to the limits, ticks over a limit, the wall time per tick (us).
    PyRunSummary,
    "RunSummary",
    Summary,
    [ticks, us_per_tick, max_error_position, max_error_rotation, rms_error_position, rms_error_rotation, max_error_joint,
     damped_ticks, first_damped_time, min_abs_det_j, saturated_ticks, max_abs_tau, max_abs_v, max_torque_ratio,
     max_velocity_ratio, limit_ticks, stopped_at_limit]
);

record_class!(
    /// The pancake's verdicts of a run (read-only): largest |phi| (rad) and slide (m) during the
    /// motion, whether it slipped then, when it first slipped and left the spatula (s).
    PyPancakeSummary,
    "PancakeSummary",
    PancakeSummary,
    [max_abs_phi, slipped, first_slip_time, left_time, max_abs_slide]
);

/// A limit violation as a dict (None: none).
fn violation_dict<'py>(py: Python<'py>, v: &Option<LimitViolation>, names: &[String]) -> PyResult<Option<Bound<'py, PyDict>>> {
    let Some(v) = v else { return Ok(None) };
    let d = PyDict::new(py);
    d.set_item("time", v.time)?;
    d.set_item("tick", v.tick)?;
    d.set_item("joint", names.get(v.joint).map_or("?", String::as_str))?;
    d.set_item("quantity", v.quantity())?;
    d.set_item("value", v.value)?;
    d.set_item("limit", v.limit)?;
    d.set_item("unit", v.unit)?;
    d.set_item("message", v.describe(names))?;
    Ok(Some(d))
}

/// The torque and speed limits in force `{"torque": [...], "velocity": [...]}`.
fn limits_dict<'py>(py: Python<'py>, torque: &[f64], velocity: &[f64]) -> PyResult<Bound<'py, PyDict>> {
    let k = PyDict::new(py);
    k.set_item("torque", torque.to_vec())?;
    k.set_item("velocity", velocity.to_vec())?;
    Ok(k)
}

/// Run `work` without the GIL, asking Python's signal handlers every few hundred ticks: a
/// pending exception (KeyboardInterrupt) is raised as it is.
fn run_interruptible<T: Send>(py: Python<'_>, work: impl FnOnce(&mut dyn FnMut() -> bool) -> genplan_core::Result<T> + Send) -> PyResult<T> {
    let mut interrupt: Option<PyErr> = None;
    let result = py.detach(|| {
        work(&mut || match Python::attach(|py| py.check_signals()) {
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
    result.map_err(to_py)
}

/// The log of a run as a dict of numpy arrays (moved, not copied), with its summary record,
/// the first tick over a limit, the motion window and, paced, the jitter.
fn run_dict<'py>(py: Python<'py>, run: Run, names: &[String], dt: f64, paced: bool) -> PyResult<Bound<'py, PyDict>> {
    let Run { log, summary, limit_violation, motion_start, motion_end } = run;
    let (n, nq, nv) = (log.n, log.nq, log.nv);
    let d = PyDict::new(py);
    d.set_item("t", array(py, &[n], log.t)?)?;
    d.set_item("q", array(py, &[n, nq], log.q)?)?;
    d.set_item("v", array(py, &[n, nv], log.v)?)?;
    d.set_item("tau", array(py, &[n, nv], log.tau)?)?;
    d.set_item("tau_dis_hat", array(py, &[n, nv], log.tau_dis_hat)?)?;
    d.set_item("tau_dis", array(py, &[n, nv], log.tau_dis)?)?;
    if !log.err_joint.is_empty() {
        d.set_item("error_joint", array(py, &[n, nv], log.err_joint)?)?;
    }
    d.set_item("position_cmd", array(py, &[n, 3], log.pos_cmd)?)?;
    d.set_item("position", array(py, &[n, 3], log.pos)?)?;
    d.set_item("rotation", array(py, &[n, 3, 3], log.rot)?)?;
    d.set_item("error_position", array(py, &[n], log.err_pos)?)?;
    d.set_item("error_rotation", array(py, &[n], log.err_rot)?)?;
    d.set_item("velocity", array(py, &[n, 6], log.vel)?)?;
    d.set_item("acceleration", array(py, &[n, 6], log.acc)?)?;
    d.set_item("det_j", array(py, &[n], log.det_j)?)?;
    d.set_item("damped", Array1::from_vec(log.damped).into_pyarray(py))?;
    d.set_item("saturated", Array1::from_vec(log.saturated).into_pyarray(py))?;
    d.set_item("torque_ratio", array(py, &[n], log.torque_ratio)?)?;
    d.set_item("velocity_ratio", array(py, &[n], log.velocity_ratio)?)?;
    if paced {
        let j = PyDict::new(py);
        for (name, xs) in [("lateness", &log.lateness), ("compute", &log.compute)] {
            j.set_item(format!("{name}_p50_us"), percentile(xs, 50.0) * 1e6)?;
            j.set_item(format!("{name}_p99_us"), percentile(xs, 99.0) * 1e6)?;
            j.set_item(format!("{name}_max_us"), xs.iter().copied().fold(0.0, f64::max) * 1e6)?;
        }
        j.set_item("overruns", log.compute.iter().zip(&log.lateness).filter(|(c, l)| **c + **l > dt).count())?;
        d.set_item("jitter", j)?;
        d.set_item("lateness", array(py, &[log.lateness.len()], log.lateness)?)?;
    }
    d.set_item("compute", array(py, &[n], log.compute)?)?;
    let k = log.channels.len();
    d.set_item("payload_channels", log.channels.iter().map(|c| c.to_string()).collect::<Vec<_>>())?;
    d.set_item("payload", array(py, &[n, k], log.payload)?)?;
    d.set_item("motion_start", motion_start)?;
    d.set_item("motion_end", motion_end)?;
    d.set_item("limit_violation", violation_dict(py, &limit_violation, names)?)?;
    d.set_item("summary", Bound::new(py, PyRunSummary { inner: summary })?)?;
    Ok(d)
}

/// A (n, width) float64 array's data, row-major, or a ShapeError naming `what`.
fn rows(arr: &PyReadonlyArrayDyn<'_, f64>, width: usize, what: &str) -> PyResult<Vec<f64>> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != width || shape[0] == 0 {
        return Err(err(Kind::Shape, format!("{what}: expected shape (n, {width}) with n >= 1, got {shape:?}")));
    }
    Ok(arr.as_array().iter().copied().collect())
}

fn reference_error(e: ReferenceError) -> PyErr {
    match e {
        ReferenceError::Input(e) => to_py(e),
        ReferenceError::Trajectory(m) => err(Kind::InvalidTrajectory, m),
    }
}

/// The 1 kHz loop for any fixed-base robot: controller, plant, observer, payloads, limits.
#[pyclass(name = "Simulation", module = "genplan._core")]
pub(crate) struct PySimulation {
    inner: Simulation,
}

#[pymethods]
impl PySimulation {
    /// `robot`: a fixed-base robot's description (`genplan.Robot.description`); `controller`
    /// must name its frame; `payloads`: what the robot holds and the controller knows;
    /// `disturbances`: what the plant has and the controller does not; `limits`: the joint
    /// limits and their policy; `substeps`: RK4 steps per period.
    #[new]
    #[pyo3(signature = (robot, controller, disturbances=None, payloads=None, limits=None, substeps=1))]
    fn new(
        robot: &Bound<'_, PyDict>,
        controller: &Bound<'_, PyControllerSettings>,
        disturbances: Option<&Bound<'_, PyDisturbances>>,
        payloads: Option<Vec<Bound<'_, PyPayload>>>,
        limits: Option<&Bound<'_, PyJointLimits>>,
        substeps: usize,
    ) -> PyResult<Self> {
        let robot = crate::robot::description_from_py(robot)?;
        let arm = Dynamics::from_description(&robot).map_err(to_py)?;
        let config = SimConfig {
            controller: controller.get().inner.clone(),
            disturbances: disturbances.map_or(Disturbances::default(), |x| x.get().inner.clone()),
            payloads: payloads.unwrap_or_default().iter().map(|p| p.get().inner.clone()).collect(),
            limits: limits.map_or(JointLimits::default(), |x| x.get().inner.clone()),
            substeps,
        };
        Ok(Self { inner: Simulation::new(&arm, config).map_err(to_py)? })
    }

    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.controller.nominal.joint_names.clone()
    }

    /// The controller's settings.
    #[getter]
    fn controller(&self) -> PyControllerSettings {
        PyControllerSettings { inner: self.inner.config().controller.clone() }
    }

    /// The joint limits in force: {"torque": [...], "velocity": [...]} (the settings', else the
    /// robot model's).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        limits_dict(py, &self.inner.limits.torque, &self.inner.limits.velocity)
    }

    /// Execute a joint trajectory sampled every `dt`: `q` (n, nq), `qd` and `qdd` (n, nv),
    /// checked first (InvalidTrajectoryError naming the field, sample and joint: outside the
    /// joint range, over the velocity limits, a jump one tick cannot follow; ShapeError,
    /// NonFiniteError). `settle`: ticks holding the first sample. `strict`: stop at the first
    /// tick over a limit, and refuse (LimitExceededError) a trajectory whose inverse-dynamics
    /// torques exceed the torque limits. Returns the log (dict of numpy arrays, `summary`
    /// record, `limit_violation`) with `reference_torque_ratio` (largest |inverse-dynamics
    /// torque| / limit along the trajectory) and `reference_over` (its first sample over, or
    /// None). The loop runs in Rust without the GIL; Ctrl-C raises KeyboardInterrupt.
    #[pyo3(signature = (q, qd, qdd, settle=0, paced=false, strict=false))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        qdd: PyReadonlyArrayDyn<'py, f64>,
        settle: usize,
        paced: bool,
        strict: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (nq, nv) = (self.inner.controller.nominal.nq, self.inner.controller.nominal.nv);
        let (q, qd, qdd) = (rows(&q, nq, "trajectory.q")?, rows(&qd, nv, "trajectory.qd")?, rows(&qdd, nv, "trajectory.qdd")?);
        let names = self.inner.controller.nominal.joint_names.clone();
        let dt = self.inner.controller.settings.dt;
        let sim = &mut self.inner;
        let mut interrupt: Option<PyErr> = None;
        let built = py.detach(|| {
            Reference::from_joints_with(&sim.controller.nominal, &sim.controller.frame, &sim.limits, q, qd, qdd, dt, &mut || {
                match Python::attach(|py| py.check_signals()) {
                    Ok(()) => false,
                    Err(e) => {
                        interrupt = Some(e);
                        true
                    }
                }
            })
        });
        if let Some(e) = interrupt {
            return Err(e);
        }
        let (reference, check) = built.map_err(reference_error)?;
        if strict {
            if let Some(v) = &check.torque_over {
                return Err(err(Kind::LimitExceeded, format!(
                    "trajectory refused (strict=True): its inverse-dynamics torques exceed the limits: {}",
                    v.describe(&names).replacen(" at t = ", " at sample t = ", 1)
                )));
            }
        }
        let q0 = reference.joint_command(0).map(|j| j.q.to_vec()).unwrap_or_default();
        let run = run_interruptible(py, |stop| sim.run_with(&reference, &q0, settle, None, paced, strict, stop))?;
        let d = run_dict(py, run, &names, dt, paced)?;
        d.set_item("reference_torque_ratio", check.max_torque_ratio)?;
        d.set_item("reference_over", violation_dict(py, &check.torque_over, &names)?)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let c = &self.inner.config().controller;
        format!(
            "Simulation(space={}, frame={:?}, dob={}, dt={}, joints={})",
            c.space.name(),
            c.frame.as_deref().unwrap_or(""),
            c.dob,
            c.dt,
            self.inner.controller.nominal.nv
        )
    }
}

/// The seq2seq paper's spatula configuration of the 1 kHz loop, with the pancake.
#[pyclass(name = "SpatulaSimulation", module = "genplan._core")]
pub(crate) struct PySpatulaSimulation {
    inner: Spatula,
}

#[pymethods]
impl PySpatulaSimulation {
    /// `robot`: a fixed-base 6-joint robot's description (the "ur5" preset's); `controller`:
    /// gains, observer and period (default: the paper's loop; its frame and axes are the
    /// spatula's); `disturbances`: what the plant has that the controller's model lacks (a
    /// payload: at the spatula point); `limits`: checked every tick (default: recorded).
    #[new]
    #[pyo3(signature = (robot, controller=None, disturbances=None, setup=None, pancake=None, limits=None, substeps=1, settle_ticks=0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        robot: &Bound<'_, PyDict>,
        controller: Option<&Bound<'_, PyControllerSettings>>,
        disturbances: Option<&Bound<'_, PyDisturbances>>,
        setup: Option<&Bound<'_, PySpatulaSetup>>,
        pancake: Option<&Bound<'_, PyPancakeSettings>>,
        limits: Option<&Bound<'_, PyJointLimits>>,
        substeps: usize,
        settle_ticks: usize,
    ) -> PyResult<Self> {
        let robot = crate::robot::description_from_py(robot)?;
        let arm = Dynamics::from_description(&robot).map_err(to_py)?;
        let d = SpatulaConfig::default();
        let config = SpatulaConfig {
            controller: controller.map_or(d.controller, |x| x.get().inner.clone()),
            disturbances: disturbances.map_or(d.disturbances, |x| x.get().inner.clone()),
            setup: setup.map_or(d.setup, |x| x.get().inner.clone()),
            pancake: pancake.map_or(d.pancake, |x| x.get().inner.clone()),
            limits: limits.map_or(d.limits, |x| x.get().inner.clone()),
            substeps,
            settle_ticks,
        };
        Ok(Self { inner: Spatula::new(&arm, config).map_err(to_py)? })
    }

    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.sim.controller.nominal.joint_names.clone()
    }

    /// The controller's settings (the spatula's frame and axes).
    #[getter]
    fn controller(&self) -> PyControllerSettings {
        PyControllerSettings { inner: self.inner.sim.config().controller.clone() }
    }

    /// The joint limits every tick is checked against: {"torque": [...], "velocity": [...]}
    /// (the settings', else the robot model's URDF limits).
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        limits_dict(py, &self.inner.sim.limits.torque, &self.inner.sim.limits.velocity)
    }

    /// Ticks holding the first pose before the motion.
    #[getter]
    fn settle_ticks(&self) -> usize {
        self.inner.config().settle_ticks
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
    /// wall clock. `stop_at_limit`: end the run at the first tick over a joint limit. Returns the
    /// log (dict of numpy arrays; `payload` holds the pancake's channels `tilt`, `phi`, `slide`,
    /// `normal`, `mode`), its `summary` record, `pancake` record and `limit_violation`. The loop
    /// runs in Rust without the GIL; Ctrl-C raises KeyboardInterrupt.
    #[pyo3(signature = (trajectory, motion_len=None, paced=false, stop_at_limit=false))]
    fn run<'py>(&mut self, py: Python<'py>, trajectory: PyReadonlyArrayDyn<'py, f64>, motion_len: Option<usize>, paced: bool, stop_at_limit: bool) -> PyResult<Bound<'py, PyDict>> {
        let traj = trajectory_rows(&trajectory)?;
        let names = self.inner.sim.controller.nominal.joint_names.clone();
        let dt = self.inner.sim.controller.settings.dt;
        let sim = &mut self.inner;
        let run = run_interruptible(py, |stop| sim.run_with(&traj, motion_len, paced, stop_at_limit, stop))?;
        let pancake = run.pancake;
        let d = run_dict(py, run.run, &names, dt, paced)?;
        d.set_item("pancake", Bound::new(py, PyPancakeSummary { inner: pancake })?)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let c = self.inner.config();
        let payload = c.disturbances.payload.as_ref().map_or(0.0, |p| p.mass);
        format!(
            "SpatulaSimulation(dob={}, dt={}, payload_error={} kg, substeps={}, settle_ticks={})",
            c.controller.dob, c.controller.dt, payload, c.substeps, c.settle_ticks
        )
    }
}

fn trajectory_rows(arr: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<f64>> {
    let shape = arr.shape();
    if shape.len() != 2 || shape[1] != 3 || shape[0] < 2 {
        return Err(err(Kind::Shape, format!(
            "trajectory: expected shape (K, 3) with K >= 2 rows [y, z, theta], got {shape:?}"
        )));
    }
    Ok(arr.as_array().iter().copied().collect())
}

/// The plant deviations of genplan's reproduction of the seq2seq experiment (for the UR5).
#[pyfunction]
fn spatula_reference_disturbances() -> PyDisturbances {
    PyDisturbances { inner: reference_disturbances() }
}

/// eq. 16 as the control loop computes it: phi for each (theta, a_y, a_z), gravity g.
#[pyfunction]
#[pyo3(signature = (theta, acc, g=9.8))]
fn pancake_phi<'py>(py: Python<'py>, theta: PyReadonlyArrayDyn<'py, f64>, acc: PyReadonlyArrayDyn<'py, f64>, g: f64) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let n = theta.len();
    if acc.shape() != [n, 2] || theta.shape().len() != 1 {
        return Err(err(Kind::Shape, format!(
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
    m.add_class::<PyControllerSettings>()?;
    m.add_class::<PyDisturbances>()?;
    m.add_class::<PyPayload>()?;
    m.add_class::<PyJointLimits>()?;
    m.add_class::<PySpatulaSetup>()?;
    m.add_class::<PyPancakeSettings>()?;
    m.add_class::<PyRunSummary>()?;
    m.add_class::<PyPancakeSummary>()?;
    m.add_class::<PySimulation>()?;
    m.add_class::<PySpatulaSimulation>()?;
    m.add_function(wrap_pyfunction!(pancake_phi, m)?)?;
    m.add_function(wrap_pyfunction!(spatula_reference_disturbances, m)?)?;
    m.add("MAX_TICKS", control::MAX_TICKS)?;
    // the names `ControllerSettings.space` and `JointLimits.policy` take, from the core's tables
    // (the stub's Literal types are checked against them)
    m.add("CONTROL_SPACES", pyo3::types::PyTuple::new(m.py(), ControlSpace::NAMES.map(|(n, _)| n))?)?;
    m.add("LIMIT_POLICIES", pyo3::types::PyTuple::new(m.py(), LimitPolicy::NAMES.map(|(n, _)| n))?)?;
    Ok(())
}

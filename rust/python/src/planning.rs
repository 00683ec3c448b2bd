//! Bindings of `genplan_core::planning`: the constrained RRT with native or Python components.
//!
//! A component is either native (a `UniformSampler`, a `Projector`, a `CollisionWorld`) or any
//! Python object with the right method:
//!
//! * sampler: `sample(n) -> (n, nq)` array;
//! * projector: `project(qs, q_noms) -> (q (n, nq), success (n,)[, iterations (n,)])`;
//! * validity checker: `is_valid(qs) -> (n,)` booleans.
//!
//! A flag (validity, success) that is not a boolean or exactly 0 / 1 is a CallbackError naming
//! the callback, the index and the value: NaN, 0.5 or 2 is neither true nor false.
//!
//! The plan runs without the GIL; a Python component takes it back for each (batched) call. An
//! exception raised in a component ends the plan and is re-raised to the caller as it was; Ctrl-C
//! is checked every 50 ms. The native samplers' batched `sample` runs in chunks that answer
//! Ctrl-C too (`crate::batch::for_chunks`).

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use genplan_core::planning::{
    self, Algorithm, CollisionChecker, SphereChecker, Components, EdgeCheck, Named, GaussNewtonProjector, MixtureSampler, PlanError, PlanResult, Planner,
    Projection, Sampler, Sampling, Settings, Space, Stats, ValidityChecker,
};

use genplan_core::kinematics::KinematicModel;
use genplan_core::{codec, flow, gan};

use crate::arrays::read_configurations;
use crate::batch::for_chunks;
use crate::collision::{PyCollisionWorld, PySphereChecker};
use crate::errors::{err, to_py, Kind};
use crate::kinematics::PyKinematicModel;
use crate::projection::PyProjector;
use crate::settings::{record_class, settings_class, Field};

fn component_error(e: PyErr) -> PlanError {
    PlanError::Component(Box::new(e))
}

/// A PlanError as the Python exception it stands for (a component's own exception unchanged).
fn plan_error_to_py(e: PlanError) -> PyErr {
    let kind = match e {
        PlanError::Component(b) => {
            return match b.downcast::<PyErr>() {
                Ok(py_err) => *py_err,
                Err(other) => match other.downcast::<genplan_core::error::Error>() {
                    Ok(core) => to_py(*core), // a custom term's bad output: typed, naming the term
                    Err(other) => PyRuntimeError::new_err(other.to_string()),
                },
            }
        }
        PlanError::Settings { .. } => Kind::Settings,
        PlanError::InvalidStart(_) => Kind::InvalidStart,
        PlanError::InvalidGoal(_) => Kind::InvalidGoal,
        PlanError::Sampler(_) => Kind::Callback,
        PlanError::Input(_) | PlanError::NoProjectableSample(_) | PlanError::TimeLimit => Kind::Generic,
        PlanError::Internal(m) => return PyRuntimeError::new_err(m),
    };
    err(kind, e.to_string())
}

/// Rows of a 2-D float64 array returned by a Python component, checked against the expected shape.
fn rows_from(py: Python<'_>, obj: &Bound<'_, PyAny>, n: usize, nq: usize, what: &str) -> PyResult<Vec<f64>> {
    let np = py.import("numpy")?;
    let arr = np.call_method1("asarray", (obj, "float64"))?;
    let arr: PyReadonlyArray2<f64> = arr.extract().map_err(|_| {
        err(Kind::Callback, format!("{what}: expected a 2-D array of shape ({n}, {nq})"))
    })?;
    if arr.shape() != [n, nq] {
        return Err(err(Kind::Callback, format!("{what}: expected shape ({n}, {nq}), got {:?}", arr.shape())));
    }
    Ok(arr.as_array().iter().copied().collect())
}

fn vector_from<'py, T: numpy::Element + Copy>(py: Python<'py>, obj: &Bound<'py, PyAny>, n: usize, dtype: &str, what: &str) -> PyResult<Vec<T>> {
    let np = py.import("numpy")?;
    let arr = np.call_method1("asarray", (obj, dtype))?;
    let arr: PyReadonlyArray1<T> = arr
        .extract()
        .map_err(|_| err(Kind::Callback, format!("{what}: expected a 1-D array of {n} values")))?;
    if arr.len() != n {
        return Err(err(Kind::Callback, format!("{what}: expected {n} values, got {}", arr.len())));
    }
    Ok(arr.as_array().iter().copied().collect())
}

/// The booleans a Python component returned: a 1-D array of n booleans, or of n numbers each
/// exactly 0 or 1. Anything else (NaN, 0.5, 2, strings, None) is a CallbackError naming
/// `what` and the first offending index and value: a validity or success flag that is not
/// clearly true or false must not be read as one.
fn bools_from(py: Python<'_>, obj: &Bound<'_, PyAny>, n: usize, what: &str) -> PyResult<Vec<bool>> {
    let np = py.import("numpy")?;
    let arr = np.call_method1("asarray", (obj,)).map_err(|_| err(Kind::Callback, format!("{what}: expected a 1-D array of {n} booleans")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    match kind.as_str() {
        "b" => vector_from(py, &arr, n, "bool", what),
        "i" | "u" | "f" => {
            let v: Vec<f64> = vector_from(py, &arr, n, "float64", what)?;
            match v.iter().position(|&x| x != 0.0 && x != 1.0) {
                Some(i) => Err(err(Kind::Callback, format!("{what}: returned {} at index {i}; expected booleans (or 0 / 1)", v[i]))),
                None => Ok(v.iter().map(|&x| x == 1.0).collect()),
            }
        }
        _ => {
            let dtype = arr.getattr("dtype")?.str()?.to_string();
            Err(err(Kind::Callback, format!("{what}: returned an array of dtype {dtype}; expected booleans (or 0 / 1)")))
        }
    }
}

fn to_array<'py>(py: Python<'py>, data: &[f64], nq: usize) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    into_array(py, data.to_vec(), nq)
}

/// Rows of `nq` as an (n, nq) numpy array that takes over `data` (no copy).
fn into_array(py: Python<'_>, data: Vec<f64>, nq: usize) -> PyResult<Bound<'_, numpy::PyArray2<f64>>> {
    let n = if nq == 0 { 0 } else { data.len() / nq };
    Ok(Array2::from_shape_vec((n, nq), data)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py))
}

// ---------------------------------------------------------------------------------------------
// Python components
// ---------------------------------------------------------------------------------------------

struct PySampler {
    obj: Py<PyAny>,
    nq: usize,
}

impl Sampler for PySampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        Python::attach(|py| -> PyResult<()> {
            let r = self.obj.bind(py).call_method1("sample", (n,))?;
            let rows = rows_from(py, &r, n, self.nq, "sampler.sample(n)")?;
            out[..n * self.nq].copy_from_slice(&rows);
            Ok(())
        })
        .map_err(component_error)
    }
}

struct PyProjectorAdapter {
    obj: Py<PyAny>,
    nq: usize,
}

impl planning::Projector for PyProjectorAdapter {
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let n = reports.len();
        let nq = self.nq;
        Python::attach(|py| -> PyResult<()> {
            let r = self.obj.bind(py).call_method1("project", (to_array(py, qs, nq)?, to_array(py, q_noms, nq)?))?;
            const RETURNS: &str = "projector.project(qs, q_noms) must return (q, success) or (q, success, iterations)";
            if !(r.is_instance_of::<PyTuple>() || r.is_instance_of::<PyList>()) {
                return Err(err(Kind::Callback, format!("{RETURNS}, got {}", r.get_type().name()?)));
            }
            let parts: Vec<Bound<'_, PyAny>> = r.extract()?;
            if !(2..=3).contains(&parts.len()) {
                return Err(err(Kind::Callback, format!("{RETURNS}, got {} items", parts.len())));
            }
            let q = rows_from(py, &parts[0], n, nq, "projector.project: q")?;
            let ok = bools_from(py, &parts[1], n, "projector.project: success")?;
            let it: Vec<i64> = if parts.len() == 3 {
                vector_from(py, &parts[2], n, "int64", "projector.project: iterations")?
            } else {
                vec![1; n]
            };
            out[..n * nq].copy_from_slice(&q);
            for i in 0..n {
                reports[i] = Projection { success: ok[i], iterations: it[i].max(0) as usize };
            }
            Ok(())
        })
        .map_err(component_error)
    }
}

struct PyChecker {
    obj: Py<PyAny>,
    nq: usize,
}

impl ValidityChecker for PyChecker {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        let n = valid.len();
        Python::attach(|py| -> PyResult<()> {
            let r = self.obj.bind(py).call_method1("is_valid", (to_array(py, qs, self.nq)?,))?;
            let v = bools_from(py, &r, n, "checker.is_valid(qs)")?;
            valid.copy_from_slice(&v);
            Ok(())
        })
        .map_err(component_error)
    }
}

// ---------------------------------------------------------------------------------------------
// Native samplers exposed to Python
// ---------------------------------------------------------------------------------------------

/// Uniform within the joint limits; a free-flyer base held at `base` ([x, y, z, qx, qy, qz, qw]);
/// `sampling`: "random" (default) or "halton" (a Halton sequence shifted by `seed`).
#[pyclass(name = "UniformSampler", module = "genplan._core", frozen)]
pub(crate) struct PyUniformSampler {
    inner: Arc<Mutex<planning::UniformSampler>>,
    nq: usize,
}

#[pymethods]
impl PyUniformSampler {
    #[new]
    #[pyo3(signature = (model, base=None, seed=0, base_box=None, sampling=None))]
    fn new(
        model: &PyKinematicModel,
        base: Option<[f64; 7]>,
        seed: u64,
        base_box: Option<[[f64; 3]; 2]>,
        sampling: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let sampling: Sampling = sampling.map_or(Ok(Sampling::default()), |v| named_from_py(v, "sampling"))?;
        let mut s = planning::UniformSampler::new(model.inner.clone(), base, seed).map_err(plan_error_to_py)?;
        if let Some([lo, hi]) = base_box {
            s = s.with_base_box(lo, hi).map_err(plan_error_to_py)?;
        }
        let s = s.with_sampling(sampling);
        Ok(Self { inner: Arc::new(Mutex::new(s)), nq: model.inner.nq })
    }

    /// n configurations, (n, nq).
    fn sample<'py>(&self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let out = sample_in_chunks(py, &self.inner, n, self.nq, "uniform sampler")?;
        to_array(py, &out, self.nq)
    }
}

/// Rows of a data set (n, nq), each drawn uniformly at random: `genplan.planning.data_sampler`.
#[pyclass(name = "DataSampler", module = "genplan._core", frozen)]
pub(crate) struct PyDataSampler {
    inner: Arc<Mutex<planning::DataSampler>>,
    nq: usize,
    rows: usize,
}

#[pymethods]
impl PyDataSampler {
    #[new]
    #[pyo3(signature = (rows, seed=0))]
    fn new(rows: PyReadonlyArray2<'_, f64>, seed: u64) -> PyResult<Self> {
        let [n, nq] = [rows.shape()[0], rows.shape()[1]];
        let data: Vec<f64> = rows.as_array().iter().copied().collect();
        let s = planning::DataSampler::new(data, nq, seed).map_err(plan_error_to_py)?;
        Ok(Self { inner: Arc::new(Mutex::new(s)), nq, rows: n })
    }

    /// n configurations, (n, nq).
    fn sample<'py>(&self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let out = sample_in_chunks(py, &self.inner, n, self.nq, "data sampler")?;
        to_array(py, &out, self.nq)
    }

    /// The number of rows drawn from.
    fn __len__(&self) -> usize {
        self.rows
    }
}

/// A native sampler shared with Python (`what` names it in errors), used by one plan at a time.
struct Shared<S>(Arc<Mutex<S>>, &'static str);

impl<S: Sampler> Sampler for Shared<S> {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let what = self.1;
        self.0.lock().map_err(|_| PlanError::Sampler(format!("{what}: lock poisoned")))?.sample(n, out)
    }
}

/// n configurations (rows of nq) from a native sampler shared with the planner, drawn in
/// chunks (the same stream as one call) without the GIL, Ctrl-C answered between chunks.
fn sample_in_chunks<S: Sampler>(py: Python<'_>, sampler: &Mutex<S>, n: usize, nq: usize, what: &str) -> PyResult<Vec<f64>> {
    let mut out = vec![0.0; n * nq];
    for_chunks(py, n, |rows| {
        let mut s = sampler.lock().map_err(|_| PyRuntimeError::new_err(format!("{what}: lock poisoned")))?;
        s.sample(rows.len(), &mut out[rows.start * nq..rows.end * nq]).map_err(plan_error_to_py)
    })?;
    Ok(out)
}

/// A trained GAN generator run natively: samples conditioned on targets uniform in a box.
/// Built by `genplan.gan.GanModel.native_sampler()` from the torch weights.
#[pyclass(name = "GanSampler", module = "genplan._core", frozen)]
pub(crate) struct PyGanSampler {
    inner: Arc<Mutex<gan::GanSampler>>,
    generator: Arc<gan::Generator>,
}

#[pymethods]
impl PyGanSampler {
    /// `weights[i]`: (n_net, inputs, outputs), `biases[i]`: (n_net, 1, outputs), float64.
    #[new]
    #[pyo3(signature = (noise_dim, weights, biases, mean, std, floating_base, lower, upper, seed=0, continuous=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        noise_dim: usize,
        weights: Vec<PyReadonlyArray3<'_, f64>>,
        biases: Vec<PyReadonlyArray3<'_, f64>>,
        mean: Vec<f64>,
        std: Vec<f64>,
        floating_base: bool,
        lower: [f64; 3],
        upper: [f64; 3],
        seed: u64,
        continuous: Option<Vec<usize>>,
    ) -> PyResult<Self> {
        if weights.len() != biases.len() || weights.is_empty() {
            return Err(err(Kind::Shape, "GAN sampler: one bias per weight matrix, at least one layer"));
        }
        let n_net = weights[0].shape()[0];
        let mut layers = Vec::new();
        for (i, (w, b)) in weights.iter().zip(&biases).enumerate() {
            let (ws, bs) = (w.shape(), b.shape());
            if ws[0] != n_net || bs != [n_net, 1, ws[2]] {
                return Err(err(Kind::Shape, format!(
                    "GAN sampler: layer {i}: weights {ws:?} and biases {bs:?} do not fit (n_net, in, out) / (n_net, 1, out)"
                )));
            }
            layers.push(gan::Layer {
                inputs: ws[1],
                outputs: ws[2],
                weights: w.as_array().iter().copied().collect(),
                biases: b.as_array().iter().copied().collect(),
            });
        }
        let mut generator = gan::Generator::new(n_net, noise_dim, layers, mean, std, floating_base).map_err(to_py)?;
        generator.codec = generator.codec.clone().with_continuous(continuous.unwrap_or_default(), "GAN sampler").map_err(to_py)?;
        let generator = Arc::new(generator);
        let sampler = gan::GanSampler::new(generator.clone(), lower, upper, seed).map_err(to_py)?;
        Ok(Self { inner: Arc::new(Mutex::new(sampler)), generator })
    }

    #[getter]
    fn nq(&self) -> usize {
        self.generator.nq()
    }

    /// n configurations, (n, nq), targets uniform in the box.
    fn sample<'py>(&self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let nq = self.generator.nq();
        let out = sample_in_chunks(py, &self.inner, n, nq, "GAN sampler")?;
        to_array(py, &out, nq)
    }

    /// The configurations the given members make of the given noise and targets (for checks).
    fn generate<'py>(
        &self,
        py: Python<'py>,
        members: Vec<usize>,
        noise: PyReadonlyArray2<'py, f64>,
        targets: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let g = &self.generator;
        let n = members.len();
        if noise.shape() != [n, g.noise_dim] || targets.shape() != [n, 3] {
            return Err(err(Kind::Shape, format!(
                "generate: expected noise ({n}, {}) and targets ({n}, 3), got {:?} and {:?}",
                g.noise_dim,
                noise.shape(),
                targets.shape()
            )));
        }
        if let Some(&m) = members.iter().find(|&&m| m >= g.n_net) {
            return Err(err(Kind::Generic, format!("generate: member {m} out of range (n_net = {})", g.n_net)));
        }
        let z: Vec<f64> = noise.as_array().iter().copied().collect();
        let t: Vec<f64> = targets.as_array().iter().copied().collect();
        let nq = g.nq();
        let mut out = vec![0.0; n * nq];
        let mut scratch = Default::default();
        for_chunks(py, n, |rows| {
            for i in rows {
                let target = [t[3 * i], t[3 * i + 1], t[3 * i + 2]];
                g.generate(members[i], &z[i * g.noise_dim..(i + 1) * g.noise_dim], &target, &mut out[i * nq..(i + 1) * nq], &mut scratch);
            }
            Ok(())
        })?;
        to_array(py, &out, nq)
    }
}

/// A trained flow-matching sampler run natively: samples conditioned on targets uniform in a box.
/// Built by `genplan.gan.flow.FlowModel.native_sampler()` from the torch weights.
#[pyclass(name = "FlowSampler", module = "genplan._core", frozen)]
pub(crate) struct PyFlowSampler {
    inner: Arc<Mutex<flow::FlowSampler>>,
    flow: Arc<flow::Flow>,
}

#[pymethods]
impl PyFlowSampler {
    /// `weights[i]`: (outputs, inputs), `biases[i]`: (outputs,), float32 (torch's Linear layout).
    #[new]
    #[pyo3(signature = (weights, biases, steps, target_mean, target_std, mean, std, floating_base, lower, upper, seed=0, continuous=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        weights: Vec<PyReadonlyArray2<'_, f32>>,
        biases: Vec<PyReadonlyArray1<'_, f32>>,
        steps: usize,
        target_mean: [f64; 3],
        target_std: [f64; 3],
        mean: Vec<f64>,
        std: Vec<f64>,
        floating_base: bool,
        lower: [f64; 3],
        upper: [f64; 3],
        seed: u64,
        continuous: Option<Vec<usize>>,
    ) -> PyResult<Self> {
        if weights.len() != biases.len() || weights.is_empty() {
            return Err(err(Kind::Shape, "flow sampler: one bias per weight matrix, at least one layer"));
        }
        let mut layers = Vec::new();
        for (w, b) in weights.iter().zip(&biases) {
            let (rows, cols) = (w.shape()[0], w.shape()[1]);
            let values: Vec<f32> = w.as_array().iter().copied().collect();
            layers.push(flow::Dense {
                weight: nalgebra::DMatrix::from_row_slice(rows, cols, &values),
                bias: b.as_array().iter().copied().collect(),
            });
        }
        let codec = codec::Codec::new(mean, std, floating_base, "flow sampler")
            .and_then(|c| c.with_continuous(continuous.unwrap_or_default(), "flow sampler"))
            .map_err(to_py)?;
        let flow = Arc::new(flow::Flow::new(layers, steps, target_mean, target_std, codec).map_err(to_py)?);
        let sampler = flow::FlowSampler::new(flow.clone(), lower, upper, seed).map_err(to_py)?;
        Ok(Self { inner: Arc::new(Mutex::new(sampler)), flow })
    }

    #[getter]
    fn nq(&self) -> usize {
        self.flow.nq()
    }

    /// n configurations, (n, nq), targets uniform in the box.
    fn sample<'py>(&self, py: Python<'py>, n: usize) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let nq = self.flow.nq();
        let out = sample_in_chunks(py, &self.inner, n, nq, "flow sampler")?;
        to_array(py, &out, nq)
    }

    /// The configurations the flow makes of the given noise (n, dim) and targets (n, 3).
    fn generate<'py>(
        &self,
        py: Python<'py>,
        noise: PyReadonlyArray2<'py, f64>,
        targets: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let f = &self.flow;
        let n = targets.shape()[0];
        let dim = f.codec.dim();
        if noise.shape() != [n, dim] || targets.shape() != [n, 3] {
            return Err(err(Kind::Shape, format!(
                "generate: expected noise ({n}, {dim}) and targets ({n}, 3), got {:?} and {:?}",
                noise.shape(),
                targets.shape()
            )));
        }
        let z: Vec<f64> = noise.as_array().iter().copied().collect();
        let t: Vec<f64> = targets.as_array().iter().copied().collect();
        let nq = f.nq();
        let mut out = vec![0.0; n * nq];
        for_chunks(py, n, |rows| {
            f.generate(&z[rows.start * dim..rows.end * dim], &t[rows.start * 3..rows.end * 3], &mut out[rows.start * nq..rows.end * nq]);
            Ok(())
        })?;
        to_array(py, &out, nq)
    }
}

/// Draws from `primary` with probability `p`, else from `secondary` (each native or Python):
/// the paper's hybrid sampler.
#[pyclass(name = "MixtureSampler", module = "genplan._core", frozen)]
pub(crate) struct PyMixtureSampler {
    primary: Py<PyAny>,
    secondary: Py<PyAny>,
    p: f64,
    half_life: Option<f64>,
    seed: Mutex<u64>,
}

#[pymethods]
impl PyMixtureSampler {
    #[new]
    #[pyo3(signature = (primary, secondary, p=0.8, seed=0, half_life=None))]
    fn new(primary: Py<PyAny>, secondary: Py<PyAny>, p: f64, seed: u64, half_life: Option<f64>) -> PyResult<Self> {
        if !(0.0..=1.0).contains(&p) {
            return Err(err(Kind::Settings, format!("p must be in [0, 1], got {p}")));
        }
        if let Some(h) = half_life {
            if !(h.is_finite() && h > 0.0) {
                return Err(err(Kind::Settings, format!("half_life must be a finite number > 0, got {h}")));
            }
        }
        Ok(Self { primary, secondary, p, half_life, seed: Mutex::new(seed) })
    }

    #[getter]
    fn p(&self) -> f64 {
        self.p
    }

    /// Rows after which the probability of the primary sampler has halved (None: constant p).
    #[getter]
    fn half_life(&self) -> Option<f64> {
        self.half_life
    }
}

fn sampler_from(py: Python<'_>, obj: &Bound<'_, PyAny>, nq: usize) -> PyResult<Box<dyn Sampler>> {
    if let Ok(u) = obj.cast::<PyUniformSampler>() {
        let u = u.get();
        if u.nq != nq {
            return Err(err(Kind::Shape, format!("sampler: configurations of length {} for a model of nq = {nq}", u.nq)));
        }
        return Ok(Box::new(Shared(u.inner.clone(), "uniform sampler")));
    }
    if let Ok(d) = obj.cast::<PyDataSampler>() {
        let d = d.get();
        if d.nq != nq {
            return Err(err(Kind::Shape, format!("sampler: data rows of length {} for a model of nq = {nq}", d.nq)));
        }
        return Ok(Box::new(Shared(d.inner.clone(), "data sampler")));
    }
    if let Ok(g) = obj.cast::<PyGanSampler>() {
        let g = g.get();
        if g.generator.nq() != nq {
            return Err(err(Kind::Shape, format!("sampler: GAN makes configurations of length {} for a model of nq = {nq}", g.generator.nq())));
        }
        return Ok(Box::new(Shared(g.inner.clone(), "GAN sampler")));
    }
    if let Ok(f) = obj.cast::<PyFlowSampler>() {
        let f = f.get();
        if f.flow.nq() != nq {
            return Err(err(Kind::Shape, format!("sampler: the flow makes configurations of length {} for a model of nq = {nq}", f.flow.nq())));
        }
        return Ok(Box::new(Shared(f.inner.clone(), "flow sampler")));
    }
    if let Ok(m) = obj.cast::<PyMixtureSampler>() {
        let m = m.get();
        let primary = sampler_from(py, m.primary.bind(py), nq)?;
        let secondary = sampler_from(py, m.secondary.bind(py), nq)?;
        let seed = {
            let mut s = m.seed.lock().map_err(|_| PyRuntimeError::new_err("mixture sampler: lock poisoned"))?;
            *s = s.wrapping_add(1);
            *s
        };
        let mut mixture = MixtureSampler::new(primary, secondary, m.p, nq, seed).map_err(plan_error_to_py)?;
        if let Some(h) = m.half_life {
            mixture = mixture.with_half_life(h).map_err(plan_error_to_py)?;
        }
        return Ok(Box::new(mixture));
    }
    if obj.hasattr("sample")? {
        return Ok(Box::new(PySampler { obj: obj.clone().unbind(), nq }));
    }
    Err(PyTypeError::new_err(format!(
        "sampler: expected a genplan._core.UniformSampler / MixtureSampler or an object with sample(n), got {}",
        obj.get_type().name()?
    )))
}

// ---------------------------------------------------------------------------------------------
// The planner
// ---------------------------------------------------------------------------------------------

/// A named setting in Python: its name (`"crrt"`, `"rrt_connect"`; `"sampled"`, `"certified"`);
/// anything else is a SettingsError listing the known names.
fn named_from_py<T: Named>(v: &Bound<'_, PyAny>, what: &str) -> PyResult<T> {
    let known = T::NAMES.iter().map(|(n, _)| format!("'{n}'")).collect::<Vec<_>>().join(", ");
    let name: Option<String> = v.extract().ok();
    name.as_deref().and_then(T::from_name).ok_or_else(|| {
        let shown = v.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
        err(Kind::Settings, format!("{what}: unknown {} {shown} (known: {known})", T::WHAT))
    })
}

macro_rules! named_field {
    ($($t:ty),*) => {$(
        impl Field for $t {
            fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
                named_from_py(v, what)
            }
            fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                Ok(pyo3::types::PyString::new(py, self.name()).into_any())
            }
        }
    )*};
}

named_field!(Algorithm, EdgeCheck, Sampling);

settings_class!(
    /// Settings of the constrained planner (defaults: the GAN paper's cRRT and its public code,
    /// plus edge validation at 0.025 rad; `algorithm="rrt_connect"` for the bidirectional
    /// RRT-Connect). Immutable: `replace(**changes)` makes a changed copy.
    PyPlannerSettings,
    "PlannerSettings",
    Settings,
    |s: &Settings| s.validate().map_err(plan_error_to_py),
    [step, max_increments, max_jump, goal_tolerance, max_extensions, retries, project_samples, sample_batch,
     edge_resolution, lazy_edges, simplify, neighbors, max_empty_batches, algorithm, edge_check, sampling, time_limit,
     balance]
);

record_class!(
    /// What a plan cost: counts and times over all attempts (read-only).
    PyPlanStats,
    "PlanStats",
    Stats,
    [success, retries, extensions, projections, projection_calls, edge_projections, samples, samples_rejected,
     validity_checks, motion_certificates, chord_checks, nodes, pruned, shortcuts, timed_out, time_s, sampler_s, projector_s,
     checker_s, simplify_s]
);

/// A plan's outcome. `path` is dense: from the start to the goal reached (the start alone when
/// it is within `goal_tolerance` of a goal), every state is on the manifold and valid,
/// consecutive states at most 1.25 x `edge_resolution` apart (planning::MAX_SPACING), the chords
/// between them held to the chord tolerance when one was given; `waypoints` are the tree nodes
/// along it; `stats` what it cost.
#[pyclass(name = "PlanResult", module = "genplan._core", frozen)]
pub(crate) struct PyPlanResult {
    #[pyo3(get)]
    success: bool,
    #[pyo3(get)]
    path: Py<numpy::PyArray2<f64>>,
    #[pyo3(get)]
    waypoints: Py<numpy::PyArray2<f64>>,
    #[pyo3(get)]
    goal_index: Option<usize>,
    #[pyo3(get)]
    stats: Py<PyPlanStats>,
}

#[pymethods]
impl PyPlanResult {
    /// Wall-clock time of the plan (s).
    #[getter]
    fn time_s(&self) -> f64 {
        self.stats.get().inner.time_s
    }

    /// Optimisation steps of the projections of samples and extension steps (Table II's "Opt. Steps").
    #[getter]
    fn projections(&self) -> usize {
        self.stats.get().inner.projections
    }

    /// Iterations of the planner over all attempts (Table II's "E").
    #[getter]
    fn extensions(&self) -> usize {
        self.stats.get().inner.extensions
    }

    /// Attempts made after the first.
    #[getter]
    fn retries(&self) -> usize {
        self.stats.get().inner.retries
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let s = &self.stats.get().inner;
        format!(
            "PlanResult(success={}, goal_index={}, path={:?}, waypoints={}, time_s={:.4}, extensions={}, projections={})",
            if self.success { "True" } else { "False" },
            self.goal_index.map_or("None".to_string(), |g| g.to_string()),
            self.path.bind(py).shape(),
            self.waypoints.bind(py).shape()[0],
            s.time_s,
            s.extensions,
            s.projections
        )
    }
}

/// The constrained planner (the GAN paper's cRRT, Algorithm 1, or RRT-Connect: the settings'
/// `algorithm`); see genplan.planning for the front end.
#[pyclass(name = "Planner", module = "genplan._core", frozen)]
pub(crate) struct PyPlanner {
    inner: Planner,
    nq: usize,
    /// The model the start and goals are read for (`arrays::read_configurations`).
    model: Arc<KinematicModel>,
}

#[pymethods]
impl PyPlanner {
    #[new]
    #[pyo3(signature = (model, settings=None))]
    fn new(model: &PyKinematicModel, settings: Option<PyRef<'_, PyPlannerSettings>>) -> PyResult<Self> {
        let st = settings.map(|s| s.inner.clone()).unwrap_or_default();
        let space: Arc<dyn Space> = model.inner.clone();
        Ok(Self { inner: Planner::new(space, st).map_err(plan_error_to_py)?, nq: model.inner.nq, model: model.inner.clone() })
    }

    /// Plan from `start` (nq,) to any row of `goals` (k, nq). `chord_tolerance`: with a native
    /// projector, the chords between consecutive states of every edge are held to its primary
    /// terms' tolerances times this (GaussNewtonProjector::with_chord_tolerance); None: not
    /// checked (a Python projector's chords never are). `projector` None: free space, nothing
    /// projected (the checker alone says which states are valid).
    #[pyo3(signature = (start, goals, sampler, projector, checker, parallel=false, chord_tolerance=None))]
    #[allow(clippy::too_many_arguments)]
    fn plan<'py>(
        &self,
        py: Python<'py>,
        start: &Bound<'py, PyAny>,
        goals: &Bound<'py, PyAny>,
        sampler: &Bound<'py, PyAny>,
        projector: Option<&Bound<'py, PyAny>>,
        checker: &Bound<'py, PyAny>,
        parallel: bool,
        chord_tolerance: Option<f64>,
    ) -> PyResult<PyPlanResult> {
        let nq = self.nq;
        // read and checked here, before any work, as `as_configurations` would (the errors name
        // the argument); copied, since the plan runs without the GIL
        let q0 = read_configurations(start, &self.model, "start").map_err(|e| refused(py, e, Kind::InvalidStart))?;
        if let Some(n) = q0.rows {
            return Err(err(Kind::Shape, format!("start: expected shape ({nq},), got ({n}, {nq})")));
        }
        let start = q0.data().to_vec();
        let g = read_configurations(goals, &self.model, "goals").map_err(|e| refused(py, e, Kind::InvalidGoal))?;
        if g.rows == Some(0) {
            return Err(err(Kind::Shape, format!("goals: expected shape (k, {nq}) with k >= 1, got (0, {nq})")));
        }
        let goals = g.data().to_vec();
        let mut sampler = sampler_from(py, sampler, nq)?;
        let mut projector: Option<Box<dyn planning::Projector>> = match projector {
            None => None,
            Some(projector) => Some(projector_from(projector, nq, parallel, chord_tolerance)?),
        };
        let mut checker: Box<dyn ValidityChecker> = if let Ok(w) = checker.cast::<PyCollisionWorld>() {
            let world = &w.borrow().inner;
            if world.model.nq != nq {
                return Err(err(Kind::Generic, "checker: collision world built for another model"));
            }
            Box::new(CollisionChecker::new(Arc::clone(world), parallel))
        } else if let Ok(c) = checker.cast::<PySphereChecker>() {
            let spheres = &c.get().inner;
            if spheres.world.model.nq != nq {
                return Err(err(Kind::Generic, "checker: sphere checker built for another model"));
            }
            Box::new(SphereChecker::new(spheres.clone(), parallel, c.get().confirm))
        } else if checker.hasattr("is_valid")? {
            Box::new(PyChecker { obj: checker.clone().unbind(), nq })
        } else {
            return Err(PyTypeError::new_err(format!(
                "checker: expected a genplan._core.CollisionWorld, a genplan._core.SphereChecker or an object with is_valid(qs), got {}",
                checker.get_type().name()?
            )));
        };
        let planner = &self.inner;
        let solution = py
            .detach(|| {
                let mut last = Instant::now();
                let mut interrupt = move || -> PlanResult<()> {
                    if last.elapsed() < Duration::from_millis(50) {
                        return Ok(());
                    }
                    last = Instant::now();
                    Python::attach(|py| py.check_signals()).map_err(component_error)
                };
                let mut c = Components {
                    sampler: &mut *sampler,
                    projector: projector.as_deref_mut().map(|p| p as &mut dyn planning::Projector),
                    checker: &mut *checker,
                    interrupt: &mut interrupt,
                };
                planner.plan(&start, &goals, &mut c)
            })
            .map_err(plan_error_to_py)?;
        Ok(PyPlanResult {
            success: solution.success,
            path: into_array(py, solution.path, nq)?.unbind(),
            waypoints: into_array(py, solution.waypoints, nq)?.unbind(),
            goal_index: solution.goal_index,
            stats: Py::new(py, PyPlanStats { inner: solution.stats })?,
        })
    }
}

/// An error of reading a start or goals: a configuration the model refuses (a plain
/// GenplanError: a joint beyond its range of numbers, a zero base quaternion) is the plan's
/// `kind` (InvalidStartError, InvalidGoalError), with the same message; a ShapeError or
/// NonFiniteError (and anything else) as it is.
fn refused(py: Python<'_>, e: PyErr, kind: Kind) -> PyErr {
    if e.get_type(py).is(py.get_type::<crate::errors::GenplanError>()) {
        return err(kind, e.value(py).to_string());
    }
    e
}

/// The planner's projector from `projector`: a native `Projector` (its chords held to
/// `chord_tolerance` when given) or a Python object with `project(qs, q_noms)`.
fn projector_from(projector: &Bound<'_, PyAny>, nq: usize, parallel: bool, chord_tolerance: Option<f64>) -> PyResult<Box<dyn planning::Projector>> {
    if let Ok(p) = projector.cast::<PyProjector>() {
        let inner = &p.get().inner;
        if inner.model.nq != nq {
            return Err(err(Kind::Generic, "projector: built for another model"));
        }
        let native = GaussNewtonProjector::new(Arc::new(inner.clone()), parallel);
        Ok(Box::new(match chord_tolerance {
            Some(scale) => native.with_chord_tolerance(scale).map_err(plan_error_to_py)?,
            None => native,
        }))
    } else if projector.hasattr("project")? {
        Ok(Box::new(PyProjectorAdapter { obj: projector.clone().unbind(), nq }))
    } else {
        Err(PyTypeError::new_err(format!(
            "projector: expected a genplan._core.Projector or an object with project(qs, q_noms), got {}",
            projector.get_type().name()?
        )))
    }
}

/// The bytes the samples of a timed path `total` seconds long take at `rate` Hz with `n` joints,
/// at most (genplan_core::timing::sample_bytes: what `TimedPath.sample` checks against
/// `MAX_TRAJECTORY_BYTES` before it allocates).
#[pyfunction]
fn sample_bytes(total: f64, rate: f64, n: usize) -> f64 {
    genplan_core::timing::sample_bytes(total, rate, n)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sample_bytes, m)?)?;
    m.add("MAX_TRAJECTORY_BYTES", genplan_core::timing::MAX_SAMPLE_BYTES)?;
    // the names `PlannerSettings` takes, from the core's tables (the stub's Literal types are
    // checked against them)
    m.add("ALGORITHMS", PyTuple::new(m.py(), Algorithm::NAMES.iter().map(|(n, _)| *n))?)?;
    m.add("EDGE_CHECKS", PyTuple::new(m.py(), EdgeCheck::NAMES.iter().map(|(n, _)| *n))?)?;
    m.add("SAMPLINGS", PyTuple::new(m.py(), Sampling::NAMES.iter().map(|(n, _)| *n))?)?;
    m.add_class::<PyPlanner>()?;
    m.add_class::<PyPlannerSettings>()?;
    m.add_class::<PyPlanStats>()?;
    m.add_class::<PyPlanResult>()?;
    m.add_class::<PyUniformSampler>()?;
    m.add_class::<PyDataSampler>()?;
    m.add_class::<PyMixtureSampler>()?;
    m.add_class::<PyGanSampler>()?;
    m.add_class::<PyFlowSampler>()?;
    Ok(())
}

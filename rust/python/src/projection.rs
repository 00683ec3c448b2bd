//! `Projector` and `SolverSettings`: the core's damped Gauss-Newton projection
//! (`genplan_core::projection`), its terms read from dicts ([`term_from_dict`]) and the terms
//! written in Python behind the core's `CustomTerm` ([`PyCustomTerm`]).

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use genplan_core::projection::{Projector, Settings, Term, TermKind};

use crate::arrays;
use crate::batch::{batch, check_rows, chunked};
use crate::errors::{err, to_py, to_py_in, Kind};
use crate::kinematics::PyKinematicModel;
use crate::settings::settings_class;

settings_class!(
    /// Damped Gauss-Newton settings (defaults: the GAN paper and its public code). Immutable:
    /// `replace(**changes)` makes a changed copy.
    PySolverSettings,
    "SolverSettings",
    Settings,
    |s: &Settings| s.validate().map_err(to_py),
    [max_iterations, mu, mu_bar, armijo_c1, backtrack, max_backtracks, clip_to_limits, active_set, secondary_backtracks, secondary_slack]
);


/// The value of `key` in the dict `d`, a SettingsError naming `what` and the key when it is
/// missing or of the wrong type.
pub(crate) fn get<'py, T: pyo3::conversion::FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str, what: &str) -> PyResult<T> {
    match d.get_item(key)? {
        Some(v) => v.extract::<T>().map_err(|e| err(Kind::Settings, format!("{what}: '{key}': {}", Into::<PyErr>::into(e)))),
        None => Err(err(Kind::Settings, format!("{what}: missing '{key}'"))),
    }
}

/// [`get`], `default` when the key is missing or None.
pub(crate) fn get_or<'py, T: pyo3::conversion::FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str, default: T, what: &str) -> PyResult<T> {
    match d.get_item(key)? {
        Some(v) if !v.is_none() => v.extract::<T>().map_err(|e| err(Kind::Settings, format!("{what}: '{key}': {}", Into::<PyErr>::into(e)))),
        _ => Ok(default),
    }
}

/// A Python term behind the core's `projection::CustomTerm` (docs/TASKS.md, "Terms of your
/// own"): an object with `dim` (int), `residual(q)` ((n, nq) -> (n, dim)) and `jacobian(q)`
/// ((n, nq) -> (n, dim, nv)), and optionally `residual_and_jacobian(q)` returning both, called
/// where the solver needs both (unless the term dict's "combined" is false: what
/// `genplan.projection.CustomTerm` passes when a subclass keeps the default). The solver asks for one configuration at a time, so
/// each call passes a batch of one row (q of shape (1, nq)); each call takes the GIL for its own
/// duration only. Outputs of another shape raise ShapeError naming the term; non-finite ones are
/// refused by the core (NonFiniteError naming the term); an exception the object raises is
/// carried through the core's `TermFailure` and raised again unchanged ([`solve_error_to_py`]).
#[derive(Debug)]
struct PyCustomTerm {
    obj: Py<PyAny>,
    name: String,
    dim: usize,
    nq: usize,
    nv: usize,
    /// The object has `residual_and_jacobian`: one call where the solver needs both.
    combined: bool,
}

impl PyCustomTerm {
    /// `combined`: call `residual_and_jacobian` where both are needed (None: when the object has it).
    fn new(obj: &Bound<'_, PyAny>, name: &str, nq: usize, nv: usize, combined: Option<bool>) -> PyResult<Self> {
        let what = format!("custom term '{name}'");
        let dim = obj.getattr("dim").map_err(|e| err(Kind::Generic, format!("{what}: needs an attribute dim (int): {e}")))?;
        let dim: usize = dim
            .extract()
            .map_err(|_| err(Kind::Generic, format!("{what}: dim must be a positive int, got {}", dim.repr().map(|r| r.to_string()).unwrap_or_default())))?;
        let callable = |m: &str| obj.getattr(m).map(|a| a.is_callable()).unwrap_or(false);
        let combined = combined.unwrap_or(true) && callable("residual_and_jacobian");
        if !callable("residual") || !(combined || callable("jacobian")) {
            return Err(err(Kind::Generic, format!("{what}: needs methods residual(q) and jacobian(q) on batches (q of shape (n, nq))")));
        }
        Ok(PyCustomTerm { obj: obj.clone().unbind(), name: name.to_string(), dim, nq, nv, combined })
    }

    /// `value` as float64 numbers of shape `shape`, copied to `out` (row-major); `call` names the
    /// method in errors.
    fn copy_out(&self, py: Python<'_>, value: &Bound<'_, PyAny>, call: &str, shape: &[usize], out: &mut [f64]) -> PyResult<()> {
        let shown = arrays::shape_str; // as Python prints a shape: (2,) (1, 2)
        let bad = |got: String| {
            err(Kind::Shape, format!(
                "term '{}': {call} must return an array of shape {} for q of shape (1, {}), got {got}",
                self.name,
                shown(shape),
                self.nq
            ))
        };
        let arr = match value.extract::<PyReadonlyArrayDyn<'_, f64>>() {
            Ok(a) => a,
            Err(_) => py
                .import("numpy")?
                .call_method1("asarray", (value, "float64"))
                .and_then(|a| a.extract::<PyReadonlyArrayDyn<'_, f64>>())
                .map_err(|e| bad(format!("{} ({e})", value.get_type().name().map(|n| n.to_string()).unwrap_or_default())))?,
        };
        if arr.shape() != shape {
            return Err(bad(format!("shape {}", shown(arr.shape()))));
        }
        for (o, v) in out.iter_mut().zip(arr.as_array().iter()) {
            *o = *v;
        }
        Ok(())
    }
}

impl genplan_core::projection::CustomTerm for PyCustomTerm {
    fn dim(&self) -> usize {
        self.dim
    }

    fn evaluate(&self, q: &[f64], residual: &mut [f64], jacobian: Option<&mut [f64]>) -> Result<(), genplan_core::projection::TermError> {
        Python::attach(|py| -> PyResult<()> {
            let obj = self.obj.bind(py);
            let qa = Array::from_shape_vec(IxDyn(&[1, self.nq]), q.to_vec())
                .map_err(|e| PyValueError::new_err(e.to_string()))?
                .into_pyarray(py);
            let (d, nv) = (self.dim, self.nv);
            match jacobian {
                None => {
                    let r = obj.call_method1("residual", (qa,))?;
                    self.copy_out(py, &r, "residual(q)", &[1, d], residual)
                }
                Some(jac) => {
                    let (r, j) = if self.combined {
                        let both = obj.call_method1("residual_and_jacobian", (qa,))?;
                        let pair: (Bound<'_, PyAny>, Bound<'_, PyAny>) = both.extract().map_err(|_| {
                            err(Kind::Shape, format!("term '{}': residual_and_jacobian(q) must return a pair (residual, jacobian)", self.name))
                        })?;
                        pair
                    } else {
                        (obj.call_method1("residual", (qa.clone(),))?, obj.call_method1("jacobian", (qa,))?)
                    };
                    let what = if self.combined { ["residual_and_jacobian(q)[0]", "residual_and_jacobian(q)[1]"] } else { ["residual(q)", "jacobian(q)"] };
                    self.copy_out(py, &r, what[0], &[1, d], residual)?;
                    self.copy_out(py, &j, what[1], &[1, d, nv], jac)
                }
            }
        })
        .map_err(|e| Box::new(e) as genplan_core::projection::TermError)
    }
}

/// The projector holds a custom term (in these bindings, a Python one: [`PyCustomTerm`]).
pub(crate) fn has_python_terms(p: &Projector) -> bool {
    p.has_custom_terms()
}

/// The outcomes of a batch that stops at its first failed row (a custom term's error: the rows
/// after it are not run, None): the first failure raised as [`solve_error_to_py`] does, else every
/// row's outcome (None for a row not run).
pub(crate) fn first_failure<T>(outs: Vec<Option<Result<T, genplan_core::projection::SolveError>>>) -> PyResult<Vec<Option<T>>> {
    outs.into_iter().map(|o| o.transpose().map_err(solve_error_to_py)).collect()
}

/// The Python error of a failed solve: a custom term's own exception unchanged, a core error as
/// its `genplan.errors` class.
pub(crate) fn solve_error_to_py(e: genplan_core::projection::SolveError) -> PyErr {
    use genplan_core::projection::{SolveError, TermFailure};
    match e {
        SolveError::Input(e) => to_py(e),
        SolveError::Term(TermFailure { term, source }) => match source.downcast::<PyErr>() {
            Ok(py_err) => *py_err,
            Err(source) => to_py(TermFailure { term, source }.into_error()),
        },
    }
}

/// A term from its dict form (`type`, `name`, the kind's fields, `weight`, `tolerance`), as the
/// Python terms' `to_native()` write it.
fn term_from_dict(model: &genplan_core::KinematicModel, d: &Bound<'_, PyDict>) -> PyResult<Term> {
    let kind_name: String = get(d, "type", "term")?;
    let name: String = get_or(d, "name", kind_name.clone(), "term")?;
    let what = format!("term '{name}'");
    // the link named by field `key` ("link", "relative_to")
    let link_at = |key: &str| -> PyResult<usize> {
        let l: String = get(d, key, &what)?;
        model.link_index(&l).map_err(to_py)
    };
    let mat3 = |m: [[f64; 3]; 3]| Matrix3::from_fn(|i, j| m[i][j]);
    let vec3 = |key: &str| -> PyResult<nalgebra::Vector3<f64>> { Ok(nalgebra::Vector3::from(get::<[f64; 3]>(d, key, &what)?)) };
    // a 4x4 homogeneous "target" (its rotation block checked by the core's validation)
    let pose = || -> PyResult<Isometry3<f64>> {
        let t: [[f64; 4]; 4] = get(d, "target", &what)?;
        let rot = Rotation3::from_matrix_unchecked(Matrix3::from_fn(|i, j| t[i][j]));
        Ok(Isometry3::from_parts(Translation3::new(t[0][3], t[1][3], t[2][3]), UnitQuaternion::from_rotation_matrix(&rot)))
    };
    let kind = match kind_name.as_str() {
        "frame_pose" => TermKind::FramePose { link: link_at("link")?, target: pose()?, mask: get_or(d, "mask", [1.0; 6], &what)? },
        "relative_pose" => TermKind::RelativePose {
            link: link_at("link")?,
            relative_to: link_at("relative_to")?,
            target: pose()?,
            mask: get_or(d, "mask", [1.0; 6], &what)?,
        },
        "relative_position" => TermKind::RelativePosition {
            link: link_at("link")?,
            relative_to: link_at("relative_to")?,
            target: vec3("target")?,
            mask: get_or(d, "mask", [1.0; 3], &what)?,
        },
        "point_at" => TermKind::PointAt { link: link_at("link")?, axis: vec3("axis")?, point: vec3("point")? },
        "plane" => TermKind::Plane { link: link_at("link")?, normal: vec3("normal")?, offset: get(d, "offset", &what)? },
        "frame_position" => TermKind::FramePosition {
            link: link_at("link")?,
            target: nalgebra::Vector3::from(get::<[f64; 3]>(d, "target", &what)?),
            mask: get_or(d, "mask", [1.0; 3], &what)?,
        },
        "frame_orientation" => TermKind::FrameOrientation {
            link: link_at("link")?,
            target: mat3(get_or(d, "target", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], &what)?),
            offset: mat3(get_or(d, "offset", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], &what)?),
            mask: get_or(d, "mask", [1.0; 3], &what)?,
        },
        "joint_limits" => TermKind::JointLimits { margin: get_or(d, "margin", 1e-3, &what)? },
        "com_box" => TermKind::ComBox {
            lower: nalgebra::Vector3::from(get::<[f64; 3]>(d, "lower", &what)?),
            upper: nalgebra::Vector3::from(get::<[f64; 3]>(d, "upper", &what)?),
            margin: get_or(d, "margin", 1e-3, &what)?,
        },
        "posture" => TermKind::Posture {
            q_nom: get_or(d, "q_nom", None::<Vec<f64>>, &what)?,
            weights: get_or(d, "weights", vec![1.0; model.nv], &what)?,
            overrides: get_or(d, "overrides", Vec::<(usize, f64)>::new(), &what)?,
        },
        "custom" => {
            let obj = d.get_item("term")?.ok_or_else(|| err(Kind::Settings, format!("{what}: missing 'term' (the Python object)")))?;
            let combined: Option<bool> = get_or(d, "combined", None, &what)?;
            TermKind::Custom(Arc::new(PyCustomTerm::new(&obj, &name, model.nq, model.nv, combined)?))
        }
        other => {
            return Err(err(Kind::UnknownName, format!(
                "unknown term type '{other}' (known: frame_pose, frame_position, frame_orientation, relative_pose, relative_position, point_at, plane, joint_limits, com_box, posture, custom)"
            )))
        }
    };
    Ok(Term {
        name,
        kind,
        weight: get_or(d, "weight", 1.0, &what)?,
        tolerance: get_or(d, "tolerance", 1e-3, &what)?,
    })
}

/// Native damped Gauss-Newton projector (see genplan.projection for the Python front end).
#[pyclass(name = "Projector", module = "genplan._core", frozen)]
pub(crate) struct PyProjector {
    pub(crate) inner: Projector,
}

#[pymethods]
impl PyProjector {
    #[new]
    #[pyo3(signature = (model, primary, secondary=Vec::new(), settings=None))]
    fn new(
        model: &PyKinematicModel,
        primary: Vec<Bound<'_, PyDict>>,
        secondary: Vec<Bound<'_, PyDict>>,
        settings: Option<PyRef<'_, PySolverSettings>>,
    ) -> PyResult<Self> {
        let m = &*model.inner;
        let primary = primary.iter().map(|d| term_from_dict(m, d)).collect::<PyResult<Vec<_>>>()?;
        let secondary = secondary.iter().map(|d| term_from_dict(m, d)).collect::<PyResult<Vec<_>>>()?;
        let st = settings.map(|s| s.inner.clone()).unwrap_or_default();
        let inner = Projector::new(model.inner.clone(), primary, secondary, st).map_err(to_py)?;
        Ok(Self { inner })
    }

    #[getter]
    fn term_names(&self) -> Vec<String> {
        self.inner.primary.iter().map(|t| t.name.clone()).collect()
    }

    /// Solve from each row of q0 ((n, nq)); q_nom likewise or None. Returns
    /// (q (n, nq), success (n,), iterations (n,), residuals (n, terms), time_s (n,)).
    /// The rows run in parallel (GIL released) when `parallel`, unless a term is a Python one
    /// (then one after the other: see the comment in the body).
    #[pyo3(signature = (q0, q_nom=None, parallel=true, target_term=None, targets=None))]
    #[allow(clippy::type_complexity, clippy::too_many_arguments)]
    fn solve_batch<'py>(
        &self,
        py: Python<'py>,
        q0: PyReadonlyArrayDyn<'py, f64>,
        q_nom: Option<PyReadonlyArrayDyn<'py, f64>>,
        parallel: bool,
        target_term: Option<String>,
        targets: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<(
        Bound<'py, numpy::PyArrayDyn<f64>>,
        Bound<'py, numpy::PyArray1<bool>>,
        Bound<'py, numpy::PyArray1<i64>>,
        Bound<'py, numpy::PyArrayDyn<f64>>,
        Bound<'py, numpy::PyArray1<f64>>,
    )> {
        let m = &*self.inner.model;
        let b = batch(&q0, m.nq, "q0")?;
        check_rows(m, &b, "q0")?;
        let noms = match &q_nom {
            Some(a) => {
                let nb = batch(a, m.nq, "q_nom")?;
                if nb.lead != b.lead {
                    return Err(err(Kind::Shape, format!("q_nom: expected {} rows like q0, got {:?}", b.lead.first().copied().unwrap_or(1), nb.lead)));
                }
                check_rows(m, &nb, "q_nom")?; // configurations like q0 (finite, joint values bounded)
                Some(nb.data)
            }
            None => None,
        };
        let nq = m.nq;
        let n = b.data.len() / nq.max(1);
        let data = b.data;
        let solver = &self.inner;
        // per-row targets of one primary term: checked up front (the term, the numbers per row,
        // finite values), so that errors surface before any work; each worker retargets its own
        // copy of the solver row by row
        let retarget: Option<(usize, &[f64], usize)> = match (&target_term, &targets) {
            (None, None) => None,
            (Some(name), Some(arr)) => {
                let ti = solver.primary.iter().position(|t| &t.name == name).ok_or_else(|| {
                    err(Kind::UnknownName, format!("unknown target term '{name}' (primary terms: {:?})", solver.primary.iter().map(|t| &t.name).collect::<Vec<_>>()))
                })?;
                let tdata = arr.as_slice().map_err(|_| err(Kind::Shape, "targets: array must be C-contiguous"))?;
                if arr.shape().first().copied() != Some(n) {
                    return Err(err(Kind::Shape, format!("targets: expected {n} rows, got shape {:?}", arr.shape())));
                }
                let k: usize = arr.shape()[1..].iter().product();
                // every row as the solver takes it (length, finite, bounded, a rotation), before any work
                let mut probe = solver.clone();
                for i in 0..n {
                    probe.retarget(ti, &tdata[i * k..(i + 1) * k]).map_err(|e| to_py_in(&format!("targets[{i}]"), e))?;
                }
                Some((ti, tdata, k))
            }
            _ => return Err(err(Kind::Generic, "give both target_term and targets, or neither")),
        };
        // with a Python term the rows run one after the other: its calls serialise on the GIL, and
        // threads contending for it made batches slower, not faster (2 cores: 200 Panda rows with
        // a numpy-only term 0.12 s sequential vs 0.46 s parallel; with a Pinocchio-based term
        // 1.3-2.1 s vs 2.5-2.6 s). One retargeted copy of the solver per worker (not per row).
        // A custom term's failure
        // stops the batch: the rows after it are skipped (None) and its error is raised
        let failed = std::sync::atomic::AtomicBool::new(false);
        let parallel = parallel && !has_python_terms(solver);
        let outs = chunked(py, n, parallel, || retarget.map(|_| solver.clone()), |own, i| {
            use genplan_core::projection::SolveError;
            if failed.load(std::sync::atomic::Ordering::Relaxed) {
                return None;
            }
            let (q, nom) = (&data[i * nq..(i + 1) * nq], noms.map(|d| &d[i * nq..(i + 1) * nq]));
            let out = match (own, retarget) {
                (Some(p), Some((ti, t, k))) => p
                    .retarget(ti, &t[i * k..(i + 1) * k])
                    .map_err(SolveError::from)
                    .and_then(|()| p.try_solve_unchecked(q, nom).map_err(SolveError::from)),
                _ => solver.try_solve_unchecked(q, nom).map_err(SolveError::from),
            };
            if out.is_err() {
                failed.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            Some(out)
        })?;
        let outs: Vec<genplan_core::projection::Outcome> = first_failure(outs)?.into_iter().flatten().collect();
        let nt = solver.primary.len();
        let q = Array::from_shape_vec(IxDyn(&[n, nq]), outs.iter().flat_map(|o| o.q.iter().copied()).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let res = Array::from_shape_vec(IxDyn(&[n, nt]), outs.iter().flat_map(|o| o.residuals.iter().copied()).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((
            q.into_pyarray(py),
            outs.iter().map(|o| o.success).collect::<Vec<_>>().into_pyarray(py),
            outs.iter().map(|o| o.iterations as i64).collect::<Vec<_>>().into_pyarray(py),
            res.into_pyarray(py),
            outs.iter().map(|o| o.time_s).collect::<Vec<_>>().into_pyarray(py),
        ))
    }

    /// The primary terms' weighted residuals stacked, at each row of q ((n, nq)): r (n, m) and,
    /// when `jacobian`, their Jacobians J (n, m, nv) in the tangent space (a Posture term's
    /// nominal is the row itself). Rows run in parallel, GIL released (one after the other with a
    /// Python term, as in `solve_batch`).
    #[pyo3(signature = (q, jacobian=true))]
    #[allow(clippy::type_complexity)]
    fn primary_residuals<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        jacobian: bool,
    ) -> PyResult<(Bound<'py, numpy::PyArrayDyn<f64>>, Option<Bound<'py, numpy::PyArrayDyn<f64>>>)> {
        let m = &*self.inner.model;
        let b = batch(&q, m.nq, "q")?;
        check_rows(m, &b, "q")?;
        let (nq, nv, dim) = (m.nq, m.nv, self.inner.primary_dim());
        let n = b.data.len() / nq.max(1);
        let data = b.data;
        let solver = &self.inner;
        let parallel = !has_python_terms(solver); // as in solve_batch
        let outs = chunked(py, n, parallel, || (), |_, i| solver.try_primary_residuals(&data[i * nq..(i + 1) * nq], jacobian))?;
        let outs = outs.into_iter().collect::<Result<Vec<_>, _>>().map_err(solve_error_to_py)?;
        let r = Array::from_shape_vec(IxDyn(&[n, dim]), outs.iter().flat_map(|(r, _)| r.iter().copied()).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let j = if jacobian {
            let flat: Vec<f64> = outs
                .iter()
                .flat_map(|(_, j)| {
                    let j = j.as_ref().expect("jacobian computed");
                    (0..dim).flat_map(move |a| (0..nv).map(move |c| j[(a, c)]))
                })
                .collect();
            Some(Array::from_shape_vec(IxDyn(&[n, dim, nv]), flat).map_err(|e| PyValueError::new_err(e.to_string()))?.into_pyarray(py))
        } else {
            None
        };
        Ok((r.into_pyarray(py), j))
    }

    /// Frame Jacobian in the frame's own axes (6 x nv) at q: for cross-checks.
    fn frame_jacobian_local<'py>(&self, py: Python<'py>, q: Vec<f64>, link: &str) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let m = &*self.inner.model;
        let li = m.link_index(link).map_err(to_py)?;
        let mut poses = Vec::new();
        m.forward_kinematics(&q, &mut poses).map_err(to_py)?;
        let mut j = nalgebra::DMatrix::zeros(6, m.nv);
        m.frame_jacobian_local(&poses, li, &mut j);
        dmatrix_to_py(py, &j)
    }

    /// Centre of mass (3,) and its Jacobian (3 x nv) at q: for cross-checks.
    fn center_of_mass<'py>(&self, py: Python<'py>, q: Vec<f64>) -> PyResult<(Vec<f64>, Bound<'py, numpy::PyArrayDyn<f64>>)> {
        let m = &*self.inner.model;
        let mut poses = Vec::new();
        m.forward_kinematics(&q, &mut poses).map_err(to_py)?;
        let mut j = nalgebra::DMatrix::zeros(3, m.nv);
        let c = m.center_of_mass(&poses, Some(&mut j));
        Ok((vec![c.x, c.y, c.z], dmatrix_to_py(py, &j)?))
    }
}

/// A matrix as a 2-D float64 array.
fn dmatrix_to_py<'py>(py: Python<'py>, j: &nalgebra::DMatrix<f64>) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
    let (r, c) = j.shape();
    let data: Vec<f64> = (0..r).flat_map(|i| (0..c).map(move |k| j[(i, k)])).collect();
    Ok(Array::from_shape_vec(IxDyn(&[r, c]), data)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py))
}

/// Register the projection classes on `genplan._core`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyProjector>()?;
    m.add_class::<PySolverSettings>()
}

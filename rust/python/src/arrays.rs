//! The boundary of the per-configuration calls (forward kinematics, collision, distance):
//! configurations read once, in Rust, with the messages of `genplan._arrays.as_configurations`
//! (python/genplan/_arrays.py), and batched outputs written in place into a NumPy array
//! (issue 18, items 1-2).
//!
//! [`read_configurations`] takes a float64 or float32 NumPy array (any strides) or a flat
//! list/tuple of Python numbers without going through Python; anything else (other dtypes,
//! nested lists, strings, objects, complex numbers) is handed to `as_configurations` itself, so
//! every input gets the answer it got when the Python layer checked it. [`Output`] is a NumPy
//! array of the requested dtype (float64 or float32), new or the caller's `out=`, written from
//! the parallel workers without the GIL.

use numpy::ndarray::IxDyn;
use numpy::{
    Element, PyArrayDescr, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyFloat, PyInt, PyList, PyTuple};

use genplan_core::KinematicModel;

use crate::errors::{err, to_py_in, Kind};

/// A shape as Python prints a tuple: `()`, `(7,)`, `(2, 7)`.
pub(crate) fn shape_str(s: &[usize]) -> String {
    match s {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            s.iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// How numpy prints a non-finite float64.
fn non_finite_str(v: f64) -> &'static str {
    if v.is_nan() {
        "nan"
    } else if v > 0.0 {
        "inf"
    } else {
        "-inf"
    }
}

enum Data<'py> {
    Borrowed(PyReadonlyArrayDyn<'py, f64>),
    /// One row of a C-contiguous float64 array, read in place while the GIL is held.
    Row(Bound<'py, PyArrayDyn<f64>>),
    Owned(Vec<f64>),
}

/// Configurations read from Python: one row (`rows == None`, shape (nq,)) or a batch
/// (`rows == Some(n)`, shape (n, nq)), C-contiguous float64, finite and accepted by
/// [`KinematicModel::check_configuration`].
pub(crate) struct Configurations<'py> {
    data: Data<'py>,
    /// Rows of a batch; None for one configuration.
    pub(crate) rows: Option<usize>,
}

impl Configurations<'_> {
    /// The rows, flat (row-major, rows of nq).
    pub(crate) fn data(&self) -> &[f64] {
        match &self.data {
            Data::Borrowed(a) => a.as_slice().expect("checked C-contiguous"),
            Data::Owned(v) => v,
            // SAFETY: see `read_configurations`: a C-contiguous row, read with the GIL held
            Data::Row(a) => unsafe { a.as_slice() }.expect("checked C-contiguous"),
        }
    }
}

/// `genplan._arrays.as_configurations`, imported once.
fn python_reader(py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
    static READER: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    READER
        .get_or_try_init(py, || {
            Ok::<_, PyErr>(
                py.import("genplan._arrays")?
                    .getattr("as_configurations")?
                    .unbind(),
            )
        })
        .map(|f| f.bind(py))
}

fn shape_error(what: &str, nq: usize, shape: &[usize]) -> PyErr {
    err(
        Kind::Shape,
        format!(
            "{what}: expected shape ({nq},) or (n, {nq}), got {}",
            shape_str(shape)
        ),
    )
}

/// The rows of a numpy array of a float dtype, checked for shape; a copy unless it is
/// C-contiguous float64.
fn from_array<'py, T: Element + Copy + Into<f64>>(
    a: &Bound<'py, PyArrayDyn<T>>,
    nq: usize,
    what: &str,
    borrow: impl FnOnce(&Bound<'py, PyArrayDyn<T>>) -> Option<PyResult<Data<'py>>>,
) -> PyResult<(Data<'py>, Option<usize>)> {
    let shape = a.shape();
    if !(1..=2).contains(&shape.len()) || shape[shape.len() - 1] != nq {
        return Err(shape_error(what, nq, shape));
    }
    let rows = (shape.len() == 2).then(|| shape[0]);
    if let Some(d) = borrow(a) {
        return Ok((d?, rows));
    }
    let ro = a.try_readonly().map_err(|e| {
        err(
            Kind::Generic,
            format!("{what}: the array cannot be read ({e})"),
        )
    })?;
    // SAFETY of the view: borrowed read-only through numpy's borrow checker just above
    let owned: Vec<f64> = ro.as_array().iter().map(|&x| x.into()).collect();
    Ok((Data::Owned(owned), rows))
}

/// A flat list or tuple of exactly `nq` Python floats and ints (numpy's float64 scalars are
/// floats), as numpy would read it; None for anything else (left to the Python reader).
fn from_sequence(q: &Bound<'_, PyAny>, nq: usize) -> Option<Vec<f64>> {
    let items: Vec<Bound<'_, PyAny>> = if let Ok(l) = q.cast::<PyList>() {
        l.iter().collect()
    } else if let Ok(t) = q.cast::<PyTuple>() {
        t.iter().collect()
    } else {
        return None;
    };
    if items.len() != nq {
        return None;
    }
    items
        .iter()
        .map(|x| {
            if x.is_instance_of::<PyFloat>() || x.is_instance_of::<PyInt>() {
                x.extract::<f64>().ok()
            } else {
                None
            }
        })
        .collect()
}

/// `q` as configurations of `model` (shape (nq,) or (n, nq)), checked before any work: the
/// shape (ShapeError), every element finite (NonFiniteError naming the first, as
/// `as_configurations` does), then each row by [`KinematicModel::check_configuration`] (a zero
/// base quaternion, a joint beyond 1e16: the row named in a batch). `what` names the argument.
pub(crate) fn read_configurations<'py>(
    q: &Bound<'py, PyAny>,
    model: &KinematicModel,
    what: &str,
) -> PyResult<Configurations<'py>> {
    let nq = model.nq;
    let borrow = |a: &Bound<'py, PyArrayDyn<f64>>| {
        if !a.is_c_contiguous() {
            return None;
        }
        if a.ndim() == 1 {
            // One row, read in place while the GIL is held, without registering a borrow with
            // numpy's borrow checker (what that costs is a good part of a single call): read
            // as numpy itself reads it. A one-row call keeps the GIL until it returns, and no
            // call of this module writes an array without the GIL but a batch's `out=`
            // (borrowed through the checker), which is not this row's array
            return Some(Ok(Data::Row(a.clone())));
        }
        Some(a.try_readonly().map(Data::Borrowed).map_err(|e| {
            err(
                Kind::Generic,
                format!("{what}: the array cannot be read ({e})"),
            )
        }))
    };
    let (data, rows) = if let Ok(a) = q.cast::<PyArrayDyn<f64>>() {
        from_array(a, nq, what, borrow)?
    } else if let Ok(a) = q.cast::<PyArrayDyn<f32>>() {
        from_array(a, nq, what, |_| None)?
    } else if let Some(v) = from_sequence(q, nq) {
        (Data::Owned(v), None)
    } else {
        // every other input as the Python layer reads it (its errors, its conversions)
        let arr = python_reader(q.py())?.call1((q, nq, what))?;
        let a = arr.cast_into::<PyArrayDyn<f64>>().map_err(PyErr::from)?;
        from_array(&a, nq, what, borrow)?
    };
    let c = Configurations { data, rows };
    check(&c, model, what)?;
    Ok(c)
}

fn check(c: &Configurations<'_>, model: &KinematicModel, what: &str) -> PyResult<()> {
    let data = c.data();
    let nq = model.nq.max(1);
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        let at = match c.rows {
            None => format!("({i},)"),
            Some(_) => format!("({}, {})", i / nq, i % nq),
        };
        return Err(err(
            Kind::NonFinite,
            format!(
                "{what}: element {at} is not finite ({})",
                non_finite_str(data[i])
            ),
        ));
    }
    for (i, row) in data.chunks(nq).enumerate() {
        model.check_configuration(row).map_err(|e| match c.rows {
            None => to_py_in(what, e),
            Some(_) => to_py_in(&format!("{what}[{i}]"), e),
        })?;
    }
    Ok(())
}

/// The element type of an output: float64 or float32.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OutType {
    F64,
    F32,
}

/// An output element: what a float64 result is written as.
pub(crate) trait OutElement: Element + Copy + Send + Sync {
    fn from_f64(x: f64) -> Self;
}
impl OutElement for f64 {
    #[inline(always)]
    fn from_f64(x: f64) -> f64 {
        x
    }
}
impl OutElement for f32 {
    #[inline(always)]
    fn from_f64(x: f64) -> f32 {
        x as f32
    }
}

/// The `dtype=` argument: None (float64), or anything `numpy.dtype` reads as float64 or float32;
/// else SettingsError.
pub(crate) fn out_type(dtype: Option<&Bound<'_, PyAny>>) -> PyResult<Option<OutType>> {
    let Some(d) = dtype.filter(|d| !d.is_none()) else {
        return Ok(None);
    };
    let py = d.py();
    let bad = || {
        let shown = d.repr().map(|r| r.to_string()).unwrap_or_default();
        err(
            Kind::Settings,
            format!("dtype: expected float64 or float32, got {shown}"),
        )
    };
    let descr = PyArrayDescr::new(py, d).map_err(|_| bad())?;
    if descr.is_equiv_to(&numpy::dtype::<f64>(py)) {
        Ok(Some(OutType::F64))
    } else if descr.is_equiv_to(&numpy::dtype::<f32>(py)) {
        Ok(Some(OutType::F32))
    } else {
        Err(bad())
    }
}

/// An output array being written: a new one, or the caller's `out=` (checked).
pub(crate) struct Output<'py> {
    array: Array<'py>,
    /// Made here (not the caller's `out=`).
    fresh: bool,
}

enum Array<'py> {
    F64(Bound<'py, PyArrayDyn<f64>>),
    F32(Bound<'py, PyArrayDyn<f32>>),
}

impl<'py> Output<'py> {
    /// The array to write results of `shape` into: `out` if given (its shape exactly `shape`,
    /// C-contiguous, writeable, float64 or float32 and of `dtype` if that is given: else
    /// ShapeError naming `out`), else a new array of `dtype` (default float64).
    pub(crate) fn new(
        py: Python<'py>,
        shape: &[usize],
        dtype: Option<OutType>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Self> {
        let Some(out) = out.filter(|o| !o.is_none()) else {
            // SAFETY: every element is written (Output::write) before the array reaches Python
            let array = match dtype.unwrap_or(OutType::F64) {
                OutType::F64 => {
                    Array::F64(unsafe { PyArrayDyn::<f64>::new(py, IxDyn(shape), false) })
                }
                OutType::F32 => {
                    Array::F32(unsafe { PyArrayDyn::<f32>::new(py, IxDyn(shape), false) })
                }
            };
            return Ok(Output { array, fresh: true });
        };
        let arr = out.cast::<PyUntypedArray>().map_err(|_| {
            let ty = out
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default();
            err(
                Kind::Shape,
                format!("out: expected a numpy array, got {ty}"),
            )
        })?;
        if arr.shape() != shape {
            return Err(err(
                Kind::Shape,
                format!(
                    "out: expected shape {}, got {}",
                    shape_str(shape),
                    shape_str(arr.shape())
                ),
            ));
        }
        let (array, has) = if let Ok(a) = out.cast::<PyArrayDyn<f64>>() {
            (Array::F64(a.clone()), OutType::F64)
        } else if let Ok(a) = out.cast::<PyArrayDyn<f32>>() {
            (Array::F32(a.clone()), OutType::F32)
        } else {
            return Err(err(
                Kind::Shape,
                format!(
                    "out: expected dtype float64 or float32, got {}",
                    arr.dtype()
                ),
            ));
        };
        if let Some(want) = dtype.filter(|&w| w != has) {
            return Err(err(
                Kind::Shape,
                format!(
                    "out: its dtype is {}, but dtype={} was asked for",
                    arr.dtype(),
                    want.name()
                ),
            ));
        }
        if !arr.is_c_contiguous() {
            return Err(err(Kind::Shape, "out: the array must be C-contiguous"));
        }
        Ok(Output {
            array,
            fresh: false,
        })
    }

    /// Run `fill` on the flat data of the array and return the array. The caller's `out=` is
    /// borrowed for writing through numpy's borrow checker (ShapeError if it is not writeable
    /// or is being read by this call, e.g. as `q`); a new array is written directly.
    pub(crate) fn write(
        self,
        fill: impl FnOnce(Slot<'_>) -> PyResult<()>,
    ) -> PyResult<Bound<'py, PyAny>> {
        fn borrowed<'py, T: OutElement>(
            a: &Bound<'py, PyArrayDyn<T>>,
        ) -> PyResult<numpy::PyReadwriteArrayDyn<'py, T>> {
            a.try_readwrite().map_err(|e| {
                err(
                    Kind::Shape,
                    format!("out: the array cannot be written ({e})"),
                )
            })
        }
        if self.fresh {
            // SAFETY: made by Output::new and not yet handed to Python: nobody else holds it
            match &self.array {
                Array::F64(a) => fill(Slot::F64(
                    unsafe { a.as_slice_mut() }.expect("new arrays are contiguous"),
                ))?,
                Array::F32(a) => fill(Slot::F32(
                    unsafe { a.as_slice_mut() }.expect("new arrays are contiguous"),
                ))?,
            }
        } else {
            match &self.array {
                Array::F64(a) => fill(Slot::F64(
                    borrowed(a)?.as_slice_mut().expect("checked C-contiguous"),
                ))?,
                Array::F32(a) => fill(Slot::F32(
                    borrowed(a)?.as_slice_mut().expect("checked C-contiguous"),
                ))?,
            }
        }
        Ok(match self.array {
            Array::F64(a) => a.into_any(),
            Array::F32(a) => a.into_any(),
        })
    }
}

impl OutType {
    fn name(self) -> &'static str {
        match self {
            OutType::F64 => "float64",
            OutType::F32 => "float32",
        }
    }
}

/// The flat data of an [`Output`], of its element type.
pub(crate) enum Slot<'a> {
    F64(&'a mut [f64]),
    F32(&'a mut [f32]),
}

//! Settings and result records defined once, in the core's Rust structs, and exposed to Python
//! as typed, immutable classes: `settings_class!` makes a class whose keyword arguments,
//! defaults (from the struct's `Default`), attributes, `replace(**changes)`, `to_dict()`,
//! `__repr__` and `__eq__` all come from one field list; `record_class!` makes a read-only
//! record of a result struct. An unknown key, a value of the wrong type or out of range is a
//! `genplan.errors.SettingsError` naming the class and the field.

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};
use pyo3::IntoPyObjectExt;

use genplan_core::planning::NeighborIndex;

use crate::errors::{err, Kind};

/// One field's conversion between a Python value and the core's Rust type.
pub(crate) trait Field: Sized + Clone {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self>;
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>>;
}

fn bad(what: &str, expected: &str, v: &Bound<'_, PyAny>) -> PyErr {
    let shown = v.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
    err(Kind::Settings, format!("{what}: expected {expected}, got {shown}"))
}

impl Field for f64 {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if v.is_instance_of::<PyBool>() || v.is_instance_of::<PyString>() {
            return Err(bad(what, "a number", v));
        }
        v.extract::<f64>().map_err(|_| bad(what, "a number", v))
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.into_bound_py_any(py)
    }
}

impl Field for usize {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if v.is_instance_of::<PyBool>() {
            return Err(bad(what, "a whole number >= 0", v));
        }
        let i = v
            .call_method0("__index__")
            .and_then(|i| i.extract::<i128>())
            .map_err(|_| bad(what, "a whole number >= 0", v))?;
        usize::try_from(i).map_err(|_| bad(what, "a whole number >= 0", v))
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.into_bound_py_any(py)
    }
}

impl Field for bool {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        // numpy booleans too; an int or a string is not a flag
        if v.is_instance_of::<PyBool>() || v.get_type().name().map(|n| n == "bool" || n == "bool_").unwrap_or(false) {
            return v.is_truthy();
        }
        Err(bad(what, "True or False", v))
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.into_bound_py_any(py)
    }
}

impl Field for String {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if !v.is_instance_of::<PyString>() {
            return Err(bad(what, "a string", v));
        }
        v.extract::<String>()
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.into_bound_py_any(py)
    }
}

impl Field for Vec<f64> {
    /// A sequence (list, tuple, 1-D array) of numbers.
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if v.is_instance_of::<PyString>() {
            return Err(bad(what, "a sequence of numbers", v));
        }
        let items = v.try_iter().map_err(|_| bad(what, "a sequence of numbers", v))?;
        let mut out = Vec::new();
        for (i, item) in items.enumerate() {
            let item = item.map_err(|_| bad(what, "a sequence of numbers", v))?;
            out.push(f64::from_py(&item, &format!("{what}[{i}]"))?);
        }
        Ok(out)
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.into_bound_py_any(py)
    }
}

impl<const N: usize> Field for [f64; N] {
    /// A sequence of exactly N numbers.
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        let values = Vec::<f64>::from_py(v, what)?;
        let n = values.len();
        values.try_into().map_err(|_| err(Kind::Settings, format!("{what}: expected {N} numbers, got {n}")))
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_vec().into_bound_py_any(py)
    }
}

impl Field for [[f64; 3]; 3] {
    /// A 3x3 matrix: three rows of three numbers (nested sequences or a (3, 3) array).
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        let shape_error = || bad(what, "a 3x3 matrix (three rows of three numbers)", v);
        if v.is_instance_of::<PyString>() {
            return Err(shape_error());
        }
        let rows = v.try_iter().map_err(|_| shape_error())?;
        let mut out = Vec::with_capacity(3);
        for (r, row) in rows.enumerate() {
            let row = row.map_err(|_| shape_error())?;
            out.push(<[f64; 3]>::from_py(&row, &format!("{what}[{r}]"))?);
        }
        out.try_into().map_err(|_| shape_error())
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.iter().map(|r| r.to_vec()).collect::<Vec<_>>().into_bound_py_any(py)
    }
}

impl<T: Field> Field for Option<T> {
    /// None, or a value of `T`.
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if v.is_none() {
            return Ok(None);
        }
        T::from_py(v, what).map(Some)
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match self {
            None => Ok(py.None().into_bound(py)),
            Some(x) => x.to_py(py),
        }
    }
}

/// The names of [`NeighborIndex`] in Python.
const NEIGHBORS: [(&str, NeighborIndex); 3] = [
    ("auto", NeighborIndex::Auto),
    ("linear", NeighborIndex::Linear),
    ("kdtree", NeighborIndex::KdForest),
];

impl Field for NeighborIndex {
    fn from_py(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        let s: String = v.extract().map_err(|_| bad(what, "'auto', 'linear' or 'kdtree'", v))?;
        NEIGHBORS
            .iter()
            .find(|(n, _)| *n == s)
            .map(|(_, k)| *k)
            .ok_or_else(|| bad(what, "'auto', 'linear' or 'kdtree'", v))
    }
    fn to_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let name = NEIGHBORS.iter().find(|(_, k)| k == self).map(|(n, _)| *n).unwrap_or("auto");
        name.into_bound_py_any(py)
    }
}

/// `repr` of a record: `Name(a=1, b=2.0)`.
pub(crate) fn record_repr(name: &str, d: &Bound<'_, PyDict>) -> PyResult<String> {
    let mut parts = Vec::with_capacity(d.len());
    for (k, v) in d.iter() {
        parts.push(format!("{}={}", k, v.repr()?));
    }
    Ok(format!("{name}({})", parts.join(", ")))
}

/// A frozen Python class over a core settings struct: keyword-only constructor with the
/// struct's defaults, one read-only attribute per field, `replace(**changes)`, `to_dict()`,
/// `__repr__`, `__eq__` and pickling. `$validate` checks the whole struct after every change and
/// returns a `PyResult<()>`.
macro_rules! settings_class {
    ($(#[$doc:meta])* $py:ident, $pyname:literal, $core:ty, $validate:expr, [$($field:ident),* $(,)?]) => {
        settings_class!($(#[$doc])* $py, $pyname, $core, $validate, [$($field),*], {});
    };
    ($(#[$doc:meta])* $py:ident, $pyname:literal, $core:ty, $validate:expr, [$($field:ident),* $(,)?], { $($extra:tt)* }) => {
        $(#[$doc])*
        #[pyclass(name = $pyname, module = "genplan._core", frozen)]
        #[derive(Clone)]
        pub(crate) struct $py {
            pub(crate) inner: $core,
        }

        impl $py {
            /// The field names, in declaration order.
            pub(crate) const FIELDS: &'static [&'static str] = &[$(stringify!($field)),*];

            fn with_changes(mut inner: $core, changes: Option<&Bound<'_, pyo3::types::PyDict>>) -> PyResult<Self> {
                if let Some(changes) = changes {
                    for (k, v) in changes.iter() {
                        let key: String = k.extract()?;
                        match key.as_str() {
                            $(stringify!($field) => {
                                inner.$field = $crate::settings::Field::from_py(&v, concat!($pyname, ".", stringify!($field)))?;
                            })*
                            other => {
                                return Err($crate::errors::err(
                                    $crate::errors::Kind::Settings,
                                    format!("{}: unknown setting '{}' (known: {})", $pyname, other, Self::FIELDS.join(", ")),
                                ))
                            }
                        }
                    }
                }
                ($validate)(&inner)?;
                Ok(Self { inner })
            }
        }

        #[pymethods]
        impl $py {
            #[new]
            #[pyo3(signature = (**changes))]
            fn py_new(changes: Option<&Bound<'_, pyo3::types::PyDict>>) -> PyResult<Self> {
                Self::with_changes(<$core>::default(), changes)
            }

            /// A copy with the given fields changed (validated like the constructor).
            #[pyo3(signature = (**changes))]
            fn replace(&self, changes: Option<&Bound<'_, pyo3::types::PyDict>>) -> PyResult<Self> {
                Self::with_changes(self.inner.clone(), changes)
            }

            /// Every field and its value.
            fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
                let d = pyo3::types::PyDict::new(py);
                $(d.set_item(stringify!($field), $crate::settings::Field::to_py(&self.inner.$field, py)?)?;)*
                Ok(d)
            }

            /// The field names, in declaration order.
            #[classattr]
            fn fields() -> Vec<&'static str> {
                Self::FIELDS.to_vec()
            }

            fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
                $crate::settings::record_repr($pyname, &self.to_dict(py)?)
            }

            fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> PyResult<bool> {
                match other.cast::<Self>() {
                    Ok(o) => self.to_dict(py)?.eq(o.get().to_dict(py)?),
                    Err(_) => Ok(false),
                }
            }

            /// Pickling: the class called with every field as a keyword.
            fn __getnewargs_ex__<'py>(&self, py: Python<'py>) -> PyResult<((), Bound<'py, pyo3::types::PyDict>)> {
                Ok(((), self.to_dict(py)?))
            }

            $(
                #[getter]
                fn $field<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                    $crate::settings::Field::to_py(&self.inner.$field, py)
                }
            )*

            $($extra)*
        }
    };
}

/// A frozen, read-only Python record over a core result struct: one attribute per field,
/// `to_dict()` and `__repr__`.
macro_rules! record_class {
    ($(#[$doc:meta])* $py:ident, $pyname:literal, $core:ty, [$($field:ident),* $(,)?]) => {
        $(#[$doc])*
        #[pyclass(name = $pyname, module = "genplan._core", frozen)]
        #[derive(Clone)]
        pub(crate) struct $py {
            pub(crate) inner: $core,
        }

        #[pymethods]
        impl $py {
            /// Every field and its value.
            fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
                let d = pyo3::types::PyDict::new(py);
                $(d.set_item(stringify!($field), &self.inner.$field)?;)*
                Ok(d)
            }

            /// The field names, in declaration order.
            #[classattr]
            fn fields() -> Vec<&'static str> {
                vec![$(stringify!($field)),*]
            }

            fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
                $crate::settings::record_repr($pyname, &self.to_dict(py)?)
            }

            /// Deprecated: `record["name"]` (results were dicts up to 0.1.0); use `record.name`.
            fn __getitem__(&self, py: Python<'_>, key: &str) -> PyResult<Py<PyAny>> {
                let msg = format!("{}[{:?}] is deprecated: use .{} or .to_dict()", $pyname, key, key);
                py.import("warnings")?.call_method1(
                    "warn",
                    (msg, py.get_type::<pyo3::exceptions::PyDeprecationWarning>(), 2),
                )?;
                match self.to_dict(py)?.get_item(key)? {
                    Some(v) => Ok(v.unbind()),
                    None => Err(pyo3::exceptions::PyKeyError::new_err(key.to_string())),
                }
            }

            $(
                #[getter]
                fn $field(&self) -> PyResult<Py<PyAny>> {
                    Python::attach(|py| pyo3::IntoPyObjectExt::into_py_any(self.inner.$field.clone(), py))
                }
            )*
        }
    };
}

pub(crate) use record_class;
pub(crate) use settings_class;

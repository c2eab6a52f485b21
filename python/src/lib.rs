//! `ipfn._ipfn`: the compiled part of the `ipfn` Python package. Every call fills one of the
//! library's requests (`SynthRequest`, `TrainRequest`, `FitRequest`, `EvalRequest`) and returns
//! numpy arrays or plain Python values; `python/ipfn/__init__.py` adds the keyword arguments'
//! conversions and the docstrings a Python user reads.
//!
//! Long calls release the GIL; errors become `ipfn.InputError` (bad input, a `ValueError`) or
//! `ipfn.IpfnError` with the command line's one-line message; a panic becomes `IpfnError` too.

mod eval;
mod fit;
mod model;
mod train;

use pyo3::prelude::*;
use pyo3::types::PyType;

/// The module `ipfn._ipfn`.
#[pymodule]
fn _ipfn(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<model::Model>()?;
    m.add_function(wrap_pyfunction!(model::load, m)?)?;
    m.add_function(wrap_pyfunction!(train::train, m)?)?;
    m.add_function(wrap_pyfunction!(train::write_image, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(eval::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(eval::compare_images, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

/// The Python exception for a library error: `InputError` for bad input, else `IpfnError`
/// (both defined in `ipfn._errors`, so that `InputError` is also a `ValueError`).
pub(crate) fn to_py(e: ipfn::Error) -> PyErr {
    let name = match e.is_input() {
        true => "InputError",
        false => "IpfnError",
    };
    raise(name, e.to_string())
}

/// An `ipfn._errors` exception by name.
pub(crate) fn raise(name: &str, message: String) -> PyErr {
    Python::attach(|py| {
        let class = py
            .import("ipfn._errors")
            .and_then(|m| m.getattr(name))
            .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
        match class {
            Ok(class) => PyErr::from_type(class, message),
            Err(e) => e,
        }
    })
}

/// Runs `f`, turning a panic into `IpfnError` (a panic must not cross into Python as a
/// `BaseException` that `except Exception` misses).
pub(crate) fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown");
            Err(raise(
                "IpfnError",
                format!("internal error (a bug in ipfn; please report it): {what}"),
            ))
        }
    }
}

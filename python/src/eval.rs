//! `ipfn.evaluate` and `ipfn.compare_images`: the JSON `ipfn eval --json` prints.

use std::path::PathBuf;

use pyo3::prelude::*;

use ipfn::device::DeviceChoice;
use ipfn::eval::EvalRequest;

use crate::model::Model;
use crate::{guard, to_py};

/// A model's report against its exemplar, as JSON.
#[pyfunction]
#[pyo3(signature = (model, exemplar, *, samples=8, seed=0, device="cpu"))]
pub fn evaluate(
    py: Python<'_>,
    model: &Model,
    exemplar: PathBuf,
    samples: usize,
    seed: u64,
    device: &str,
) -> PyResult<String> {
    let request = EvalRequest {
        exemplar,
        samples,
        seed,
        device: DeviceChoice::resolve(device).map_err(to_py)?,
    };
    let report = py.detach(|| guard(|| request.evaluate(&model.file).map_err(to_py)))?;
    serde_json::to_string(&report).map_err(|e| crate::raise("IpfnError", format!("report: {e}")))
}

/// SIFID of image A to image B and B's structure distance to A, as JSON.
#[pyfunction]
pub fn compare_images(py: Python<'_>, a: PathBuf, b: PathBuf) -> PyResult<String> {
    let report = py.detach(|| guard(|| ipfn::eval::compare_images(&a, &b).map_err(to_py)))?;
    serde_json::to_string(&report).map_err(|e| crate::raise("IpfnError", format!("report: {e}")))
}

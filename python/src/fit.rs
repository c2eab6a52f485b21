//! `ipfn.fit`: a `FitRequest` run with the GIL released; Ctrl-C stops it after a checkpoint.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use pyo3::prelude::*;

use ipfn::fit::request::{FitOutcome, FitRequest, OpenedFit};

use crate::{guard, to_py};

/// Fits a tile; returns the JSON of its report with the files written.
#[pyfunction]
#[pyo3(signature = (*, photo=None, maps=None, period=None, time=None, iterations=None,
    run=None, out=None, resume=None, mask=None, bits=None, device="auto".to_string(), seed=None))]
#[allow(clippy::too_many_arguments)]
pub fn fit(
    py: Python<'_>,
    photo: Option<PathBuf>,
    maps: Option<Vec<PathBuf>>,
    period: Option<(usize, usize)>,
    time: Option<String>,
    iterations: Option<u64>,
    run: Option<PathBuf>,
    out: Option<PathBuf>,
    resume: Option<PathBuf>,
    mask: Option<PathBuf>,
    bits: Option<u8>,
    device: String,
    seed: Option<u64>,
) -> PyResult<String> {
    let request = FitRequest {
        photo,
        maps: maps.map(ipfn::maps::MapSetRequest::files),
        period: period.map(|(w, h)| [h, w]),
        time,
        iterations,
        run,
        out,
        resume,
        mask,
        bits,
        device,
        seed,
        ..FitRequest::default()
    };
    let stop = AtomicBool::new(false);
    let mut interrupted: Option<PyErr> = None;
    let outcome = py.detach(|| {
        guard(|| {
            let OpenedFit {
                mut fitter,
                deadline,
                ..
            } = request.open().map_err(to_py)?;
            fitter
                .run(&stop, deadline, |_| {
                    if interrupted.is_none()
                        && let Err(e) = Python::attach(|py| py.check_signals())
                    {
                        interrupted = Some(e);
                        stop.store(true, Ordering::SeqCst);
                    }
                })
                .map_err(to_py)?;
            request.finish(&fitter).map_err(to_py)
        })
    })?;
    if let Some(e) = interrupted {
        return Err(e);
    }
    let FitOutcome {
        model,
        images,
        report,
    } = outcome;
    let mut json = serde_json::to_value(&report)
        .map_err(|e| crate::raise("IpfnError", format!("report: {e}")))?;
    json["model"] = serde_json::json!(model);
    json["images"] = serde_json::json!(images);
    Ok(json.to_string())
}

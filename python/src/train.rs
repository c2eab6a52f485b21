//! `ipfn.train`: a `TrainRequest` run with the GIL released, progress reported to a Python
//! callback after every iteration, Ctrl-C and a callback's `False` stopping it after a
//! checkpoint, as the command line stops on Ctrl-C.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use ipfn::train::request::{OpenedRun, TrainRequest};
use ipfn::train::{IterationStats, RunEnd, Trainer};

use crate::{guard, to_py};

/// Trains (or resumes) a run; returns the run folder. `settings` is TOML text of config keys.
#[pyfunction]
#[pyo3(signature = (*, exemplar=None, maps=None, config=None, settings=None, out=None,
    resume=None, device="auto".to_string(), on_progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn train(
    py: Python<'_>,
    exemplar: Option<PathBuf>,
    maps: Option<Vec<PathBuf>>,
    config: Option<PathBuf>,
    settings: Option<String>,
    out: Option<PathBuf>,
    resume: Option<PathBuf>,
    device: String,
    on_progress: Option<Py<PyAny>>,
) -> PyResult<PathBuf> {
    let request = TrainRequest {
        exemplar,
        maps: maps.map(ipfn::maps::MapSetRequest::files),
        config,
        settings,
        out,
        resume,
        device,
        ..TrainRequest::default()
    };
    let stop = AtomicBool::new(false);
    let mut raised: Option<PyErr> = None;
    let (end, run_dir) = py.detach(|| {
        guard(|| {
            let OpenedRun { mut trainer, .. } = request.open().map_err(to_py)?;
            let end = trainer.run(&stop, |trainer, stats| {
                if raised.is_none()
                    && let Err(e) = report(trainer, stats, on_progress.as_ref(), &stop)
                {
                    raised = Some(e);
                    stop.store(true, Ordering::SeqCst);
                }
            });
            Ok((end.map_err(to_py)?, trainer.run_dir().to_path_buf()))
        })
    })?;
    // A stop asked for by the callback's `False` ends the run as a finished one does; Ctrl-C
    // (KeyboardInterrupt) and the callback's own exceptions are raised after the checkpoint.
    match raised {
        Some(e) => Err(e),
        None => {
            let _: RunEnd = end;
            Ok(run_dir)
        }
    }
}

/// Writes an image array (`[H, W, C]`, values in [-1, 1]) as the path's format (PNG of `bits`,
/// EXR, NPY), atomically; also how a numpy exemplar becomes the file a run reads.
#[pyfunction]
#[pyo3(signature = (path, values, bits=8))]
pub fn write_image(
    path: PathBuf,
    values: numpy::PyReadonlyArray3<'_, f32>,
    bits: u8,
) -> PyResult<()> {
    let [h, w, c] = [0, 1, 2].map(|a| values.shape()[a]);
    let values = values.as_array().iter().copied().collect::<Vec<f32>>();
    guard(|| {
        let format = ipfn::io::OutputFormat::from_path(&path, bits).map_err(to_py)?;
        format.check_size(&path, w, h, c).map_err(to_py)?;
        let mut writer = ipfn::io::ImageWriter::create(&path, format, w, h, c).map_err(to_py)?;
        writer.write_rows(&values).map_err(to_py)?;
        writer.finish().map_err(to_py)
    })
}

/// Checks for Ctrl-C, then calls `on_progress` with the iteration's figures; its `False` asks
/// the run to stop after a checkpoint.
fn report(
    trainer: &Trainer,
    stats: &IterationStats,
    on_progress: Option<&Py<PyAny>>,
    stop: &AtomicBool,
) -> PyResult<()> {
    Python::attach(|py| {
        py.check_signals()?;
        let Some(callback) = on_progress else {
            return Ok(());
        };
        let info = PyDict::new(py);
        info.set_item("iteration", stats.iteration)?;
        info.set_item("iterations", trainer.config.iterations)?;
        info.set_item("wasserstein", stats.wasserstein)?;
        info.set_item("penalty", stats.penalty)?;
        info.set_item("generator_loss", stats.generator_loss)?;
        info.set_item("k", stats.k.clone())?;
        info.set_item("iterations_per_second", stats.iterations_per_second)?;
        info.set_item("sifid", stats.sifid)?;
        info.set_item("structure", stats.structure)?;
        info.set_item("repeat", stats.repeat)?;
        info.set_item("map_structure", stats.map_structure.clone())?;
        info.set_item("run_dir", trainer.run_dir())?;
        info.set_item("preview", preview(py, trainer, stats.iteration)?)?;
        let answer = callback.call1(py, (info,))?;
        if answer.bind(py).is(pyo3::types::PyBool::new(py, false)) {
            stop.store(true, Ordering::SeqCst);
        }
        Ok(())
    })
}

/// The preview written at this iteration, as a float32 array in [-1, 1] (`None` between
/// previews).
fn preview<'py>(
    py: Python<'py>,
    trainer: &Trainer,
    iteration: u64,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let path = trainer
        .run_dir()
        .join("previews")
        .join(format!("iter-{iteration:06}.png"));
    if !path.is_file() {
        return Ok(None);
    }
    let image = ipfn::exemplar::read_exemplar(&path).map_err(to_py)?;
    let shape = [image.height, image.width, image.channels];
    let array = ArrayD::from_shape_vec(IxDyn(&shape), image.values)
        .map_err(|e| crate::raise("IpfnError", format!("preview: {e}")))?;
    Ok(Some(array.into_pyarray(py).into_any()))
}

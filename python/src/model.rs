//! `ipfn.load` and `Model`: a model file of any kind, its attributes, and `Model.paint`.

use std::path::PathBuf;

use numpy::IntoPyArray;
use numpy::ndarray::{ArrayD, IxDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use ipfn::device::DeviceChoice;
use ipfn::model::{ModelFile, ModelKind};
use ipfn::paint::Painted;
use ipfn::paint::SynthRequest;

use crate::{guard, to_py};

/// A trained generator or a fitted tile, read once from its file.
#[pyclass(frozen, module = "ipfn", name = "Model")]
pub struct Model {
    pub(crate) file: ModelFile,
    path: Option<PathBuf>,
}

/// Reads a model file (or a run folder's best model); no path: the shipped honeycomb.
#[pyfunction]
#[pyo3(signature = (path=None))]
pub fn load(py: Python<'_>, path: Option<PathBuf>) -> PyResult<Model> {
    py.detach(|| guard(|| Model::read(path)))
}

impl Model {
    pub(crate) fn read(path: Option<PathBuf>) -> PyResult<Self> {
        // A run folder is read as the model file it paints with, and `path` names that file.
        let path = path.map(|p| match p.is_dir() {
            true => ipfn::model::run_model(&p).unwrap_or(p),
            false => p,
        });
        let file = match &path {
            Some(p) => ipfn::model::load_model(Some(p), std::path::Path::new(".")),
            None => ipfn::model::load_shipped().map(ModelFile::Generator),
        }
        .map_err(to_py)?;
        Ok(Self { file, path })
    }
}

#[pymethods]
impl Model {
    /// `image`, `map_set`, `solid`, `volume` or `tile`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.file.kind().name()
    }

    /// Channels painted (all maps' together for a map set).
    #[getter]
    fn channels(&self) -> usize {
        match &self.file {
            ModelFile::Generator(m) => m.config.channels,
            ModelFile::Tile { checkpoint, .. } => ipfn::fit::PeriodicNet::read_from(checkpoint)
                .map(|n| n.shape.channels)
                .unwrap_or(0),
        }
    }

    /// The maps' names of a map set, in order; empty otherwise.
    #[getter]
    fn map_names(&self) -> Vec<String> {
        match &self.file {
            ModelFile::Generator(m) => m
                .maps
                .iter()
                .flat_map(|s| s.maps.iter().map(|m| m.name.clone()))
                .collect(),
            ModelFile::Tile { checkpoint, .. } => {
                ipfn::maps::MapSet::read_from(checkpoint, std::path::Path::new("tile"))
                    .ok()
                    .flatten()
                    .map(|s| s.maps.iter().map(|m| m.name.clone()).collect())
                    .unwrap_or_default()
            }
        }
    }

    /// Each map's part in a material, from its file's name ("color", "normal", "height",
    /// "roughness", "ambient_occlusion", "metalness", or None), in `map_names` order.
    #[getter]
    fn map_roles(&self) -> Vec<Option<&'static str>> {
        let set = match &self.file {
            ModelFile::Generator(m) => m.maps.clone(),
            ModelFile::Tile { checkpoint, .. } => {
                ipfn::maps::MapSet::read_from(checkpoint, std::path::Path::new("tile"))
                    .ok()
                    .flatten()
            }
        };
        set.map(|s| s.maps.iter().map(|m| m.role.map(|r| r.name())).collect())
            .unwrap_or_default()
    }

    /// The pattern's period in pixels, in array order (rows, columns; depth first for a 3D
    /// model): a generator's octave-0 period, a tile's own period.
    #[getter]
    fn period(&self) -> Vec<f64> {
        match &self.file {
            ModelFile::Generator(m) => m
                .weights
                .k
                .iter()
                .map(|k| (k.abs() * m.config.crop as f32) as f64)
                .collect(),
            ModelFile::Tile { checkpoint, .. } => ipfn::fit::PeriodicNet::read_from(checkpoint)
                .map(|n| n.shape.period.iter().map(|&p| p as f64).collect())
                .unwrap_or_default(),
        }
    }

    /// The training iteration the file was written at (`None` for an imported model or a tile).
    #[getter]
    fn iteration(&self) -> Option<u64> {
        match &self.file {
            ModelFile::Generator(m) => m.iteration,
            ModelFile::Tile { .. } => None,
        }
    }

    /// Where the model came from, as `ipfn synth` prints it.
    #[getter]
    fn description(&self) -> &str {
        self.file.description()
    }

    /// The file it was read from (a run folder's best or latest model; `None` for the shipped
    /// honeycomb).
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.path.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "<ipfn.Model {} ({} channels): {}>",
            self.kind(),
            self.channels(),
            self.description()
        )
    }

    /// Paints `width` x `height` pixels; see `ipfn.Model.paint` in `ipfn/__init__.pyi`.
    #[pyo3(signature = (width, height, *, seed=0, offset=(0, 0), zoom=1.0, noise_scale=1.0,
        tile=false, mirror=false, device="auto", depth=None, slice=None, guide=None,
        density=None, lod=None))]
    #[allow(clippy::too_many_arguments)]
    fn paint<'py>(
        &self,
        py: Python<'py>,
        width: usize,
        height: usize,
        seed: u64,
        offset: (i64, i64),
        zoom: f64,
        noise_scale: f64,
        tile: bool,
        mirror: bool,
        device: &str,
        depth: Option<usize>,
        slice: Option<(char, usize)>,
        guide: Option<String>,
        density: Option<(f32, f32)>,
        lod: Option<f32>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let device = DeviceChoice::resolve(device).map_err(to_py)?;
        let solid = matches!(self.file.kind(), ModelKind::Solid);
        // A solid texture paints its z = 0 plane unless a volume or another plane is asked for.
        let slice = match (solid, depth, slice) {
            (true, None, None) => Some(('z', 0)),
            (_, _, given) => given,
        };
        let request = SynthRequest {
            width: Some(width),
            height: Some(height),
            depth,
            slice,
            solid,
            density,
            seed,
            zoom,
            offset: (offset != (0, 0)).then_some(offset),
            tile,
            mirror,
            noise_scale,
            guide,
            device,
            lod,
            ..SynthRequest::default()
        };
        let painted = py.detach(|| {
            guard(|| {
                let plan = request.plan(&self.file).map_err(to_py)?;
                plan.render().map_err(to_py)
            })
        })?;
        arrays(py, painted)
    }
}

/// One array, or a dict of one array per map for a map set.
fn arrays(py: Python<'_>, painted: Vec<Painted>) -> PyResult<Bound<'_, PyAny>> {
    let array = |p: Painted| -> PyResult<Bound<'_, PyAny>> {
        let array = ArrayD::from_shape_vec(IxDyn(&p.shape), p.values)
            .map_err(|e| crate::raise("IpfnError", format!("painted array: {e}")))?;
        Ok(array.into_pyarray(py).into_any())
    };
    let named = painted.len() > 1 || painted.first().is_some_and(|p| p.name.is_some());
    if !named {
        let first = painted.into_iter().next();
        return array(first.expect("a plan paints at least one array"));
    }
    let dict = PyDict::new(py);
    for p in painted {
        let name = p.name.clone().unwrap_or_default();
        dict.set_item(name, array(p)?)?;
    }
    Ok(dict.into_any())
}

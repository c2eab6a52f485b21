//! `ipfn eval` as a library request: a model against its exemplar ([`EvalRequest::evaluate`]:
//! SIFID, structure distance, seam, period and repeat for a generator; PSNR and seam for a
//! fitted tile), or two images against each other ([`compare_images`]). Each report serialises
//! to the JSON that `ipfn eval --json` prints.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::fit::TileReport;
use crate::input_error;
use crate::metrics::{self, ModelReport};
use crate::model::ModelFile;

/// What to evaluate, one field per `ipfn eval` flag.
#[derive(Debug, Clone)]
pub struct EvalRequest {
    /// The exemplar the model was trained on (or the photo a tile was fitted to).
    pub exemplar: PathBuf,
    /// Samples painted (seeds `seed..seed + samples`), each at the exemplar's size.
    pub samples: usize,
    pub seed: u64,
    pub device: DeviceChoice,
}

impl Default for EvalRequest {
    fn default() -> Self {
        Self {
            exemplar: PathBuf::new(),
            samples: 8,
            seed: 0,
            device: DeviceChoice::Cpu,
        }
    }
}

/// A model's report: a generator's or a fitted tile's.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum Report {
    Generator(Box<ModelReport>),
    Tile(TileReport),
}

impl EvalRequest {
    /// Evaluates `model` against the exemplar.
    pub fn evaluate(&self, model: &ModelFile) -> Result<Report> {
        self.device.burn_device()?;
        if self.samples == 0 {
            return Err(input_error!("--samples 0: need at least one sample"));
        }
        let exemplar = crate::exemplar::read_exemplar(&self.exemplar)?;
        match model {
            ModelFile::Tile {
                checkpoint,
                description,
                ..
            } => {
                let net = crate::fit::PeriodicNet::read_from(checkpoint)?;
                let painter = crate::fit::TilePainter {
                    device: self.device.burn_device()?,
                    ..crate::fit::TilePainter::new(net)
                };
                let config = crate::fit::FitConfig::default();
                let report = TileReport::of(&painter, &exemplar, None, &config, None)
                    .map_err(|e| e.in_file(&self.exemplar))
                    .map_err(|e| input_error!("{e} (the tile: {description})"))?;
                Ok(Report::Tile(report))
            }
            ModelFile::Generator(model) => metrics::evaluate_model(
                metrics::Samples {
                    config: &model.config,
                    weights: &model.weights,
                    count: self.samples,
                    seed: self.seed,
                    device: self.device,
                },
                &exemplar,
            )
            .map(|r| Report::Generator(Box::new(r)))
            .map_err(|e| e.in_file(&self.exemplar)),
        }
    }
}

/// SIFID of image A to image B, and B's structure distance to A (A as the exemplar: its lags
/// and its floor), as `ipfn eval --images A B` reports them.
#[derive(Debug, Clone, Serialize)]
pub struct ImagesReport {
    pub metric: &'static str,
    pub sifid: f64,
    pub structure: f64,
    pub structure_floor: f64,
    pub structure_lags: usize,
    pub a: PathBuf,
    pub b: PathBuf,
}

/// Compares two images: see [`ImagesReport`].
pub fn compare_images(a: &Path, b: &Path) -> Result<ImagesReport> {
    let read = |p: &Path| -> Result<(Exemplar, metrics::Gaussian)> {
        let image = crate::exemplar::read_exemplar(p)?;
        let rgb = metrics::to_unit_rgb(&image.values, image.channels).map_err(|e| e.in_file(p))?;
        let features = metrics::InceptionStem::embedded()
            .features(&rgb, image.height, image.width)
            .map_err(|e| e.in_file(p))?;
        let gaussian = metrics::Gaussian::fit(&features).map_err(|e| e.in_file(p))?;
        Ok((image, gaussian))
    };
    let ((ia, ga), (ib, gb)) = (read(a)?, read(b)?);
    let lags = metrics::structure_lags(ia.height, ia.width);
    let map =
        |i: &Exemplar| metrics::Autocorrelation::of(&i.values, i.height, i.width, i.channels, lags);
    Ok(ImagesReport {
        metric: metrics::SIFID_NAME,
        sifid: metrics::frechet_distance(&ga, &gb),
        structure: map(&ia).distance(&map(&ib)),
        structure_floor: metrics::structure_floor(&ia.values, ia.height, ia.width, ia.channels),
        structure_lags: lags,
        a: a.to_path_buf(),
        b: b.to_path_buf(),
    })
}

//! Which model a command paints with: `--model`, else the most recent model in the working
//! folder (a run's `best.ipfn`, else its `latest.ipfn`, or an `.ipfn` file), else the shipped
//! honeycomb. `--model RUN_FOLDER` takes that folder's best or latest model.

use std::path::{Path, PathBuf};

use crate::checkpoint::Checkpoint;
use crate::error::Result;
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::maps::MapSet;

/// The honeycomb generator published by the authors of IPFN (MIT), converted with
/// `ipfn import`; see `exemplars/README.md`.
pub const SHIPPED_HONEYCOMB: &[u8] = include_bytes!("../exemplars/honeycomb.ipfn");

/// The shipped honeycomb model's config and weights.
pub fn shipped_model() -> Result<(GeneratorConfig, GeneratorWeights)> {
    let checkpoint = Checkpoint::from_bytes(SHIPPED_HONEYCOMB, Path::new("<shipped honeycomb>"))?;
    GeneratorWeights::read_from(&checkpoint)
}

/// A model to synthesize with, and a phrase saying where it came from.
pub struct ChosenModel {
    pub config: GeneratorConfig,
    pub weights: GeneratorWeights,
    pub description: String,
    /// The maps of a map-set model.
    pub maps: Option<MapSet>,
    /// What the model learned from: an image, a map set, a solid texture or a volume.
    pub kind: ModelKind,
    /// The training iteration the model file was written at (none for an imported model).
    pub iteration: Option<u64>,
}

/// What a model paints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// A generator of an image (the shipped honeycomb, `ipfn train IMAGE`).
    Image,
    /// A generator of aligned material maps (`ipfn train --maps`).
    MapSet,
    /// A 3D generator trained from a 2D exemplar (`ipfn train --solid`).
    Solid,
    /// A 3D generator of a signed distance volume (`ipfn train VOLUME.npy`).
    Volume,
    /// A tile fitted by `ipfn fit` (a periodic sine network, not an IPFN).
    Tile,
}

impl ModelKind {
    /// The kind's name: `image`, `map_set`, `solid`, `volume` or `tile`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Image => "image",
            Self::MapSet => "map_set",
            Self::Solid => "solid",
            Self::Volume => "volume",
            Self::Tile => "tile",
        }
    }
}

/// The checkpoint `--model` names, else the most recent model in `dir`, else the shipped
/// honeycomb's, with a phrase saying where it came from and its path (none for the shipped one).
pub fn choose_checkpoint(
    explicit: Option<&Path>,
    dir: &Path,
) -> Result<(Checkpoint, String, Option<PathBuf>)> {
    let in_folder = explicit.filter(|p| p.is_dir()).map(|dir| {
        run_model(dir).ok_or_else(|| {
            crate::file_error!(
                &dir,
                "no tile.ipfn, best.ipfn or latest.ipfn in this folder; give a model file",
            )
        })
    });
    let explicit = match in_folder {
        Some(model) => Some(model?),
        None => explicit.map(Path::to_path_buf),
    };
    Ok(match explicit {
        Some(path) => (
            Checkpoint::load(&path)?,
            format!("{}", path.display()),
            Some(path),
        ),
        None => match most_recent_model(dir) {
            Some(path) => (
                Checkpoint::load(&path)?,
                format!("{} (most recent model in this folder; --model to choose)", path.display()),
                Some(path),
            ),
            None => (
                Checkpoint::from_bytes(SHIPPED_HONEYCOMB, Path::new("<shipped honeycomb>"))?,
                "shipped honeycomb (the IPFN authors' pretrained generator, MIT; --model to choose)".to_string(),
                None,
            ),
        },
    })
}

/// A model file of either kind a command paints, read once.
pub enum ModelFile {
    /// A generator (an IPFN) of an image, a map set, a solid texture or a volume.
    Generator(ChosenModel),
    /// A tile fitted by `ipfn fit` (a periodic sine network, not an IPFN).
    Tile {
        checkpoint: Checkpoint,
        description: String,
        path: Option<PathBuf>,
    },
}

impl ModelFile {
    /// The generator, or an error saying a fitted tile paints only images.
    pub fn generator(&self) -> Result<&ChosenModel> {
        match self {
            ModelFile::Generator(model) => Ok(model),
            ModelFile::Tile {
                description, path, ..
            } => Err(not_a_generator(description, path.as_deref())),
        }
    }

    /// What the model paints.
    pub fn kind(&self) -> ModelKind {
        match self {
            ModelFile::Generator(model) => model.kind,
            ModelFile::Tile { .. } => ModelKind::Tile,
        }
    }

    /// Where the model came from, as commands print it.
    pub fn description(&self) -> &str {
        match self {
            ModelFile::Generator(model) => &model.description,
            ModelFile::Tile { description, .. } => description,
        }
    }
}

/// The error for a fitted tile given where only a generator paints.
fn not_a_generator(description: &str, path: Option<&Path>) -> crate::Error {
    input_error!(
        "{description}: a tile fitted by `ipfn fit`, not a generator; `ipfn synth --model {}` paints it as an image (no volumes, guides, mirrors or Zarr stores)",
        path.unwrap_or(Path::new("TILE")).display()
    )
}

/// Reads `--model`, else the most recent model in `dir`, else the shipped honeycomb, whichever
/// kind it is.
pub fn load_model(explicit: Option<&Path>, dir: &Path) -> Result<ModelFile> {
    let (checkpoint, description, path) = choose_checkpoint(explicit, dir)?;
    if crate::fit::PeriodicNet::is_in(&checkpoint) {
        return Ok(ModelFile::Tile {
            checkpoint,
            description,
            path,
        });
    }
    generator_model(&checkpoint, description, path.as_deref()).map(ModelFile::Generator)
}

/// The shipped honeycomb generator.
pub fn load_shipped() -> Result<ChosenModel> {
    let checkpoint = Checkpoint::from_bytes(SHIPPED_HONEYCOMB, Path::new("<shipped honeycomb>"))?;
    let description = "shipped honeycomb (the IPFN authors' pretrained generator, MIT)".to_string();
    generator_model(&checkpoint, description, None)
}

/// Loads `--model`, else the most recent model in `dir`, else the shipped honeycomb: a
/// generator (a fitted tile is refused with a line saying what paints it).
pub fn choose_model(explicit: Option<&Path>, dir: &Path) -> Result<ChosenModel> {
    let (checkpoint, description, path) = choose_checkpoint(explicit, dir)?;
    if crate::fit::PeriodicNet::is_in(&checkpoint) {
        return Err(not_a_generator(&description, path.as_deref()));
    }
    generator_model(&checkpoint, description, path.as_deref())
}

/// The generator in `checkpoint`, with its map list where it has one.
fn generator_model(
    checkpoint: &Checkpoint,
    description: String,
    explicit: Option<&Path>,
) -> Result<ChosenModel> {
    let (config, weights) = GeneratorWeights::read_from(checkpoint)?;
    let maps = MapSet::read_from(checkpoint, explicit.unwrap_or(Path::new("model")))?;
    if let Some(set) = &maps
        && set.channels() != config.channels
    {
        return Err(input_error!(
            "{}: its map list has {} channels but the generator paints {}",
            description,
            set.channels(),
            config.channels
        ));
    }
    // A 3D generator says how it was trained in its run's settings (an imported one has none).
    let trained = checkpoint
        .metadata
        .get("train_config")
        .and_then(|text| text.parse::<toml::Table>().ok());
    let flag = |key: &str| {
        trained
            .as_ref()
            .and_then(|t| t.get(key))
            .and_then(toml::Value::as_bool)
            .unwrap_or(false)
    };
    let kind = match (&maps, config.dims) {
        (Some(_), _) => ModelKind::MapSet,
        (None, 2) => ModelKind::Image,
        (None, _) if flag("solid") => ModelKind::Solid,
        (None, _) => ModelKind::Volume,
    };
    let iteration = checkpoint
        .metadata
        .get("iteration")
        .and_then(|i| i.parse().ok());
    Ok(ChosenModel {
        config,
        weights,
        description,
        maps,
        kind,
        iteration,
    })
}

/// The model a run folder paints with: a fit's `tile.ipfn`, else a training run's `best.ipfn`
/// (the best-scoring checkpoint) where there is one, else its `latest.ipfn`.
pub fn run_model(run: &Path) -> Option<PathBuf> {
    ["tile.ipfn", "best.ipfn", "latest.ipfn"]
        .iter()
        .map(|name| run.join(name))
        .find(|p| p.is_file())
}

/// The newest `*.ipfn` in `dir`, or run folder model ([`run_model`]) under `dir/runs`.
pub fn most_recent_model(dir: &Path) -> Option<PathBuf> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    let ipfn_files = |d: &Path| -> Vec<PathBuf> {
        std::fs::read_dir(d)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "ipfn"))
            .collect()
    };
    candidates.extend(ipfn_files(dir));
    for run in std::fs::read_dir(dir.join("runs"))
        .into_iter()
        .flatten()
        .flatten()
    {
        if let Some(model) = run_model(&run.path()) {
            candidates.push(model);
        }
    }
    candidates
        .into_iter()
        .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
        .max()
        .map(|(_, p)| p.strip_prefix(dir).map(Path::to_path_buf).unwrap_or(p))
}

//! `ipfn train` as a library request: what to learn from (an image, a map set, or a run to
//! resume), the settings (a config file, settings given as TOML text, flags), the run folder
//! and the device. [`TrainRequest::open`] decides everything a new run takes (the recipe's
//! choices included) and returns a [`Trainer`] ready to run, with the lines that say what was
//! chosen. The command line and the Python package only fill the request.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use super::recipe::settle;
use super::{ExemplarSource, RunState, TrainConfig, TrainOverrides, Trainer, default_run_dir};
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::input_error;
use crate::maps::MapSetRequest;

/// What to train, one field per `ipfn train` flag.
#[derive(Debug, Clone, Default)]
pub struct TrainRequest {
    /// The exemplar image (or volume). Not with `maps` or `resume`.
    pub exemplar: Option<PathBuf>,
    /// A material map set instead of one image.
    pub maps: Option<MapSetRequest>,
    /// A TOML config file (`--config`).
    pub config: Option<PathBuf>,
    /// Config keys as TOML text, applied over `config` (the Python package's keyword
    /// arguments); `flags` apply over both.
    pub settings: Option<String>,
    /// The command line's flags, over everything else.
    pub flags: TrainOverrides,
    /// The run folder; default `runs/<exemplar name>`.
    pub out: Option<PathBuf>,
    /// Continue the run in this folder (from `previous.ipfn` with `from_previous`).
    pub resume: Option<PathBuf>,
    pub from_previous: bool,
    /// `auto`, `flex`, `wgpu` or `cuda` (`cpu` is `flex` for training).
    pub device: String,
}

/// A run ready to train, and what was decided for it.
pub struct OpenedRun {
    pub trainer: Trainer,
    pub device: DeviceChoice,
    /// What the recipe chose and measured, or where the run resumes, for the user.
    pub lines: Vec<String>,
}

impl TrainRequest {
    /// Starts the run (checked settings, the recipe's choices, the run folder and its lock) or
    /// resumes it.
    pub fn open(&self) -> Result<OpenedRun> {
        let device = DeviceChoice::for_training(self.device_name())?;
        let burn_device = device.training_device()?;
        if let Some(dir) = &self.resume {
            if self.exemplar.is_some() || self.maps.is_some() || self.config.is_some() {
                return Err(input_error!(
                    "resuming {}: the run keeps its exemplar and config; give only the settings a resumed run may change",
                    dir.display()
                ));
            }
            let state = match self.from_previous {
                true => RunState::Previous,
                false => RunState::Latest,
            };
            let mut flags = self.flags.clone();
            if let Some(text) = &self.settings {
                flags = settings_over(flags, text)?;
            }
            let trainer = Trainer::resume_with(dir, state, &flags, &burn_device)?;
            let lines = vec![format!(
                "resuming {} at iteration {}",
                dir.display(),
                trainer.iteration
            )];
            return Ok(OpenedRun {
                trainer,
                device,
                lines,
            });
        }
        let source = self.source()?;
        let (mut config, explicit) = self.settings_given()?;
        let on_gpu = !matches!(device, DeviceChoice::Cpu | DeviceChoice::Flex);
        let mut lines = settle(&mut config, &source, &explicit, on_gpu)?;
        let run_dir = self
            .out
            .clone()
            .unwrap_or_else(|| default_run_dir(source.main_path()));
        let trainer = Trainer::new(config, source, &run_dir, &burn_device)?.start()?;
        if let Some(maps) = trainer.maps() {
            lines.push(format!("map set: {}", maps.describe()));
        }
        Ok(OpenedRun {
            trainer,
            device,
            lines,
        })
    }

    fn device_name(&self) -> &str {
        match self.device.as_str() {
            "" => "auto",
            name => name,
        }
    }

    /// The exemplar or the map set.
    fn source(&self) -> Result<ExemplarSource> {
        match (&self.exemplar, &self.maps) {
            (Some(_), Some(_)) => Err(input_error!(
                "give either an exemplar image or --maps, not both"
            )),
            (Some(image), None) => Ok(image.into()),
            (None, Some(maps)) => Ok(maps.open()?.into()),
            (None, None) => Err(input_error!(
                "no exemplar given: `ipfn train IMAGE` (or `--maps A.png,B.png,...`) starts a run, `ipfn train --resume runs/NAME` continues one"
            )),
        }
    }

    /// The config file, the settings text over it and the flags over both, and the keys they
    /// set (which the recipe keeps as given).
    fn settings_given(&self) -> Result<(TrainConfig, BTreeSet<String>)> {
        let mut table = match &self.config {
            Some(path) => std::fs::read_to_string(path)
                .map_err(|e| crate::file_error!(&path, "cannot read: {e}"))?
                .parse::<toml::Table>()
                .map_err(|e| crate::file_error!(&path, "{}", e.message()))?,
            None => toml::Table::new(),
        };
        if let Some(text) = &self.settings {
            table.extend(parse_settings(text)?);
        }
        let source = self.config.as_deref().unwrap_or(Path::new("settings"));
        let text = toml::to_string(&table).expect("a TOML table serialises");
        let mut config = TrainConfig::from_toml(&text, source)?;
        let mut explicit: BTreeSet<String> = table.keys().cloned().collect();
        self.flags.apply(&mut config);
        explicit.extend(self.flags.given().into_iter().map(String::from));
        Ok((config, explicit))
    }
}

fn parse_settings(text: &str) -> Result<toml::Table> {
    text.parse::<toml::Table>()
        .map_err(|e| input_error!("settings: {}", e.message().replace('\n', " ")))
}

/// A resumed run takes settings only as the flags a resume may change (an unknown key is
/// refused here, one a resume cannot change by the resume).
fn settings_over(flags: TrainOverrides, text: &str) -> Result<TrainOverrides> {
    let settings: TrainOverrides = toml::from_str(text)
        .map_err(|e| input_error!("settings: {}", e.message().replace('\n', " ")))?;
    Ok(flags.over(settings))
}

//! `ipfn fit` as a library request: the photo or map set, the settings, the run folder, the
//! time budget and the device ([`FitRequest::open`]), and the tile written at the end
//! ([`FitRequest::finish`]). The command line and the Python package only fill the request.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::{FitConfig, Fitter, TileReport};
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::input_error;
use crate::io::OutputFormat;
use crate::maps::{MapOutput, MapSetRequest, preview};

/// The time budget of a fit that names neither a budget nor a step count.
pub const DEFAULT_FIT_TIME: &str = "10m";

/// What to fit, one field per `ipfn fit` flag; `None` keeps [`FitConfig`]'s default.
#[derive(Debug, Clone, Default)]
pub struct FitRequest {
    pub photo: Option<PathBuf>,
    pub maps: Option<MapSetRequest>,
    pub mask: Option<PathBuf>,
    /// The tile's period in photo pixels `[rows, cols]`.
    pub period: Option<[usize; 2]>,
    /// The tile image; default `RUN/tile.png`.
    pub out: Option<PathBuf>,
    pub bits: Option<u8>,
    /// `--preview`: the fitted map set's material lit, as an 8-bit PNG (one period, up to its
    /// top-left 1024²).
    pub preview: Option<PathBuf>,
    /// The run folder; default `runs/<photo name>-tile`.
    pub run: Option<PathBuf>,
    pub resume: Option<PathBuf>,
    /// A time budget such as `10m` (the default when `iterations` is not given either).
    pub time: Option<String>,
    /// Steps of the last stage, instead of a time budget.
    pub iterations: Option<u64>,
    /// `auto` (the best present: cuda, then a wgpu GPU, else the CPU), `cpu`, `flex`, `wgpu`
    /// or `cuda`.
    pub device: String,
    pub band_limit: Option<usize>,
    pub stages: Option<usize>,
    pub frequencies: Option<usize>,
    pub hidden: Option<Vec<usize>>,
    pub lr: Option<f64>,
    pub batch: Option<usize>,
    pub seam_band: Option<f32>,
    pub seed: Option<u64>,
    pub checkpoint_every: Option<u64>,
}

/// A fit ready to run.
pub struct OpenedFit {
    pub fitter: Fitter,
    pub device: DeviceChoice,
    /// When a new fit's time budget ends (a resumed fit finishes its plan).
    pub deadline: Option<Instant>,
    /// Where a resumed fit continues, for the user.
    pub lines: Vec<String>,
}

/// What a finished fit wrote.
pub struct FitOutcome {
    /// `RUN/tile.ipfn`, the tile's model.
    pub model: PathBuf,
    /// The tile image(s): one file, or one per map; then the preview, if asked for.
    pub images: Vec<PathBuf>,
    pub report: TileReport,
}

impl FitRequest {
    /// Starts the fit (settings checked, steps planned for the budget) or resumes it.
    pub fn open(&self) -> Result<OpenedFit> {
        let device = DeviceChoice::resolve(&self.device)?;
        let burn_device = device.burn_device()?;
        self.check_bits()?;
        self.check_preview()?;
        if let Some(dir) = &self.resume {
            let fitter = Fitter::resume(dir, burn_device)?;
            if self.preview.is_some() && fitter.maps().is_none() {
                return Err(input_error!(
                    "--preview lights a material's maps: {} fits one photo, not a map set; drop --preview",
                    dir.display()
                ));
            }
            let lines = vec![format!(
                "resuming {} at stage {}, step {}",
                dir.display(),
                fitter.stage + 1,
                fitter.iteration
            )];
            return Ok(OpenedFit {
                fitter,
                device,
                deadline: None,
                lines,
            });
        }
        let config = self.config()?;
        let budget = config
            .time
            .as_deref()
            .map(crate::train::config::parse_duration)
            .transpose()?;
        let run = self
            .run
            .clone()
            .unwrap_or_else(|| default_run_dir(self.name()));
        let mut fitter = Fitter::start(config, &run, burn_device)?;
        if let Some(budget) = budget.filter(|_| fitter.config.iterations.is_empty()) {
            fitter.plan(budget);
        }
        let lines = fitter
            .maps()
            .map(|maps| format!("map set: {}", maps.describe()))
            .into_iter()
            .collect();
        Ok(OpenedFit {
            fitter,
            device,
            deadline: budget.map(|b: Duration| Instant::now() + b),
            lines,
        })
    }

    /// Writes `RUN/tile.ipfn` and the tile image(s), and measures the tile against its photo.
    pub fn finish(&self, fitter: &Fitter) -> Result<FitOutcome> {
        let run = fitter.run_dir();
        let model = run.join("tile.ipfn");
        fitter.model_file().save(&model)?;
        let out = self.out.clone().unwrap_or_else(|| run.join("tile.png"));
        let outputs = match fitter.maps() {
            Some(set) => set.outputs(&out, self.bits)?,
            None => vec![MapOutput {
                path: out.clone(),
                format: OutputFormat::from_path(&out, self.bits.unwrap_or(8))?,
                channels: 0..fitter.photo().channels,
                normal: false,
                directx: false,
            }],
        };
        let painter = fitter.painter();
        let period = fitter.net.shape.period;
        painter.write(&outputs, [0, 0], period, crate::synth::DEFAULT_BAND_PIXELS)?;
        let report = TileReport::of(
            &painter,
            fitter.photo(),
            fitter.mask(),
            &fitter.config,
            fitter.maps(),
        )?;
        let mut images: Vec<PathBuf> = outputs.into_iter().map(|o| o.path).collect();
        if let (Some(path), Some(set)) = (&self.preview, fitter.maps()) {
            let region = preview::region(period);
            preview::write(path, set, &painter.render([0, 0], region), region)?;
            images.push(path.clone());
        }
        Ok(FitOutcome {
            model,
            images,
            report,
        })
    }

    /// `--preview` needs a map set and a .png.
    fn check_preview(&self) -> Result<()> {
        let Some(path) = &self.preview else {
            return Ok(());
        };
        crate::maps::preview::check_path(path)?;
        if self.photo.is_some() {
            return Err(input_error!(
                "--preview lights a material's maps (give --maps): a single photo's tile is its own picture; drop --preview"
            ));
        }
        crate::io::check_destination(path).map(drop)
    }

    fn check_bits(&self) -> Result<()> {
        match self.bits.filter(|b| *b != 8 && *b != 16) {
            Some(bits) => Err(crate::setting_error!(
                "--bits",
                bits,
                "PNG output is 8 or 16 bits per channel"
            )),
            None => Ok(()),
        }
    }

    /// The photo, or the first map, that names the run.
    fn name(&self) -> &Path {
        let first_map = self.maps.as_ref().and_then(|m| m.files.first());
        self.photo
            .as_deref()
            .or(first_map.map(PathBuf::as_path))
            .unwrap_or(Path::new("tile"))
    }

    /// The fit's settings: [`FitConfig`]'s defaults with the request's over them.
    fn config(&self) -> Result<FitConfig> {
        let mut c = FitConfig {
            photo: self.photo.clone(),
            mask: self.mask.clone(),
            period: self.period,
            ..FitConfig::default()
        };
        if let Some(maps) = &self.maps {
            c.maps = Some(maps.open()?);
        }
        macro_rules! set {
            ($($field:ident),*) => { $(if let Some(v) = &self.$field { c.$field = v.clone(); })* };
        }
        set!(
            band_limit,
            stages,
            frequencies,
            hidden,
            lr,
            batch,
            seed,
            checkpoint_every
        );
        if self.seam_band.is_some() {
            c.seam_band = self.seam_band;
        }
        if let Some(n) = self.iterations {
            c.iterations = FitConfig::stage_steps(n, c.stages);
        }
        c.time = match (&self.time, self.iterations) {
            (Some(t), _) => Some(t.clone()),
            (None, None) => Some(DEFAULT_FIT_TIME.into()),
            (None, Some(_)) => None,
        };
        Ok(c)
    }
}

/// `runs/<photo stem>-tile`.
pub fn default_run_dir(photo: &Path) -> PathBuf {
    let stem = photo.file_stem().map(|s| s.to_string_lossy().into_owned());
    PathBuf::from("runs").join(format!("{}-tile", stem.unwrap_or_else(|| "photo".into())))
}

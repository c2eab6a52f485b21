//! Settings from the machine and the exemplar. Before a new run, `ipfn train` takes settings
//! that fit the device's budget (on a CPU, `configs/cpu.toml`'s network, scale and crop),
//! measures the exemplar (its dominant period per axis, its size, whether its channels are all
//! equal), trains a gray photo as gray, and says what it measured. Every choice is a config
//! key: keys given in a config file or as flags are kept as given.
//!
//! Three choices come from the period:
//! - a periodic plain image trains at the working scale at which a fine crop holds one whole
//!   period of its shorter clear period ([`cell_scale`]): a crop smaller than one cell cannot
//!   learn the cell's shape, and the generator then paints a grid of crop-sized blobs;
//!   (a run that sets its own scale and leaves the crop is told when the crop holds less than
//!   one period, and which `--crop` holds one);
//! - a plain image whose rows alternate (a running bond) trains with K held on the two courses
//!   after which it repeats and a coarse critic over about three ([`alternating_rows`]);
//! - a plain image with no clear period on either axis trains with the diversity hinge
//!   ([`NO_PERIOD_DIVERSITY`], [`super::diversity`]), which keeps its samples from repeating as
//!   a grid. A periodic exemplar keeps the paper's loss: its crops and their twins at the same
//!   phase should be alike, not as different as two random crops.
//!
//! Built, measured and not made by default (the book's experiments have the figures): a scale
//! at which the crop holds two of the longer periods, the initial K from the period
//! ([`initial_k`]; printed, and `k_init` sets it) where the rows do not alternate, K from the
//! exemplar's extent where it has no clear period, and the coarse critic ([`super::coarse`])
//! on its own.

use std::collections::BTreeSet;

mod rows;

pub use rows::{COARSE_PERIODS, alternating_rows};
use rows::{apply_alternating_rows, staggered};

use super::TrainConfig;
use crate::exemplar::Exemplar;
use crate::metrics::{Repeat, repeats};

/// The shortest period the recipe believes, in pixels.
const MIN_PERIOD: f64 = 4.0;

/// The weakest repeat the recipe calls a period: the autocorrelation at its peak over the
/// autocorrelation at lag 0. Regular photos (a honeycomb, a brick wall) and stochastic ones
/// (marble, flecks) fall far to either side of it; the book's photographs experiment has the
/// figures.
pub const CLEAR_REPEAT: f64 = 0.25;

/// What the recipe measured on the exemplar, at its own scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    /// `[height, width]` in pixels.
    pub size: [usize; 2],
    pub channels: usize,
    /// Every pixel's channels are equal (a gray photo stored as RGB).
    pub gray: bool,
    /// The strongest repeat along rows and columns, where the autocorrelation has a peak (of
    /// [`MIN_PERIOD`] pixels or more), however weak.
    pub repeat: [Option<Repeat>; 2],
    /// Along which axes the rows alternate ([`staggered`]): a running bond's courses, whose
    /// joints move by half a brick from one course to the next.
    pub staggered: [bool; 2],
}

impl Measured {
    /// The period in pixels along `axis` (0 rows, 1 columns), where the exemplar clearly repeats
    /// (a repeat of [`CLEAR_REPEAT`] or more).
    pub fn period(&self, axis: usize) -> Option<f64> {
        self.repeat[axis]
            .filter(|r| r.strength >= CLEAR_REPEAT)
            .map(|r| r.period)
    }

    /// The shorter of the two axes' clear periods, if either axis has one: the cell a crop
    /// must hold.
    pub fn shortest_period(&self) -> Option<f64> {
        (0..2).filter_map(|axis| self.period(axis)).reduce(f64::min)
    }

    /// The period after which the pattern repeats unshifted along `axis`: the clear period,
    /// twice it where the rows alternate. The generator's encoding must repeat no sooner, or
    /// it cannot tell one course from the next.
    pub fn lattice_period(&self, axis: usize) -> Option<f64> {
        let twice = if self.staggered[axis] { 2.0 } else { 1.0 };
        self.period(axis).map(|p| p * twice)
    }
}

/// Measures `exemplar` (at most 512 pixels a side are read for the period: a larger exemplar's
/// centre).
pub fn measure(exemplar: &Exemplar) -> Measured {
    let (h, w, c) = (exemplar.height, exemplar.width, exemplar.channels);
    let gray = exemplar.is_gray();
    let window = exemplar.centre(512);
    // A "period" of a few pixels is noise (or aliasing), not a pattern the crops must hold.
    let repeat = repeats(&window.values, window.height, window.width, c)
        .map(|r| r.filter(|r| r.period >= MIN_PERIOD));
    Measured {
        size: [h, w],
        channels: c,
        gray,
        repeat,
        staggered: [0, 1].map(|axis| staggered(&window, &repeat, axis)),
    }
}

/// The initial K per axis (rows, cols) for `measured` at working scale `resize`, `crop` and
/// `octaves`. The encoding's octave `j` repeats every `K * crop / 2^j` pixels, so where there is
/// a lattice period `P` ([`Measured::lattice_period`], at the working scale), K is
/// `P * 2^m / crop` for the octave `m` (0 to `octaves - 1`) that brings K nearest 1: that
/// octave then repeats with the pattern, and every lower one with a multiple of it. Where there is no period, K is the exemplar's extent in
/// crops (at least 1), so the encoding repeats no sooner than the exemplar does and paints no
/// grid of crops.
pub fn initial_k(measured: &Measured, resize: f64, crop: usize, octaves: usize) -> Vec<f32> {
    let crop = crop as f64;
    let top = octaves.saturating_sub(1) as f64;
    (0..2)
        .map(|axis| match measured.lattice_period(axis) {
            Some(p) => {
                let in_crops = p * resize / crop;
                let m = (1.0 / in_crops).log2().round().clamp(0.0, top);
                (in_crops * m.exp2()) as f32
            }
            None => (measured.size[axis] as f64 * resize / crop).max(1.0) as f32,
        })
        .collect()
}

/// The smallest working scale the recipe takes from the period: below it a photo loses the
/// detail SIFID and the eye look for.
pub const MIN_CELL_SCALE: f64 = 0.25;

/// The working scale at which a fine crop of `crop` pixels holds one whole period of the
/// exemplar's shorter clear period (one cell of a honeycomb, two courses of bricks), in steps
/// of 0.05 down; `None` where the crop already holds it or there is no clear period. A crop
/// smaller than one cell cannot learn the cell's shape, and the generator then paints a grid
/// of crop-sized blobs.
pub fn cell_scale(measured: &Measured, crop: usize) -> Option<f64> {
    let period = measured.shortest_period()?;
    let scale = (crop as f64 / period * 20.0).floor() / 20.0;
    (scale < 1.0).then_some(scale.max(MIN_CELL_SCALE))
}

/// The diversity hinge's weight ([`super::diversity`]) for a plain image with no clear period
/// on either axis.
pub const NO_PERIOD_DIVERSITY: f64 = 1.0;

/// Writes the exemplar's choices into `config` (gray; for a `plain` image, one neither solid
/// nor guided, with no clear period: the diversity hinge), except the keys in `explicit`, and
/// says what was measured: each axis's period where the exemplar clearly repeats, else its
/// strongest repeat and how weak it is, and the K that would line an octave up with the period
/// (`k_init`; not set by default: see the module's notes). Returns the lines for the user.
pub fn apply(
    measured: &Measured,
    config: &mut TrainConfig,
    explicit: &BTreeSet<String>,
    plain: bool,
) -> Vec<String> {
    let along = |axis: usize, name: &str| match (measured.period(axis), measured.repeat[axis]) {
        (Some(p), Some(r)) if measured.staggered[axis] => format!(
            "period {p:.1} px {name} (repeat {:.2}; the rows alternate: unshifted every {:.1} px)",
            r.strength,
            2.0 * p
        ),
        (Some(p), Some(r)) => format!("period {p:.1} px {name} (repeat {:.2})", r.strength),
        (None, Some(r)) => format!(
            "no clear period {name} (strongest repeat {:.1} px, {:.2})",
            r.period, r.strength
        ),
        _ => format!("no period {name}"),
    };
    let scale = (plain && !explicit.contains("resize") && !explicit.contains("crop"))
        .then(|| cell_scale(measured, config.crop))
        .flatten();
    if let Some(scale) = scale {
        config.resize = scale;
    }
    let k = initial_k(measured, config.resize, config.crop, config.octaves);
    let mut lines = vec![format!(
        "exemplar {}x{}: {}, {} (k_init = [{:.3}, {:.3}] would start an octave on it)",
        measured.size[1],
        measured.size[0],
        along(0, "down"),
        along(1, "across"),
        k[0],
        k[1]
    )];
    if let Some(scale) = scale {
        lines.push(format!(
            "working scale {scale} (--resize): a {} px crop holds one whole period, so the cells' shape can be learned; the model still paints at the exemplar's own scale",
            config.crop
        ));
    }
    lines.extend(crop_short_of_a_period(measured, config, explicit, plain));
    if !explicit.contains("gray") && measured.gray {
        config.gray = true;
        lines.push("every pixel's channels are equal: trained as gray (1 channel)".into());
    }
    let stochastic = measured.period(0).is_none() && measured.period(1).is_none();
    if plain && stochastic && !explicit.contains("diversity") {
        config.diversity = NO_PERIOD_DIVERSITY;
        lines.push(format!(
            "no clear period: diversity {NO_PERIOD_DIVERSITY} (a generated crop and its twin under another latent field must differ as two crops of the exemplar do, so the samples do not repeat as a grid)"
        ));
    }
    lines
}

/// A warning where the run set the scale and left the crop, and the crop then holds less than
/// one period of a periodic plain image: the cells' shape cannot be learned, as at the
/// exemplar's own scale with a crop too small.
fn crop_short_of_a_period(
    measured: &Measured,
    config: &TrainConfig,
    explicit: &BTreeSet<String>,
    plain: bool,
) -> Option<String> {
    if !plain || !explicit.contains("resize") || explicit.contains("crop") {
        return None;
    }
    let period = measured.shortest_period()? * config.resize;
    // Crops are multiples of 16: the way out names the first that holds the period.
    (period > config.crop as f64).then(|| {
        format!(
            "a {} px crop holds less than one period ({period:.1} px at --resize {}): the cells' shape may not be learned; --crop {} holds one (slower), or leave --resize out and the recipe picks a scale",
            config.crop,
            config.resize,
            (period / 16.0).ceil() as usize * 16
        )
    })
}

/// The time budget of a run that names neither a budget nor an iteration count.
pub const DEFAULT_TIME: &str = "15m";

/// Iterations at most, for a run with a time budget and no iteration count of its own.
pub const BUDGET_ITERATIONS: u64 = 1_000_000;

/// On a CPU, the network, batch, learning rates, scale and crop of `configs/cpu.toml` (this
/// file is the one place they are written), for a good result within 15 minutes on 2 cores; a
/// GPU keeps the authors' (10x128, batch 4, lr 1e-4, the exemplar's own scale, 128-pixel crops).
const CPU_PRESET: &str = include_str!("../../../configs/cpu.toml");

/// The keys of [`CPU_PRESET`] a CPU run takes.
const CPU_KEYS: [&str; 7] = [
    "hidden_layers",
    "width",
    "batch",
    "lr",
    "k_lr",
    "resize",
    "crop",
];

fn cpu_preset() -> TrainConfig {
    TrainConfig::from_toml(CPU_PRESET, std::path::Path::new("configs/cpu.toml"))
        .expect("the shipped configs/cpu.toml parses")
}

/// Completes the settings of a new run: `config` as given by a config file and flags
/// (`explicit` names the keys they set), then on a CPU (`on_gpu` false) a network that fits a
/// CPU's budget, the recipe's choices from the exemplar (images and solid textures), and a
/// default time budget. Returns the lines that say what was chosen.
pub fn settle(
    config: &mut TrainConfig,
    source: &super::ExemplarSource,
    explicit: &BTreeSet<String>,
    on_gpu: bool,
) -> crate::Result<Vec<String>> {
    config.time_budget()?;
    let mut lines = Vec::new();
    // The preset's scale and crop were tuned on single images: map sets take them too
    // (measured on their colour map), volumes keep their own. A run that sets the scale keeps
    // the preset's crop (a CPU trains 128-px crops at a tenth of the speed); one that sets the
    // crop keeps its own scale, since it sized the crop for the exemplar as it is.
    let flat = matches!(
        source,
        super::ExemplarSource::Image(_) | super::ExemplarSource::Maps(_)
    );
    let preset_crop = flat;
    let preset_scale = flat && !explicit.contains("crop");
    // K's own rate was measured on plain 2D images: solid textures, guided runs, map sets and
    // volumes keep K at the weights' rate.
    let plain_image = matches!(source, super::ExemplarSource::Image(_))
        && !config.solid
        && config.guide.is_none();
    let free: Vec<&str> = CPU_KEYS
        .into_iter()
        .filter(|k| !explicit.contains(*k))
        .filter(|k| match *k {
            "crop" => preset_crop,
            "resize" => preset_scale,
            _ => true,
        })
        .filter(|k| plain_image || *k != "k_lr")
        .collect();
    if !on_gpu && !free.is_empty() {
        let preset = cpu_preset();
        for key in &free {
            match *key {
                "hidden_layers" => config.hidden_layers = preset.hidden_layers,
                "width" => config.width = preset.width,
                "batch" => config.batch = preset.batch,
                "resize" => config.resize = preset.resize,
                "crop" => config.crop = preset.crop,
                "k_lr" => config.k_lr = preset.k_lr,
                _ => config.lr = preset.lr,
            }
        }
        lines.push(format!(
            "on the CPU: {} as configs/cpu.toml has them (--config configs/default.toml for the authors' settings)",
            free.join(", ")
        ));
    }
    match source {
        super::ExemplarSource::Image(path) => {
            let exemplar = crate::exemplar::read_exemplar(path)?;
            let plain = !config.solid && config.guide.is_none();
            let measured = measure(&exemplar);
            lines.extend(apply(&measured, config, explicit, plain));
            if plain {
                lines.extend(apply_alternating_rows(&measured, config, explicit));
            }
        }
        super::ExemplarSource::Maps(files) => {
            // The colour map's period sets the working scale for every map; the set is
            // never trained as gray, whatever its colour map holds.
            let (stacked, set) = files.load()?;
            let range = set.ranges()[set.colour_map()].clone();
            let measured = Measured {
                gray: false,
                ..measure(&stacked.select(range))
            };
            lines.extend(apply(&measured, config, explicit, config.guide.is_none()));
        }
        super::ExemplarSource::Volume(_) => {}
    }
    if !explicit.contains("iterations") && !explicit.contains("time") {
        config.time = Some(DEFAULT_TIME.into());
    }
    if config.time.is_some() && !explicit.contains("iterations") {
        config.iterations = BUDGET_ITERATIONS;
    }
    if let Some(time) = &config.time {
        lines.push(format!(
            "time budget {time}: iterations planned from the first ones' speed"
        ));
    }
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn measured(period: [Option<f64>; 2]) -> Measured {
        Measured {
            size: [512, 512],
            channels: 3,
            gray: false,
            staggered: [false; 2],
            repeat: period.map(|p| {
                p.map(|period| Repeat {
                    period,
                    strength: 0.5,
                })
            }),
        }
    }

    #[test]
    fn k_starts_on_an_octave_that_repeats_with_the_period() {
        // 40 px at scale 0.5 is 20 px, 0.625 of a 32 px crop: octave 1 (K = 1.25) repeats with
        // it, octave 0 with two periods.
        let k = initial_k(&measured([Some(40.0), Some(40.0)]), 0.5, 32, 5);
        assert!(k.iter().all(|k| (k - 1.25).abs() < 1e-6), "{k:?}");
        // A period longer than a crop: octave 0 must repeat with it (K > 1), never half of it.
        let k = initial_k(&measured([Some(200.0), Some(200.0)]), 0.5, 32, 5);
        assert!(k.iter().all(|k| (k - 3.125).abs() < 1e-6), "{k:?}");
    }

    #[test]
    fn the_working_scale_fits_one_period_in_a_crop() {
        let with = |down: f64, across: f64| Measured {
            repeat: [Some(down), Some(across)].map(|p| {
                p.map(|period| Repeat {
                    period,
                    strength: 0.5,
                })
            }),
            ..measured([None, None])
        };
        // Honeycomb cells 59.5 px across (two rows 104 px down): the 32 px crop holds a cell at
        // scale 0.5 (32 / 59.5 = 0.54, down to a step of 0.05).
        assert_eq!(cell_scale(&with(104.0, 59.5), 32), Some(0.5));
        // Bricks 160 px long, two courses 40 px: the shorter period sets it.
        assert_eq!(cell_scale(&with(40.1, 159.7), 32), Some(0.75));
        // A crop that holds the period already, or no period: the exemplar's own scale.
        assert_eq!(cell_scale(&with(20.0, 30.0), 32), None);
        assert_eq!(cell_scale(&measured([None, None]), 32), None);
        // Never below the smallest scale.
        assert_eq!(cell_scale(&with(400.0, 500.0), 32), Some(MIN_CELL_SCALE));
        // The recipe takes it unless the run set its scale or crop, and says so.
        let mut config = TrainConfig {
            crop: 32,
            resize: 1.0,
            ..TrainConfig::default()
        };
        let lines = apply(&with(104.0, 59.5), &mut config, &BTreeSet::new(), true);
        assert_eq!(config.resize, 0.5);
        assert!(
            lines.iter().any(|l| l.starts_with("working scale 0.5")),
            "{lines:?}"
        );
        let explicit = BTreeSet::from(["resize".to_string()]);
        config.resize = 1.0;
        let lines = apply(&with(104.0, 59.5), &mut config, &explicit, true);
        assert_eq!(config.resize, 1.0);
        // A scale of the run's own that leaves the crop short of a cell is named, with the
        // crop (a multiple of 16) that holds one.
        let warning = "a 32 px crop holds less than one period (59.5 px at --resize 1): the cells' shape may not be learned; --crop 64 holds one (slower), or leave --resize out and the recipe picks a scale";
        assert!(lines.iter().any(|l| l == warning), "{lines:?}");
        config.resize = 0.5;
        let lines = apply(&with(104.0, 59.5), &mut config, &explicit, true);
        assert!(!lines.iter().any(|l| l.contains("less than one period")));
    }

    /// A running bond repeats unshifted after two courses, a stack bond after one; a
    /// honeycomb's rows, measured over two rows, are not doubled again.
    #[test]
    fn a_stochastic_exemplar_is_not_painted_as_a_grid_of_crops() {
        // No period: the encoding repeats with the exemplar (256 px at scale 0.5 = 8 crops).
        let k = initial_k(&measured([None, None]), 0.5, 32, 5);
        assert!(k.iter().all(|k| (k - 8.0).abs() < 1e-6), "{k:?}");
    }

    #[test]
    fn a_weak_repeat_is_reported_but_is_no_period() {
        let repeat = Some(Repeat {
            period: 31.0,
            strength: CLEAR_REPEAT / 10.0,
        });
        let measured = Measured {
            size: [320, 512],
            channels: 3,
            gray: false,
            repeat: [repeat, repeat],
            staggered: [false; 2],
        };
        assert_eq!((measured.period(0), measured.period(1)), (None, None));
        let mut config = TrainConfig {
            crop: 32,
            resize: 1.0,
            ..TrainConfig::default()
        };
        let lines = apply(&measured, &mut config, &BTreeSet::new(), true);
        assert!(
            lines[0].contains("no clear period down (strongest repeat 31.0 px"),
            "{lines:?}"
        );
        // Without a period, the suggested K spans the exemplar (320 and 512 px in 32 px crops).
        assert!(lines[0].contains("k_init = [10.000, 16.000]"), "{lines:?}");
        assert_eq!(config.k_init, None, "K is only suggested");
        // No clear period on either axis: the diversity hinge, unless the run set it or the
        // image is a solid texture's or guided.
        assert_eq!(config.diversity, NO_PERIOD_DIVERSITY, "{lines:?}");
        assert!(
            lines
                .iter()
                .any(|l| l.starts_with("no clear period: diversity 1"))
        );
        let explicit = BTreeSet::from(["diversity".to_string()]);
        let mut config = TrainConfig::default();
        apply(&measured, &mut config, &explicit, true);
        apply(&measured, &mut config, &BTreeSet::new(), false);
        assert_eq!(config.diversity, 0.0);
    }

    #[test]
    fn a_periodic_exemplar_keeps_the_papers_loss() {
        let mut config = TrainConfig::default();
        let lines = apply(
            &measured([Some(40.0), None]),
            &mut config,
            &BTreeSet::new(),
            true,
        );
        assert_eq!(config.diversity, 0.0, "{lines:?}");
    }
}

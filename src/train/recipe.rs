//! Settings from the exemplar: before a new run, `ipfn train` measures the exemplar (its
//! dominant period per axis, its size, whether its channels are all equal) and chooses the
//! working scale, the crop and the initial K, so that a crop holds about two periods of the
//! pattern at a resolution the critic can use. Every choice is a config key: keys given in a
//! config file or as flags are kept as given, and `configs/paper.toml` sets all of them.

use std::collections::BTreeSet;

use super::TrainConfig;
use crate::exemplar::Exemplar;
use crate::metrics::dominant_period;

/// Crop side of the recipe, in pixels of the working scale.
pub const RECIPE_CROP: usize = 64;

/// Periods a crop should hold.
const PERIODS_PER_CROP: f64 = 2.0;

/// The shortest period the recipe believes, in pixels.
const MIN_PERIOD: f64 = 4.0;

/// A stochastic exemplar (no clear period) is scaled so its shorter side holds this many crops.
const CROPS_PER_SIDE: f64 = 4.0;

/// What the recipe measured on the exemplar, at its own scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    /// `[height, width]` in pixels.
    pub size: [usize; 2],
    pub channels: usize,
    /// Every pixel's channels are equal (a gray photo stored as RGB).
    pub gray: bool,
    /// Dominant period in pixels along rows and columns, where the autocorrelation has a clear
    /// peak.
    pub period: [Option<f64>; 2],
}

/// Measures `exemplar` (at most 512 pixels a side are read for the period: a larger exemplar's
/// centre).
pub fn measure(exemplar: &Exemplar) -> Measured {
    let (h, w, c) = (exemplar.height, exemplar.width, exemplar.channels);
    let gray = exemplar.is_gray();
    let (ch, cw) = (h.min(512), w.min(512));
    let (top, left) = ((h - ch) / 2, (w - cw) / 2);
    let mut window = Vec::with_capacity(ch * cw * c);
    for y in top..top + ch {
        let from = (y * w + left) * c;
        window.extend_from_slice(&exemplar.values[from..from + cw * c]);
    }
    // A "period" of a few pixels is noise (or aliasing), not a pattern the crops must hold.
    let period = dominant_period(&window, ch, cw, c).map(|p| p.filter(|&p| p >= MIN_PERIOD));
    Measured {
        size: [h, w],
        channels: c,
        gray,
        period,
    }
}

/// What the recipe chose, and why, in a few lines for the user.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    pub resize: f64,
    pub crop: usize,
    /// Initial K per axis (rows, cols).
    pub k_init: Vec<f32>,
    pub gray: bool,
    pub reasons: Vec<String>,
}

/// Chooses the working scale, crop and initial K for `measured`.
///
/// - Periodic (a period on both axes): the scale puts about two periods of the longer period in
///   a crop (never above the exemplar's own scale), and K starts where the encoding's lowest
///   octave repeats a power-of-two multiple of the period nearest one crop (K near 1).
/// - Stochastic (no clear period on an axis): the scale puts about four crops across the
///   exemplar's shorter side, and K starts at the exemplar's extent on that axis in crops, so
///   the encoding repeats no sooner than the exemplar does and paints no grid of crops.
pub fn choose(measured: &Measured) -> Recipe {
    let crop = RECIPE_CROP as f64;
    let short = measured.size[0].min(measured.size[1]) as f64;
    let longest = measured
        .period
        .iter()
        .flatten()
        .fold(0f64, |a, &p| a.max(p));
    let mut reasons = Vec::new();
    let periodic = measured.period.iter().all(Option::is_some);
    let resize = if periodic {
        let scale = (crop / (PERIODS_PER_CROP * longest)).min(1.0);
        // Keep at least two crops across the exemplar.
        scale.max((2.0 * crop / short).min(1.0))
    } else {
        (CROPS_PER_SIDE * crop / short).min(1.0)
    };
    let resize = (resize * 1000.0).round() / 1000.0;
    let k_init = initial_k(measured, resize, RECIPE_CROP);
    let fmt = |p: Option<f64>| p.map_or("none".to_string(), |v| format!("{v:.1} px"));
    reasons.push(format!(
        "exemplar {}x{}, period {} down, {} across",
        measured.size[1],
        measured.size[0],
        fmt(measured.period[0]),
        fmt(measured.period[1])
    ));
    reasons.push(if periodic {
        format!(
            "resize {resize} and crop {RECIPE_CROP}: a crop holds {:.1} periods",
            crop / (longest * resize)
        )
    } else {
        format!(
            "no clear period: resize {resize} puts {:.1} crops of {RECIPE_CROP} across the shorter side",
            short * resize / crop
        )
    });
    if measured.gray {
        reasons.push("every pixel's channels are equal: trained as gray (1 channel)".into());
    }
    Recipe {
        resize,
        crop: RECIPE_CROP,
        k_init,
        gray: measured.gray,
        reasons,
    }
}

/// The initial K per axis (rows, cols) for `measured` at working scale `resize` and `crop`:
/// where there is a period, the power-of-two multiple of it nearest one crop (the encoding's
/// octaves are powers of two apart, so each lines up with the period); where there is none,
/// the exemplar's extent in crops, at least 1.
pub fn initial_k(measured: &Measured, resize: f64, crop: usize) -> Vec<f32> {
    let crop = crop as f64;
    (0..2)
        .map(|axis| match measured.period[axis] {
            Some(p) => {
                let in_crops = p * resize / crop;
                let octaves = (1.0 / in_crops).log2().round();
                (in_crops * octaves.exp2()) as f32
            }
            None => (measured.size[axis] as f64 * resize / crop).max(1.0) as f32,
        })
        .collect()
}

impl Recipe {
    /// Writes the recipe's choices into `config`, except the keys in `explicit` (given in a
    /// config file or as flags); K is chosen for the crop and scale the run ends up with.
    /// Returns the lines that say what was chosen.
    pub fn apply(
        &self,
        measured: &Measured,
        config: &mut TrainConfig,
        explicit: &BTreeSet<String>,
    ) -> Vec<String> {
        let free = |key: &str| !explicit.contains(key);
        let mut applied = vec![self.reasons[0].clone()];
        if free("resize") && free("crop") {
            config.resize = self.resize;
            config.crop = self.crop;
            applied.push(self.reasons[1].clone());
        }
        if free("k_init") && !config.solid {
            let k = initial_k(measured, config.resize, config.crop);
            applied.push(format!(
                "K starts at {:.3} x {:.3} (rows x cols)",
                k[0], k[1]
            ));
            config.k_init = Some(k);
        }
        if free("gray") && self.gray {
            config.gray = true;
            applied.extend(self.reasons.last().cloned());
        }
        applied
    }
}

/// The time budget of a run that names neither a budget nor an iteration count.
pub const DEFAULT_TIME: &str = "15m";

/// Iterations at most, for a run with a time budget and no iteration count of its own.
pub const BUDGET_ITERATIONS: u64 = 1_000_000;

/// Completes the settings of a new run: `config` as given by a config file and flags
/// (`explicit` names the keys they set), then the recipe's choices from the exemplar (images and
/// solid textures), and a default time budget. Returns the lines that say what was chosen.
pub fn settle(
    config: &mut TrainConfig,
    source: &super::ExemplarSource,
    explicit: &BTreeSet<String>,
) -> crate::Result<Vec<String>> {
    config.time_budget()?;
    let mut lines = Vec::new();
    if let super::ExemplarSource::Image(path) = source {
        let exemplar = crate::exemplar::read_exemplar(path)?;
        let measured = measure(&exemplar);
        lines = choose(&measured).apply(&measured, config, explicit);
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

    #[test]
    fn a_periodic_exemplar_gets_two_periods_per_crop_and_k_on_the_period() {
        let m = Measured {
            size: [600, 600],
            channels: 3,
            gray: false,
            period: [Some(100.0), Some(100.0)],
        };
        let r = choose(&m);
        assert_eq!(r.crop, 64);
        assert!((r.resize - 0.32).abs() < 1e-9, "{}", r.resize);
        // One period is 32 px at the working scale, half a crop: K = 0.5 * 2 = 1 lines the
        // lowest octave up with two periods and the next with one.
        for k in &r.k_init {
            assert!((k - 1.0).abs() < 1e-6, "{k}");
        }
    }

    #[test]
    fn a_stochastic_exemplar_is_not_painted_as_a_grid_of_crops() {
        let m = Measured {
            size: [512, 512],
            channels: 1,
            gray: false,
            period: [None, None],
        };
        let r = choose(&m);
        assert!((r.resize - 0.5).abs() < 1e-9);
        // The encoding's period is the exemplar's extent: 256 px = 4 crops.
        for k in &r.k_init {
            assert!((k - 4.0).abs() < 1e-6, "{k}");
        }
    }
}

//! Quality regression: train on a shipped exemplar with a fixed seed and budget, evaluate
//! (SIFID and the structure distance), and compare with `benches/baselines.toml`. Exits 1,
//! printing the numbers, when either is above its threshold. `.ci/run` runs the `ci` budget;
//! the `quick` budget (configs/quick.toml as shipped) runs by hand:
//!
//! ```text
//! cargo bench --bench sifid                            # budget "ci"
//! IPFN_SIFID_BUDGET=quick cargo bench --bench sifid    # budget "quick"
//! IPFN_SIFID_RECORD=1 cargo bench --bench sifid        # measure only, print the numbers to record
//! IPFN_SIFID_RECORD=1 IPFN_SIFID_SEED=1 cargo bench --bench sifid   # another training seed
//! ```
//!
//! Beside our model it evaluates, in the same run, the untrained generator (what no learning
//! scores) and the IPFN authors' fully trained honeycomb generator (what a full run scores), so
//! the number can be read without a paper at hand. SIFID here uses the Keras InceptionV3 stem:
//! not comparable with the paper's torchvision-based values.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::prelude::*;
use ipfn::generator::{GeneratorConfig, GeneratorWeights};
use ipfn::metrics::{self, ModelReport};
use ipfn::train::{TrainConfig, Trainer};

/// One budget of `benches/baselines.toml`.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Baseline {
    /// Training config, relative to the repository root.
    config: String,
    /// Exemplar, relative to the repository root.
    exemplar: String,
    iterations: u64,
    seed: u64,
    /// Samples evaluated (seeds 0..samples).
    samples: usize,
    /// SIFID measured when the baseline was set.
    measured: Option<f64>,
    /// Fail above this.
    threshold: Option<f64>,
    date: Option<String>,
    command: Option<String>,
    /// Why the threshold is where it is.
    margin: Option<String>,
    /// The structure distance measured when the baseline was set, and the one to fail above.
    structure_measured: Option<f64>,
    structure_threshold: Option<f64>,
    /// Whether the config takes the recipe's choices from the exemplar (its working scale and
    /// the rest, `train::recipe::apply`), as `ipfn train` does for keys its config leaves free.
    #[serde(default)]
    recipe: bool,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn evaluate(
    config: &GeneratorConfig,
    weights: &GeneratorWeights,
    exemplar: &ipfn::exemplar::Exemplar,
    samples: usize,
    first_seed: u64,
) -> ModelReport {
    metrics::evaluate_model(
        metrics::Samples::cpu(config, weights, samples, first_seed),
        exemplar,
    )
    .expect("evaluation runs")
}

fn main() {
    let budget = std::env::var("IPFN_SIFID_BUDGET").unwrap_or_else(|_| "ci".into());
    let path = root().join("benches/baselines.toml");
    let text = std::fs::read_to_string(&path).expect("benches/baselines.toml");
    let baselines: BTreeMap<String, Baseline> =
        toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let Some(base) = baselines.get(&budget) else {
        eprintln!(
            "IPFN_SIFID_BUDGET={budget}: no such budget in {}; have {:?}",
            path.display(),
            baselines.keys().collect::<Vec<_>>()
        );
        std::process::exit(2);
    };
    let config_path = root().join(&base.config);
    let mut config = TrainConfig::from_toml(
        &std::fs::read_to_string(&config_path).expect("config"),
        &config_path,
    )
    .expect("config parses");
    config.iterations = base.iterations;
    let exemplar_path = root().join(&base.exemplar);
    let exemplar = ipfn::exemplar::read_exemplar(&exemplar_path).expect("exemplar");
    if base.recipe {
        let measured = ipfn::train::recipe::measure(&exemplar);
        let free = Default::default(); // the preset's keys, as `ipfn train` leaves them free
        for line in ipfn::train::recipe::apply(&measured, &mut config, &free, true) {
            println!("recipe: {line}");
        }
    }
    // Other training seeds measure the spread a threshold's margin must cover.
    config.seed = match std::env::var("IPFN_SIFID_SEED") {
        Ok(seed) => seed.parse().expect("IPFN_SIFID_SEED is a number"),
        Err(_) => base.seed,
    };

    println!(
        "SIFID regression, budget '{budget}': {} on {}, {} iterations, seed {}, {} samples at {}x{}",
        base.config,
        base.exemplar,
        base.iterations,
        config.seed,
        base.samples,
        exemplar.width,
        exemplar.height
    );
    let run = tempfile::tempdir().expect("temp dir");
    let mut trainer =
        Trainer::new(config, &exemplar_path, run.path(), &Device::flex()).expect("trainer");
    let (gc, gw) = trainer.model();
    let untrained = evaluate(&gc, &gw, &exemplar, base.samples, 0);

    let start = Instant::now();
    for i in 1..=base.iterations {
        trainer.step();
        if i % 100 == 0 || i == base.iterations {
            eprintln!(
                "  iteration {i}/{}: {:.0} s",
                base.iterations,
                start.elapsed().as_secs_f64()
            );
        }
    }
    let train_s = start.elapsed().as_secs_f64();
    let (gc, gw) = trainer.model();
    let ours = evaluate(&gc, &gw, &exemplar, base.samples, 0);

    let mut rows = vec![
        ("untrained generator (same config, seed)", untrained),
        ("ours after this budget", ours.clone()),
    ];
    if base.exemplar.ends_with("honeycomb.png") {
        let shipped = ipfn::checkpoint::Checkpoint::from_bytes(
            ipfn::model::SHIPPED_HONEYCOMB,
            Path::new("<shipped honeycomb>"),
        )
        .expect("shipped model");
        let (sc, sw) = GeneratorWeights::read_from(&shipped).expect("shipped model");
        // exemplars/honeycomb.png is this generator's own render with seed 0, so its samples
        // start at seed 1; it is still the model that drew the exemplar: a floor, not a rival.
        rows.push((
            "authors' trained generator, seeds 1.. (it drew the exemplar, with seed 0)",
            evaluate(&sc, &sw, &exemplar, base.samples, 1),
        ));
    }
    println!(
        "\ntrained {} iterations in {train_s:.0} s ({:.2} s/iteration, flex, {} threads)\n",
        base.iterations,
        train_s / base.iterations as f64,
        rayon::current_num_threads()
    );
    println!(
        "| model | SIFID mean ± std | / ours | structure mean ± std | tile seam score | period rows x cols (px) |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, r) in &rows {
        println!(
            "| {name} | {:.3} ± {:.3} | {:.2} | {:.4} ± {:.4} | {:.3} | {:.1} x {:.1} |",
            r.sifid.mean,
            r.sifid.std,
            r.sifid.mean / ours.sifid.mean,
            r.structure.mean,
            r.structure.std,
            r.seam_model_tile.overall,
            r.period_model[0],
            r.period_model[1]
        );
    }
    println!(
        "\nexemplar period (autocorrelation): {:?} x {:?}; structure floor (its halves): {:.4}; metric: {}",
        ours.period_exemplar[0].map(|v| (v * 10.0).round() / 10.0),
        ours.period_exemplar[1].map(|v| (v * 10.0).round() / 10.0),
        ours.structure_floor,
        metrics::SIFID_NAME
    );
    let record = std::env::var_os("IPFN_SIFID_RECORD").is_some_and(|v| v == "1");
    let (Some(measured), Some(threshold), false) = (base.measured, base.threshold, record) else {
        println!(
            "\nrecord in benches/baselines.toml [{budget}]: measured = {:.3}, structure_measured = {:.4}, date, command, and thresholds with their margin",
            ours.sifid.mean, ours.structure.mean
        );
        return;
    };
    println!(
        "baseline on {} ({}): {} ({})",
        base.date.as_deref().unwrap_or("?"),
        base.command.as_deref().unwrap_or("?"),
        base.thresholds_text(),
        base.margin.as_deref().unwrap_or("?")
    );
    // SIFID always; the structure distance where the budget records it.
    let structure = base.structure_threshold.zip(base.structure_measured);
    let checks = std::iter::once(("SIFID", ours.sifid.mean, threshold, measured)).chain(
        structure
            .map(|(threshold, measured)| ("STRUCTURE", ours.structure.mean, threshold, measured)),
    );
    let regressed = checks
        .filter(|&(_, ours, threshold, _)| ours > threshold)
        .inspect(|(name, ours, threshold, measured)| {
            eprintln!(
                "{name} REGRESSION: {ours:.4} > threshold {threshold:.4} (baseline {measured:.4} measured {}); find the change that made training worse, do not raise the threshold to pass",
                base.date.as_deref().unwrap_or("?")
            )
        })
        .count();
    if regressed > 0 {
        std::process::exit(1);
    }
    println!(
        "ok: SIFID {:.3} <= {threshold:.3}; structure {:.4}{}",
        ours.sifid.mean,
        ours.structure.mean,
        structure.map_or(" (no threshold in this budget)".into(), |(t, _)| format!(
            " <= {t:.4}"
        ))
    );
}

impl Baseline {
    /// The measured figures and thresholds, for the log.
    fn thresholds_text(&self) -> String {
        let sifid = format!(
            "SIFID {:.3}, threshold {:.3}",
            self.measured.unwrap_or(f64::NAN),
            self.threshold.unwrap_or(f64::NAN)
        );
        match self.structure_measured.zip(self.structure_threshold) {
            Some((m, t)) => format!("{sifid}; structure {m:.4}, threshold {t:.4}"),
            None => sifid,
        }
    }
}

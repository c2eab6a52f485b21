//! The guide's "`ipfn eval`: how good is a model" (docs/guide/eval.md), as library calls.
//!
//! `cargo run --release --example 08_eval` scores the shipped honeycomb model against the
//! shipped honeycomb exemplar: SIFID and structure distance over 2 samples (beside the
//! exemplar's structure floor), the seam score of `--tile` samples laid 2x2, and the period
//! from K beside the exemplar's autocorrelation peak.

use std::path::Path;

use ipfn::metrics::{Samples, evaluate_model};
use ipfn::model::shipped_model;

fn main() -> ipfn::Result<()> {
    let (config, weights) = shipped_model()?;
    let exemplar = ipfn::exemplar::read_exemplar(Path::new("exemplars/honeycomb.png"))?;
    // `ipfn eval --exemplar exemplars/honeycomb.png --samples 2`
    // Two samples (seeds 0 and 1) painted on the CPU.
    let report = evaluate_model(Samples::cpu(&config, &weights, 2, 0), &exemplar)?;
    println!(
        "SIFID {:.3} ± {:.3}; structure {:.4} (floor {:.4}); seam score {:.3} (exemplar laid 2x2: {:.3}); period {:.1} x {:.1} px",
        report.sifid.mean,
        report.sifid.std,
        report.structure.mean,
        report.structure_floor,
        report.seam_model_tile.overall,
        report.seam_exemplar.overall,
        report.period_model[0],
        report.period_model[1]
    );
    Ok(())
}

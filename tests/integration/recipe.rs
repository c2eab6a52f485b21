//! Training settings from the machine and the exemplar: on the CPU the preset's
//! network, scale and crop; the exemplar's period is measured and reported, a gray photo trains
//! as gray; a time budget plans the run's length; the run scores its checkpoints (SIFID) and
//! keeps the best as `best.ipfn`, which synth prefers.

use crate::common;

use crate::common::{ipfn, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::generator::GeneratorWeights;
use ipfn::train::TrainConfig;

/// A small generator and critic; neither crop, resize nor iterations: the recipe and the time
/// budget choose them.
const TINY: &str = r#"
batch = 2
critic_widths = [8, 16, 16, 16]
hidden_layers = 3
width = 16
checkpoint_every = 5
preview_every = 1000
log_every = 1000
"#;

#[test]
fn a_time_budget_plans_the_run_scores_it_and_keeps_the_best() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Bricks of 32 px: a period of 32 down and across, in a 128 px exemplar.
    assert!(
        ipfn(d, &["draw", "bricks", "--size", "128", "-o", "b.png"])
            .status
            .success()
    );
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    let out = ipfn(
        d,
        &[
            "train",
            "b.png",
            "--config",
            "tiny.toml",
            "--time",
            "12s",
            "--out",
            "runs/b",
        ],
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    for said in [
        "px down",
        "on the CPU",
        "would start an octave",
        "time budget 12s",
    ] {
        assert!(err.contains(said), "the recipe should say '{said}': {err}");
    }
    // The plan replaced the budget by an iteration count, so a resume continues exactly.
    let config = std::fs::read_to_string(d.join("runs/b/config.toml")).unwrap();
    let config = TrainConfig::from_toml(&config, std::path::Path::new("config.toml")).unwrap();
    assert_eq!(config.time, None);
    assert!(
        config.iterations >= 3 && config.iterations < 1_000_000,
        "{}",
        config.iterations
    );
    // On the CPU configs/cpu.toml's scale and crop; K from 1 (the period's K is only suggested).
    assert_eq!((config.crop, config.resize), (32, 1.0));
    assert_eq!(config.k_init, None);
    assert_eq!(config.k_lr, 10.0, "a plain image takes K's own rate");
    // The exemplar's structure floor is printed once, before training.
    let floor_line = err
        .lines()
        .find(|l| l.starts_with("structure floor "))
        .unwrap();
    let floor: f64 = floor_line
        .split(' ')
        .nth(2)
        .unwrap()
        .trim_end_matches(':')
        .parse()
        .unwrap();
    assert!((0.0..1.0).contains(&floor), "{floor_line}");
    assert_eq!(err.matches("structure floor").count(), 1, "{err}");
    // Every checkpoint row carries a finite SIFID, repeat strength and structure distance;
    // others leave them empty.
    let metrics = std::fs::read_to_string(d.join("runs/b/metrics.csv")).unwrap();
    assert!(
        metrics
            .lines()
            .next()
            .unwrap()
            .ends_with(",sifid,repeat,structure")
    );
    let scored: Vec<[f64; 3]> = metrics
        .lines()
        .skip(1)
        .filter_map(|l| {
            let cells: Vec<&str> = l.rsplitn(4, ',').take(3).collect();
            let (structure, repeat, sifid) = (cells[0], cells[1], cells[2]);
            assert_eq!(sifid.is_empty(), repeat.is_empty(), "{l}");
            assert_eq!(sifid.is_empty(), structure.is_empty(), "{l}");
            (!sifid.is_empty()).then(|| [sifid, repeat, structure].map(|v| v.parse().unwrap()))
        })
        .collect();
    assert!(!scored.is_empty());
    for &[sifid, repeat, structure] in &scored {
        assert!(sifid.is_finite() && sifid >= 0.0 && (0.0..=1.0).contains(&repeat));
        assert!(structure.is_finite() && structure > 0.0, "{structure}");
    }
    // best.ipfn holds the checkpoint's generator with the lowest SIFID x structure, and synth
    // prefers it.
    let best = Checkpoint::load(&d.join("runs/b/best.ipfn")).unwrap();
    GeneratorWeights::read_from(&best).unwrap();
    let lowest = scored
        .iter()
        .map(|[sifid, _, structure]| sifid * structure)
        .fold(f64::INFINITY, f64::min);
    let latest = Checkpoint::load(&d.join("runs/b/latest.ipfn")).unwrap();
    let (score, _) = latest.meta("best_score").unwrap().split_once(' ').unwrap();
    assert!((score.parse::<f64>().unwrap() - lowest).abs() <= 1e-9 * lowest.max(1.0));
    assert!(
        latest.meta("best_sifid").is_err(),
        "the old key is no longer written"
    );
    let synth = ipfn(d, &["synth", "--size", "64", "--out", "s.png"]);
    assert!(synth.status.success(), "{}", stderr(&synth));
    assert!(stderr(&synth).contains("best.ipfn"), "{}", stderr(&synth));
    let by_folder = ipfn(
        d,
        &[
            "synth", "--model", "runs/b", "--size", "64", "--out", "t.png",
        ],
    );
    assert!(by_folder.status.success(), "{}", stderr(&by_folder));
    assert!(stderr(&by_folder).contains("best.ipfn"));
}

/// Trains `exemplar` (in `d`) for one iteration with the `config` file and `extra` flags into
/// `out`; returns what training said and the run's saved settings.
fn train_once(
    d: &std::path::Path,
    exemplar: &str,
    config: &str,
    out: &str,
    extra: &[&str],
) -> (String, TrainConfig) {
    let mut args = vec!["train", exemplar, "--config", config];
    args.extend(["--iterations", "1", "--out", out]);
    args.extend(extra);
    let run = ipfn(d, &args);
    assert!(run.status.success(), "{}", stderr(&run));
    let text = std::fs::read_to_string(d.join(out).join("config.toml")).unwrap();
    let config = TrainConfig::from_toml(&text, std::path::Path::new("config.toml")).unwrap();
    (stderr(&run), config)
}

/// A periodic photo whose cells are wider than a crop trains at the scale at which a crop holds
/// one (the shipped honeycomb: cells 59.5 px across, crops of 32 px, scale 0.5), and still
/// paints at its own scale; a run that sets its scale keeps it, and the CPU's crop, and is told
/// when that crop holds less than one cell.
#[test]
fn a_crop_holds_a_whole_cell_of_a_periodic_photo() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let honeycomb =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars/honeycomb.png");
    std::fs::copy(honeycomb, d.join("h.png")).unwrap();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    let train = |out: &str, extra: &[&str]| train_once(d, "h.png", "tiny.toml", out, extra);
    let (err, config) = train("runs/h", &[]);
    assert!(err.contains("working scale 0.5"), "{err}");
    assert_eq!((config.crop, config.resize), (32, 0.5));
    let model = Checkpoint::load(&d.join("runs/h/latest.ipfn")).unwrap();
    let (generator, _) = GeneratorWeights::read_from(&model).unwrap();
    assert_eq!(generator.crop, 64, "the model's pixel is the exemplar's");
    let (err, config) = train("runs/own", &["--resize", "1"]);
    assert!(!err.contains("working scale"), "{err}");
    assert_eq!(config.resize, 1.0);
    // The scale alone leaves the CPU's crop: 128-px crops would train at a tenth of the speed.
    assert_eq!(config.crop, 32, "{err}");
    assert!(err.contains("crop as configs/cpu.toml"), "{err}");
    // ... and says that a 32-px crop now holds less than one 59.5-px cell, with the way out.
    assert!(
        err.contains("a 32 px crop holds less than one period (59.5 px at --resize 1)"),
        "{err}"
    );
    assert!(err.contains("--crop 64 holds one"), "{err}");
    let (err, _) = train("runs/half", &["--resize", "0.5"]);
    assert!(!err.contains("less than one period"), "{err}");
}

/// A running bond (each course's joints halfway between the last one's): the recipe trains it
/// with K held on the two courses after which it repeats and the coarse critic over three, and
/// a run that sets any of those keys keeps its own.
#[test]
fn alternating_rows_train_with_k_held_on_two_courses_and_the_coarse_critic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 48x16 bricks with 2-px mortar, every other course shifted by half a brick.
    let bond = image::GrayImage::from_fn(256, 256, |x, y| {
        let shift = (y / 16 % 2) * 24;
        let mortar = y % 16 < 2 || (x + shift) % 48 < 2;
        image::Luma([if mortar { 255 } else { 77 }])
    });
    bond.save(d.join("bond.png")).unwrap();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    let train =
        |out: &str, config: &str, extra: &[&str]| train_once(d, "bond.png", config, out, extra);
    let (err, config) = train("runs/bond", "tiny.toml", &[]);
    // Courses of 16 px at scale 1 and 32-px crops: three courses are 48 px, a stride of 2.
    assert!(
        err.contains("the rows alternate: K held on two courses"),
        "{err}"
    );
    assert!(err.contains("(--coarse-stride 2)"), "{err}");
    assert_eq!((config.coarse_stride, config.k_lr), (2, 0.0), "{err}");
    // K down on two courses (32 px: one crop); across, an octave on the period measured there.
    let k = config.k_init.clone().expect("K is set");
    assert!((k[0] - 1.0).abs() < 0.05 && k[1] > 0.5, "{k:?}");
    let said = format!("k_init = [{:.3}, {:.3}], k_lr = 0", k[0], k[1]);
    assert!(err.contains(&said), "{err}");
    let model = Checkpoint::load(&d.join("runs/bond/latest.ipfn")).unwrap();
    assert!(
        model
            .tensors
            .keys()
            .any(|k| k.starts_with("coarse_critic.")),
        "the coarse critic is saved"
    );
    // A run that sets one of the three keys keeps K free and no coarse critic.
    let (err, config) = train("runs/own", "tiny.toml", &["--coarse-stride", "0"]);
    assert!(!err.contains("the rows alternate: K held"), "{err}");
    assert_eq!((config.coarse_stride, config.k_init), (0, None), "{err}");
    assert_ne!(config.k_lr, 0.0);
}

#[test]
fn a_gray_photo_stored_as_rgb_trains_and_paints_as_gray() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Stripes in gray, stored with three equal channels.
    let gray: Vec<f32> = ipfn::procedural::stripes(96, 96, 24.0)
        .chunks_exact(3)
        .flat_map(|p| [p[0] * 2.0 - 1.0; 3])
        .collect();
    ipfn::io::write_png(&d.join("g.png"), 96, 96, 3, &gray).unwrap();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    let out = ipfn(
        d,
        &[
            "train",
            "g.png",
            "--config",
            "tiny.toml",
            "--crop",
            "32",
            "--iterations",
            "2",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("trained as gray"), "{}", stderr(&out));
    let model = Checkpoint::load(&d.join("run/latest.ipfn")).unwrap();
    let (config, _) = GeneratorWeights::read_from(&model).unwrap();
    assert_eq!(config.channels, 1);
    let synth = ipfn(
        d,
        &["synth", "--model", "run", "--size", "40", "--out", "s.png"],
    );
    assert!(synth.status.success(), "{}", stderr(&synth));
    let image = image::open(d.join("s.png")).unwrap();
    assert_eq!(image.color(), image::ColorType::L8);
    // `ipfn eval` compares the gray model with the RGB photo it came from.
    let eval = ipfn(
        d,
        &[
            "eval",
            "--model",
            "run/latest.ipfn",
            "--exemplar",
            "g.png",
            "--samples",
            "1",
        ],
    );
    assert!(eval.status.success(), "{}", stderr(&eval));
    let report = String::from_utf8(eval.stdout).unwrap();
    assert!(
        report.contains("SIFID ") && report.contains("structure "),
        "{report}"
    );
}

#[test]
fn flags_and_config_keys_override_the_recipe() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(
        ipfn(d, &["draw", "bricks", "--size", "128", "-o", "b.png"])
            .status
            .success()
    );
    let config = format!("{TINY}\ncrop = 32\nresize = 1.0\nk_init = [0.5, 2.0]\n");
    std::fs::write(d.join("c.toml"), config).unwrap();
    let out = ipfn(
        d,
        &[
            "train",
            "b.png",
            "--config",
            "c.toml",
            "--iterations",
            "1",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let saved = std::fs::read_to_string(d.join("run/config.toml")).unwrap();
    let saved = TrainConfig::from_toml(&saved, std::path::Path::new("config.toml")).unwrap();
    assert_eq!((saved.crop, saved.resize, saved.iterations), (32, 1.0, 1));
    assert_eq!(saved.k_init, Some(vec![0.5, 2.0]));
    assert_eq!(
        saved.time, None,
        "an iteration count means no default budget"
    );
}

/// A photo with no clear period trains with the diversity hinge, unless the run's config or
/// flags set it.
#[test]
fn a_photo_without_a_period_trains_with_the_diversity_hinge() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // White noise: no period on either axis.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let noise: Vec<f32> = (0..96 * 96 * 3)
        .map(|_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / 8_388_608.0 - 1.0
        })
        .collect();
    ipfn::io::write_png(&d.join("n.png"), 96, 96, 3, &noise).unwrap();
    std::fs::write(d.join("tiny.toml"), TINY).unwrap();
    std::fs::write(d.join("off.toml"), format!("{TINY}\ndiversity = 0.0\n")).unwrap();
    let train = |config: &str, out: &str, flags: &[&str]| {
        let mut args = vec![
            "train",
            "n.png",
            "--config",
            config,
            "--crop",
            "32",
            "--iterations",
            "1",
            "--out",
            out,
        ];
        args.extend_from_slice(flags);
        let run = ipfn(d, &args);
        assert!(run.status.success(), "{}", stderr(&run));
        let saved = std::fs::read_to_string(d.join(out).join("config.toml")).unwrap();
        let saved = TrainConfig::from_toml(&saved, std::path::Path::new("config.toml")).unwrap();
        (saved.diversity, stderr(&run))
    };
    let (diversity, err) = train("tiny.toml", "on", &[]);
    assert_eq!(diversity, 1.0, "{err}");
    assert!(err.contains("no clear period: diversity 1"), "{err}");
    assert_eq!(train("off.toml", "off", &[]).0, 0.0);
    assert_eq!(train("tiny.toml", "flag", &["--diversity", "0.5"]).0, 0.5);
}

#[test]
fn durations_parse_and_bad_ones_are_one_line_errors() {
    use ipfn::train::config::parse_duration;
    assert_eq!(parse_duration("15m").unwrap().as_secs(), 900);
    assert_eq!(parse_duration("1h30m").unwrap().as_secs(), 5400);
    assert_eq!(parse_duration("90").unwrap().as_secs(), 90);
    for bad in ["", "0s", "fast", "5x"] {
        let e = parse_duration(bad).unwrap_err().to_string();
        assert!(e.contains("--time") && !e.contains('\n'), "{e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(dir.path(), &["train", "x.png", "--time", "soon"]);
    common::assert_error(&out, &["--time soon"]);
}

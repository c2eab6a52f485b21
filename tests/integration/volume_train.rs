//! Training on signed-distance volumes: `ipfn train volume.npy` learns a 3D generator
//! against the 3D critic on cubic crops, resumes exactly, and its volumes take on the
//! exemplar's structure.

use crate::common;

use crate::common::{assert_error, ipfn, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::exemplar::read_sdf_volume;
use ipfn::generator::GeneratorWeights;
use ipfn::io::read_npy;
use npyz::WriterBuilder;

/// A small model and 3D critic (crop 16, 4x32 generator): 300 iterations take about 95 s on 2
/// cores.
const VOLUME_CONFIG: &str = r#"
batch = 4
crop = 16
lr = 2e-4
critic_widths = [16, 32, 64, 64]
hidden_layers = 4
width = 32
checkpoint_every = 100
preview_every = 100
log_every = 100
"#;

fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("v.toml"), VOLUME_CONFIG).unwrap();
    let out = ipfn(
        d,
        &[
            "draw", "gyroid", "--size", "48", "--period", "16", "-o", "g.npy",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    dir
}

fn train(d: &std::path::Path, args: &[&str]) {
    let mut all = vec!["train", "g.npy", "--config", "v.toml"];
    all.extend_from_slice(args);
    let out = ipfn(d, &all);
    assert!(out.status.success(), "{all:?}: {}", stderr(&out));
}

/// The 1-Wasserstein distance between the value distributions of two equally sized volumes.
fn value_distance(a: &[f32], b: &[f32]) -> f64 {
    let sorted = |v: &[f32]| {
        let mut v = v.to_vec();
        v.sort_by(f32::total_cmp);
        v
    };
    let (a, b) = (sorted(a), sorted(b));
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs() as f64)
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn a_volume_model_takes_on_the_exemplars_structure() {
    let dir = setup();
    let d = dir.path();
    train(d, &["--iterations", "300", "--out", "run"]);
    train(d, &["--iterations", "1", "--out", "untrained"]);
    let model = Checkpoint::load(&d.join("run/latest.ipfn")).unwrap();
    let (config, _) = GeneratorWeights::read_from(&model).unwrap();
    assert_eq!((config.dims, config.channels), (3, 1), "a 3D SDF generator");
    assert!(d.join("run/previews/iter-000300.png").is_file());

    let exemplar = read_sdf_volume(&d.join("g.npy"), 10.0).unwrap().values;
    let porosity = |v: &[f32]| v.iter().filter(|&&x| x < 0.0).count() as f64 / v.len() as f64;
    let mut distances = Vec::new();
    for run in ["run", "untrained"] {
        let out = ipfn(
            d,
            &[
                "synth",
                "--model",
                &format!("{run}/latest.ipfn"),
                "--size",
                "48x48x48",
                "--out",
                &format!("{run}.npy"),
                "--mesh",
                &format!("{run}.obj"),
            ],
        );
        assert!(out.status.success(), "{}", stderr(&out));
        let (shape, values) = read_npy(&d.join(format!("{run}.npy"))).unwrap();
        assert_eq!(shape, vec![48, 48, 48, 1]);
        let distance = value_distance(&values, &exemplar);
        eprintln!(
            "{run}: porosity {:.3} (exemplar {:.3}), value distance {distance:.3}",
            porosity(&values),
            porosity(&exemplar)
        );
        distances.push((porosity(&values), distance));
    }
    // Measured: trained porosity 0.173 (exemplar 0.258), value distance 0.054 trained and
    // 0.478 after 1 iteration (a volume all inside).
    let (p, trained) = distances[0];
    let (_, untrained) = distances[1];
    assert!(
        trained < 0.25 * untrained,
        "value distance {trained:.3} trained is not under a quarter of {untrained:.3} untrained"
    );
    assert!(
        (0.1..0.45).contains(&p),
        "porosity {p:.3}: a porous solid should be neither empty nor full"
    );
    let mesh = std::fs::read_to_string(d.join("run.obj")).unwrap();
    assert!(
        mesh.lines().filter(|l| l.starts_with("f ")).count() > 1000,
        "the trained volume's surface is meshed"
    );
}

#[test]
fn volume_runs_resume_bit_exactly() {
    let dir = setup();
    let d = dir.path();
    train(d, &["--iterations", "4", "--out", "one"]);
    train(d, &["--iterations", "2", "--out", "two"]);
    let out = ipfn(d, &["train", "--resume", "two", "--iterations", "4"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let a = Checkpoint::load(&d.join("one/latest.ipfn")).unwrap();
    let b = Checkpoint::load(&d.join("two/latest.ipfn")).unwrap();
    assert_eq!(b.metadata["iteration"], "4");
    assert!(
        a.tensors.keys().any(|k| k.starts_with("adam.critic.m.")),
        "optimiser state is saved"
    );
    assert_eq!(a.tensors.len(), b.tensors.len());
    for (name, t) in &a.tensors {
        assert!(
            t == &b.tensors[name],
            "{name} differs between 4 iterations and 2 + 2 resumed"
        );
    }
    let config = std::fs::read_to_string(d.join("one/config.toml")).unwrap();
    assert!(config.contains("volume = true"), "{config}");
    // metrics.csv logs K for all three axes, and the resumed run's rows match the straight one.
    let metrics = |run: &str| std::fs::read_to_string(d.join(run).join("metrics.csv")).unwrap();
    let straight = metrics("one");
    assert_eq!(
        straight.lines().next().unwrap(),
        "iteration,wasserstein,penalty,generator_loss,k_depth,k_rows,k_cols,iterations_per_second,sifid,repeat,structure"
    );
    assert_eq!(straight.lines().count(), 5, "header + 4 rows:\n{straight}");
    let without_speed = |m: String| -> Vec<String> {
        // Every column but iterations_per_second (the 8th), which is a timing.
        m.lines()
            .map(|l| {
                let mut fields: Vec<&str> = l.split(',').collect();
                fields.remove(7);
                fields.join(",")
            })
            .collect()
    };
    assert_eq!(without_speed(straight), without_speed(metrics("two")));
}

#[test]
fn bad_volume_training_input_is_one_line() {
    let dir = setup();
    let d = dir.path();
    let bad = |args: &[&str], needles: &[&str]| {
        let mut all = vec!["train"];
        all.extend_from_slice(args);
        assert_error(&ipfn(d, &all), needles);
    };
    bad(
        &["g.npy", "--config", "v.toml", "--crop", "64"],
        &["g.npy", "48x48x48", "64 voxel crop"],
    );
    bad(
        &["g.npy", "--config", "v.toml", "--solid"],
        &["g.npy", "--solid"],
    );
    bad(
        &["g.npy", "--config", "v.toml", "--crop", "24"],
        &["crop 24", "multiple of 16"],
    );
    // A 2D array is not a volume.
    {
        let file = std::io::BufWriter::new(std::fs::File::create(d.join("flat.npy")).unwrap());
        let mut writer = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[8, 8])
            .writer(file)
            .begin_nd()
            .unwrap();
        writer.extend([0f32; 64]).unwrap();
        writer.finish().unwrap();
    }
    bad(&["flat.npy"], &["flat.npy", "3D float array"]);
    // A volume model cannot paint an image.
    train(d, &["--iterations", "1", "--out", "run"]);
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                "run/latest.ipfn",
                "--size",
                "32",
                "-o",
                "x.png",
            ],
        ),
        &["3 coordinate axes", "2D model"],
    );
}

/// Porosity (fraction of voxels inside, sdf < 0) of each third of a D×H×W volume along x.
fn porosity_thirds(values: &[f32], side: usize) -> [f64; 3] {
    let mut inside = [0usize; 3];
    let mut total = [0usize; 3];
    for (i, v) in values.iter().enumerate() {
        let third = (i % side) * 3 / side;
        total[third] += 1;
        inside[third] += usize::from(*v < 0.0);
    }
    std::array::from_fn(|t| inside[t] as f64 / total[t] as f64)
}

/// Paper Fig. 7: a model trained with `--density` on a gyroid whose wall thickness grows along
/// x paints porosity that follows a requested density ramp, and turns when the ramp is reversed.
#[test]
fn density_control_follows_the_requested_ramp() {
    let dir = setup();
    let d = dir.path();
    let out = ipfn(
        d,
        &[
            "draw", "gyroid", "--size", "48", "--period", "16", "--graded", "-o", "gg.npy",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let out = ipfn(
        d,
        &[
            "train",
            "gg.npy",
            "--config",
            "v.toml",
            "--density",
            "--iterations",
            "300",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let paint = |ramp: &str, name: &str| {
        let out = ipfn(
            d,
            &[
                "synth",
                "--model",
                "run/latest.ipfn",
                "--size",
                "48x48x48",
                &format!("--density={ramp}"),
                "--out",
                name,
            ],
        );
        assert!(out.status.success(), "{ramp}: {}", stderr(&out));
        let (shape, values) = read_npy(&d.join(name)).unwrap();
        assert_eq!(shape, vec![48, 48, 48, 1]);
        let thirds = porosity_thirds(&values, 48);
        eprintln!("density {ramp}: porosity by third along x {thirds:.3?}");
        thirds
    };
    // Mean |sdf| falls as porosity rises: a ramp from dense walls (0.36) to thin ones (0.2)
    // should open the solid along x. Measured: [0.17, 0.31, 0.38] and reversed
    // [0.41, 0.31, 0.15]. Never loosen these bounds to make a change pass.
    let opening = paint("0.36,0.2", "opening.npy");
    let closing = paint("0.2,0.36", "closing.npy");
    for (name, p, sign) in [("0.36,0.2", opening, 1.0), ("0.2,0.36", closing, -1.0)] {
        assert!(
            sign * (p[1] - p[0]) > 0.03 && sign * (p[2] - p[1]) > 0.03,
            "porosity {p:.3?} along the ramp {name} is not monotone"
        );
        assert!(
            sign * (p[2] - p[0]) > 0.12,
            "porosity {p:.3?} along the ramp {name} changes too little"
        );
    }
    // A constant density sets the porosity of the whole volume.
    let mean = |p: [f64; 3]| p.iter().sum::<f64>() / 3.0;
    let dense = mean(paint("0.36", "dense.npy"));
    let open = mean(paint("0.2", "open.npy"));
    assert!(
        open > dense + 0.1,
        "density 0.2 gives porosity {open:.3}, density 0.36 gives {dense:.3}"
    );
}

/// Volume training (3D convolutions, their transposes in the penalty, a density channel) runs
/// on wgpu, lavapipe in CI: two iterations with finite losses and a resumable checkpoint.
#[cfg(feature = "wgpu")]
#[test]
#[ignore = "needs a wgpu adapter (CI: lavapipe); run by `cargo test --release -- --ignored`"]
fn volume_training_runs_on_wgpu() {
    let dir = setup();
    let d = dir.path();
    train(
        d,
        &[
            "--iterations",
            "2",
            "--critic-steps",
            "1",
            "--generator-steps",
            "1",
            "--density",
            "--device",
            "wgpu",
            "--out",
            "gpu",
        ],
    );
    let latest = Checkpoint::load(&d.join("gpu/latest.ipfn")).unwrap();
    assert_eq!(latest.metadata["iteration"], "2");
    let last = common::last_metrics_row(&d.join("gpu"));
    assert_eq!(last.len(), 8, "iteration, 3 losses, 3 K, speed: {last:?}");
    assert!(
        last.iter().all(|v| v.is_finite()),
        "finite losses on wgpu: {last:?}"
    );
}

//! Sharded synthesis into Zarr v3 stores: N concurrent worker processes fill one store with
//! exactly the values of a single render, a killed worker's rerun completes it, GNU parallel
//! runs the README's line as written, and zarr-python reads what we wrote.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;

use crate::common::{assert_error, ipfn, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::generator::{GeneratorConfig, GeneratorWeights};
use ipfn::io::read_npy;
use zarrs::array::Array;
use zarrs::filesystem::FilesystemStore;

fn spawn(dir: &Path, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ipfn starts")
}

/// Runs `count` shards of `args` (with `--shard k/count` appended) as concurrent processes.
fn run_shards(dir: &Path, args: &[&str], count: usize) {
    let workers: Vec<Child> = (0..count)
        .map(|k| {
            let shard = format!("{k}/{count}");
            let mut all = args.to_vec();
            all.extend(["--shard", &shard]);
            spawn(dir, &all)
        })
        .collect();
    for worker in workers {
        let out = worker.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
    }
}

/// The store's whole array read back through `zarrs`: (shape, values in C order).
fn read_zarr_f32(path: &Path) -> (Vec<usize>, Vec<f32>) {
    let store = Arc::new(FilesystemStore::new(path).unwrap());
    let array = Array::open(store, "/").unwrap();
    let shape = array.shape().iter().map(|&s| s as usize).collect();
    let values: Vec<f32> = array.retrieve_array_subset(&array.subset_all()).unwrap();
    (shape, values)
}

fn chunk_files(store: &Path) -> usize {
    fn count(dir: &Path) -> usize {
        std::fs::read_dir(dir).map_or(0, |entries| {
            entries
                .flatten()
                .map(|e| {
                    let p = e.path();
                    if p.is_dir() {
                        count(&p)
                    } else {
                        usize::from(!e.file_name().to_string_lossy().starts_with('.'))
                    }
                })
                .sum()
        })
    }
    count(&store.join("c"))
}

/// A random 3D model with two channels, saved as `models/m3.ipfn` in `dir` (not in `dir`
/// itself, where `synth` would take it as the default model).
fn save_model_3d(dir: &Path) -> PathBuf {
    let config = GeneratorConfig::new()
        .with_dims(3)
        .with_channels(2)
        .with_hidden_layers(2)
        .with_width(16)
        .with_crop(32);
    let weights = GeneratorWeights::random(&config, 0);
    let mut ckpt = Checkpoint::new();
    weights.write_to(&config, &mut ckpt);
    std::fs::create_dir_all(dir.join("models")).unwrap();
    let path = dir.join("models/m3.ipfn");
    ckpt.save(&path).unwrap();
    path
}

#[test]
fn image_shards_as_processes_equal_one_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 100x70 in chunks of 32: a 3x4 grid with cut chunks on the right and bottom edges.
    let common = [
        "synth", "--size", "100x70", "--seed", "3", "--offset", "-17,5",
    ];
    let out = ipfn(d, &[&common[..], &["--out", "one.npy"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let (shape, expected) = read_npy(&d.join("one.npy")).unwrap();
    assert_eq!(shape, [70, 100, 3]);
    for n in [1, 2, 4, 7] {
        let store = format!("s{n}.zarr");
        run_shards(
            d,
            &[&common[..], &["--chunk", "32", "--out", &store]].concat(),
            n,
        );
        let (zshape, values) = read_zarr_f32(&d.join(&store));
        assert_eq!(zshape, shape, "{n} shards");
        assert_eq!(
            values, expected,
            "{n} shards: values differ from one render"
        );
        assert_eq!(chunk_files(&d.join(&store)), 12);
    }
}

#[test]
fn volume_shards_as_processes_equal_one_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    save_model_3d(d);
    let common = [
        "synth",
        "--model",
        "models/m3.ipfn",
        "--size",
        "40x30x20",
        "--seed",
        "9",
    ];
    let out = ipfn(d, &[&common[..], &["--out", "one.npy"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let (shape, expected) = read_npy(&d.join("one.npy")).unwrap();
    assert_eq!(shape, [20, 30, 40, 2]);
    for n in [1, 2, 4, 7] {
        let store = format!("v{n}.zarr");
        run_shards(
            d,
            &[&common[..], &["--chunk", "16", "--out", &store]].concat(),
            n,
        );
        let (zshape, values) = read_zarr_f32(&d.join(&store));
        assert_eq!(zshape, shape, "{n} shards");
        assert_eq!(
            values, expected,
            "{n} shards: values differ from one render"
        );
    }
}

/// A worker killed mid-way (SIGKILL: no chance to clean up) and run again completes the same
/// array, skipping the chunks it had finished.
#[test]
fn killed_shard_rerun_completes_the_array() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "synth",
        "--size",
        "1024x1024",
        "--seed",
        "4",
        "--chunk",
        "32",
        "--out",
        "k.zarr",
    ];
    let total = 32 * 32;
    let mut worker = spawn(d, &args);
    let store = d.join("k.zarr");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while chunk_files(&store) < 5 && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    worker.kill().unwrap();
    worker.wait().unwrap();
    let before = chunk_files(&store);
    assert!(
        (5..total).contains(&before),
        "the worker should be stopped mid-way: {before} of {total} chunks"
    );
    let out = ipfn(d, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!("{before} already complete and skipped")),
        "{}",
        stderr(&out)
    );
    assert_eq!(chunk_files(&store), total);
    let out = ipfn(
        d,
        &[
            "synth",
            "--size",
            "1024x1024",
            "--seed",
            "4",
            "--out",
            "k.npy",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        read_zarr_f32(&store).1,
        read_npy(&d.join("k.npy")).unwrap().1
    );
}

/// `--bits 8` and `--bits 16` store the levels PNG output holds.
#[test]
fn integer_stores_hold_the_png_levels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for bits in ["8", "16"] {
        let store = format!("b{bits}.zarr");
        let png = format!("b{bits}.png");
        let args = ["synth", "--size", "50x40", "--seed", "2", "--bits", bits];
        for extra in [&["--chunk", "16", "--out", &store][..], &["--out", &png]] {
            let o = ipfn(d, &[&args[..], extra].concat());
            assert!(o.status.success(), "{}", stderr(&o));
        }
        let array =
            Array::open(Arc::new(FilesystemStore::new(d.join(&store)).unwrap()), "/").unwrap();
        let image = image::open(d.join(&png)).unwrap();
        if bits == "8" {
            let v: Vec<u8> = array.retrieve_array_subset(&array.subset_all()).unwrap();
            assert_eq!(v, image.to_rgb8().into_raw());
        } else {
            let v: Vec<u16> = array.retrieve_array_subset(&array.subset_all()).unwrap();
            assert_eq!(v, image.to_rgb16().into_raw());
        }
    }
}

/// A store is never mixed: another render's store, a plain file or a foreign folder is refused
/// with one line, and shard flags are checked.
#[test]
fn stores_are_not_mixed_and_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = ipfn(
        d,
        &["synth", "--size", "40", "--seed", "1", "--out", "a.zarr"],
    );
    assert!(first.status.success(), "{}", stderr(&first));
    let other = ipfn(
        d,
        &["synth", "--size", "40", "--seed", "2", "--out", "a.zarr"],
    );
    assert_error(&other, &["a.zarr", "holds another array"]);
    std::fs::create_dir(d.join("f.zarr")).unwrap();
    std::fs::write(d.join("f.zarr/notes.txt"), "mine").unwrap();
    let foreign = ipfn(d, &["synth", "--size", "40", "--out", "f.zarr"]);
    assert_error(&foreign, &["f.zarr", "no zarr.json"]);
    let shard = ipfn(
        d,
        &["synth", "--size", "40", "--out", "b.zarr", "--shard", "4/4"],
    );
    assert_eq!(shard.status.code(), Some(2), "{}", stderr(&shard));
    assert!(stderr(&shard).contains("K < N"), "{}", stderr(&shard));
    let png = ipfn(
        d,
        &["synth", "--size", "40", "--out", "c.png", "--shard", "0/2"],
    );
    assert_error(&png, &["Zarr"]);
    let env = Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args([
            "synth",
            "--size",
            "40",
            "--out",
            "e.zarr",
            "--shard-from-env",
        ])
        .current_dir(d)
        .env_remove("JOB_COMPLETION_INDEX")
        .env_remove("SLURM_ARRAY_TASK_ID")
        .output()
        .unwrap();
    assert_error(&env, &["JOB_COMPLETION_INDEX", "SLURM_ARRAY_TASK_ID"]);
    // The Kubernetes variable, as an Indexed Job sets it.
    let k8s = Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args([
            "synth",
            "--size",
            "40",
            "--chunk",
            "16",
            "--out",
            "e.zarr",
            "--shard-from-env",
            "--shards",
            "3",
        ])
        .current_dir(d)
        .env("JOB_COMPLETION_INDEX", "1")
        .output()
        .unwrap();
    assert!(k8s.status.success(), "{}", stderr(&k8s));
    assert!(
        stderr(&k8s).contains("shard 1/3: 3 of 9 chunks"),
        "{}",
        stderr(&k8s)
    );
}

/// The README's GNU parallel line, run as written, fills the store a single render equals.
#[test]
#[ignore = "needs GNU parallel; run by `cargo test --release -- --ignored`"]
fn readme_parallel_line_runs_as_written() {
    assert!(
        Command::new("parallel").arg("--version").output().is_ok(),
        "GNU parallel is not installed (apt-get install parallel)"
    );
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let line = readme
        .lines()
        .find(|l| l.starts_with("seq 0 3 | parallel"))
        .expect("the README shows a GNU parallel line");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bin = Path::new(env!("CARGO_BIN_EXE_ipfn")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("bash")
        .args(["-c", line])
        .env("PATH", path)
        .current_dir(d)
        .output()
        .unwrap();
    assert!(out.status.success(), "{line}: {}", stderr(&out));
    // The same render as one process, to .npy.
    let args: Vec<&str> = line
        .split_once("ipfn ")
        .unwrap()
        .1
        .split(' ')
        .take_while(|a| *a != "--out")
        .collect();
    let out = ipfn(d, &[&args[..], &["--out", "one.npy"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let store = line
        .split(' ')
        .skip_while(|a| *a != "--out")
        .nth(1)
        .unwrap();
    assert_eq!(
        read_zarr_f32(&d.join(store)).1,
        read_npy(&d.join("one.npy")).unwrap().1
    );
}

/// zarr-python (the reference implementation, from PyPI) reads our store as the same array.
#[test]
#[ignore = "needs zarr-python and numpy; run by `cargo test --release -- --ignored`"]
fn zarr_python_reads_the_store() {
    let probe = Command::new("python3")
        .args(["-c", "import zarr, numpy"])
        .output();
    assert!(
        probe.is_ok_and(|o| o.status.success()),
        "zarr-python and numpy are not installed (pip install zarr numpy)"
    );
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    save_model_3d(d);
    let runs: [&[&str]; 2] = [
        &["synth", "--size", "90x60", "--seed", "8"],
        &["synth", "--model", "models/m3.ipfn", "--size", "20x18x9"],
    ];
    for (i, args) in runs.iter().enumerate() {
        let store = format!("p{i}.zarr");
        let npy = format!("p{i}.npy");
        let zarr = ["--chunk", "8", "--out", store.as_str()];
        run_shards(d, &[args, &zarr[..]].concat(), 3);
        let out = ipfn(d, &[args, &["--out", npy.as_str()][..]].concat());
        assert!(out.status.success(), "{}", stderr(&out));
        let script = format!(
            "import zarr, numpy as np\n\
             a = zarr.open_array('{store}', mode='r')\n\
             b = np.load('{npy}')\n\
             assert a.shape == b.shape, (a.shape, b.shape)\n\
             assert a.dtype == np.float32, a.dtype\n\
             assert np.array_equal(a[...], b), float(np.abs(a[...] - b).max())\n\
             assert a.attrs['ipfn']['command'].startswith('ipfn synth')\n\
             print('ok', a.shape)"
        );
        let out = Command::new("python3")
            .args(["-c", &script])
            .current_dir(d)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "zarr-python: {}{}",
            String::from_utf8_lossy(&out.stdout),
            stderr(&out)
        );
    }
}

fn path_with_ipfn() -> String {
    let bin = Path::new(env!("CARGO_BIN_EXE_ipfn")).parent().unwrap();
    format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    )
}

fn recipe(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("deploy")
        .join(name)
}

/// `deploy/slurm-array.sh`, run as SLURM runs it (one process per array task, with SLURM's
/// variables), on a small volume, fills the store a single render equals.
#[test]
fn slurm_recipe_runs_as_a_job_array() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    save_model_3d(d);
    let tasks: Vec<Child> = (1..=4)
        .map(|id| {
            Command::new("bash")
                .arg(recipe("slurm-array.sh"))
                .env("PATH", path_with_ipfn())
                .envs([
                    ("SLURM_ARRAY_TASK_ID", id.to_string()),
                    ("SLURM_ARRAY_TASK_MIN", "1".to_string()),
                    ("SLURM_ARRAY_TASK_COUNT", "4".to_string()),
                    ("MODEL", "models/m3.ipfn".to_string()),
                    ("SIZE", "24x20x18".to_string()),
                    ("OUT", "slurm.zarr".to_string()),
                    ("CHUNK", "8".to_string()),
                ])
                .current_dir(d)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for task in tasks {
        let out = task.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let one = ipfn(
        d,
        &[
            "synth",
            "--model",
            "models/m3.ipfn",
            "--size",
            "24x20x18",
            "--seed",
            "1",
            "--out",
            "one.npy",
        ],
    );
    assert!(one.status.success(), "{}", stderr(&one));
    let (shape, values) = read_zarr_f32(&d.join("slurm.zarr"));
    assert_eq!(shape, [18, 20, 24, 2]);
    assert_eq!(values, read_npy(&d.join("one.npy")).unwrap().1);
}

/// `deploy/k8s-indexed-job.yaml`'s container arguments, run once per completion index with
/// `JOB_COMPLETION_INDEX` as Kubernetes sets it (on a small size and chunk, in a temporary
/// folder standing for the shared volume), fill the store a single render equals.
#[test]
fn kubernetes_recipe_args_run_as_an_indexed_job() {
    let manifest = std::fs::read_to_string(recipe("k8s-indexed-job.yaml")).unwrap();
    let field = |name: &str| {
        manifest
            .lines()
            .map(str::trim)
            .find_map(|l| l.strip_prefix(name))
            .unwrap_or_else(|| panic!("the manifest has {name}"))
            .trim()
            .to_string()
    };
    let completions: usize = field("completions:").parse().unwrap();
    let args: Vec<String> = serde_json::from_str(&field("args:")).unwrap();
    let args: Vec<String> = args
        .iter()
        .map(|a| match a.as_str() {
            "65536" => "96".to_string(),
            a => a.trim_start_matches("/data/").to_string(),
        })
        .chain(["--chunk".to_string(), "16".to_string()])
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let import = ipfn(
        d,
        &[
            "import",
            common::data("official-honeycomb/netG.pth")
                .to_str()
                .unwrap(),
            "-o",
            "honeycomb.ipfn",
        ],
    );
    assert!(import.status.success(), "{}", stderr(&import));
    let pods: Vec<Child> = (0..completions)
        .map(|index| {
            Command::new(env!("CARGO_BIN_EXE_ipfn"))
                .args(&args)
                .env("JOB_COMPLETION_INDEX", index.to_string())
                .current_dir(d)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for pod in pods {
        let out = pod.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let out = args.iter().position(|a| a == "--out").unwrap();
    let single: Vec<&str> = args[..out]
        .iter()
        .map(String::as_str)
        .chain(["--out", "one.png"])
        .collect();
    let one = ipfn(d, &single);
    assert!(one.status.success(), "{}", stderr(&one));
    let store = Arc::new(FilesystemStore::new(d.join(&args[out + 1])).unwrap());
    let array = Array::open(store, "/").unwrap();
    let v: Vec<u8> = array.retrieve_array_subset(&array.subset_all()).unwrap();
    assert_eq!(
        v,
        image::open(d.join("one.png")).unwrap().to_rgb8().into_raw()
    );
}

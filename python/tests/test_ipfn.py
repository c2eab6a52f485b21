"""The Python package against the command line: the same arguments give the same values.

Run from the repository root after `cargo build --release` and `pip install ./python`:
`python -m pytest python/tests`. The `ipfn` binary is target/release/ipfn (or $IPFN_BIN).
"""

import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import ipfn

ROOT = Path(__file__).resolve().parents[2]
HONEYCOMB = ROOT / "exemplars" / "honeycomb.png"


def cli():
    binary = Path(os.environ.get("IPFN_BIN", ROOT / "target" / "release" / "ipfn"))
    assert binary.is_file(), f"{binary}: build the binary first (cargo build --release)"
    return binary


def synth_npy(tmp_path, *args):
    out = tmp_path / "cli.npy"
    subprocess.run([cli(), "synth", "--quiet", "-o", out, *args], check=True)
    return np.load(out)


def test_the_shipped_model_paints_as_the_command_line_does(tmp_path):
    model = ipfn.load()
    assert model.kind == "image"
    assert model.channels == 3
    assert model.path is None
    assert len(model.period) == 2 and all(p > 0 for p in model.period)
    image = model.paint(96, 64, seed=3, offset=(10, -7), zoom=1.5, noise_scale=0.8)
    assert image.dtype == np.float32 and image.shape == (64, 96, 3)
    expected = synth_npy(
        tmp_path, "--size", "96x64", "--seed", "3", "--offset", "10,-7", "--zoom", "1.5",
        "--noise-scale", "0.8",
    )
    np.testing.assert_array_equal(image, expected)


def test_tile_and_mirror_are_the_command_lines(tmp_path):
    model = ipfn.load()
    for flag in ("tile", "mirror"):
        image = model.paint(64, 64, seed=1, **{flag: True})
        np.testing.assert_array_equal(
            image, synth_npy(tmp_path, "--size", "64", "--seed", "1", f"--{flag}")
        )


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny run of 4 iterations on the honeycomb, through the Python package."""
    run = tmp_path_factory.mktemp("runs") / "honeycomb"
    calls = []
    model = ipfn.train(
        HONEYCOMB, out=run, iterations=4, crop=16, batch=2, hidden_layers=2, width=16,
        critic_widths=[8, 16], checkpoint_every=2, preview_every=2, score_samples=1,
        device="cpu", on_progress=calls.append,
    )
    return run, model, calls


def test_train_reports_progress_and_returns_the_runs_model(trained):
    run, model, calls = trained
    assert [c["iteration"] for c in calls] == [1, 2, 3, 4]
    assert calls[1]["preview"] is not None and calls[1]["preview"].ndim == 3
    assert calls[0]["preview"] is None
    assert calls[3]["sifid"] is not None and calls[3]["structure"] is not None
    assert model.kind == "image" and model.iteration == 4
    assert Path(model.path).parent == run
    assert (run / "latest.ipfn").is_file()


def test_a_trained_model_paints_as_the_command_line_does(trained, tmp_path):
    _, model, _ = trained
    np.testing.assert_array_equal(
        model.paint(40, 24, seed=5),
        synth_npy(tmp_path, "--model", model.path, "--size", "40x24", "--seed", "5"),
    )


def test_a_callback_returning_false_stops_the_run_and_resume_continues(tmp_path):
    run = tmp_path / "stopped"
    settings = dict(crop=16, batch=2, hidden_layers=2, width=16, critic_widths=[8, 16])
    ipfn.train(HONEYCOMB, out=run, iterations=50, device="cpu", score_samples=0,
               on_progress=lambda p: p["iteration"] < 3, **settings)
    stopped = ipfn.load(run / "latest.ipfn")
    assert stopped.iteration == 3
    resumed = ipfn.train(resume=run, iterations=5, device="cpu")
    assert ipfn.load(run / "latest.ipfn").iteration == 5
    assert resumed.iteration is not None


def test_a_numpy_exemplar_trains_from_the_run_folder(tmp_path):
    image = (np.indices((32, 32)).sum(axis=0) % 8 < 4).astype(np.uint8) * 255
    image = np.stack([image] * 3, axis=-1)
    run = tmp_path / "array"
    ipfn.train(image, out=run, iterations=1, crop=16, batch=2, hidden_layers=2, width=16,
               critic_widths=[8, 16], score_samples=0, device="cpu")
    assert (run / "exemplar.png").is_file()
    assert ipfn.load(run).iteration == 1


def test_evaluate_is_the_command_lines_report(trained):
    _, model, _ = trained
    report = ipfn.evaluate(model, HONEYCOMB, samples=2)
    out = subprocess.run(
        [cli(), "eval", "--model", model.path, "--exemplar", HONEYCOMB, "--samples", "2",
         "--json"],
        check=True, capture_output=True, text=True,
    ).stdout
    import json

    assert report == json.loads(out)
    assert report["sifid"]["mean"] > 0 and report["structure"]["mean"] > 0


def test_fit_writes_a_tile_that_loads_and_paints(tmp_path):
    photo = tmp_path / "photo.png"
    subprocess.run([cli(), "synth", "--quiet", "--size", "32", "-o", photo], check=True)
    report = ipfn.fit(photo, iterations=20, run=tmp_path / "fit", device="cpu")
    assert report["psnr"] > 10 and report["seam_tile"]["overall"] > 0
    tile = ipfn.load(report["model"])
    assert tile.kind == "tile" and tile.period == [32.0, 32.0]
    np.testing.assert_array_equal(
        tile.paint(32, 32),
        synth_npy(tmp_path, "--model", report["model"], "--size", "32"),
    )


def test_bad_input_raises_the_command_lines_one_line(tmp_path):
    with pytest.raises(ipfn.InputError) as e:
        ipfn.load(tmp_path / "missing.ipfn")
    assert isinstance(e.value, ValueError) and "missing.ipfn" in str(e.value)
    assert "\n" not in str(e.value)
    with pytest.raises(ipfn.InputError):
        ipfn.load().paint(0, 10)
    with pytest.raises(ipfn.InputError):
        ipfn.load().paint(8, 8, device="nonsense")
    with pytest.raises(ipfn.InputError):
        ipfn.train(tmp_path / "missing.png", out=tmp_path / "r", iterations=1)
    with pytest.raises(ipfn.InputError):
        ipfn.train(HONEYCOMB, out=tmp_path / "r2", iterations=1, no_such_key=3)


def test_painting_releases_the_gil():
    """Another Python thread runs while a large image is painted."""
    model = ipfn.load()
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(1)
            time.sleep(0.001)

    thread = threading.Thread(target=tick)
    thread.start()
    try:
        before = len(ticks)
        model.paint(1024, 1024, device="cpu")
        during = len(ticks) - before
    finally:
        done.set()
        thread.join()
    assert during > 10, f"the other thread ran {during} times while painting"

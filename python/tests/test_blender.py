"""The Blender add-on in a real Blender (Debian's `blender`, 3.4, headless): installed from the
zip `python -m ipfn.blender` writes, run on the shipped honeycomb and on a small map-set model,
its pixels checked against `ipfn synth`'s (see blender_addon.py, which runs inside Blender).

Needs `blender` on the PATH (CI installs Debian's); without it this test fails, never skips.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

import ipfn

from test_ipfn import ROOT, cli

HERE = Path(__file__).resolve().parent


def synth(work, out, *args):
    subprocess.run([cli(), "synth", "--quiet", "-o", work / out, *args], check=True)


def map_set_model(work):
    """Trains a 2-iteration map set (colour, normal, roughness, height) as maps.ipfn."""
    y, x = np.indices((32, 32)) / 32.0
    color = np.stack([np.sin(6 * x), np.cos(6 * y), np.sin(6 * (x + y))], axis=-1)
    normal = np.stack([0.3 * np.cos(6 * x), 0.3 * np.sin(6 * y), np.ones_like(x)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    rough = np.sin(12 * x * y)[:, :, None]
    height = np.cos(9 * x)[:, :, None]
    files = []
    for name, values in [("color", color), ("normal", normal), ("roughness", rough),
                         ("height", height)]:
        path = work / f"{name}.png"
        ipfn.write_image(path, values, bits=16)
        files.append(str(path))
    (work / "tiny.toml").write_text(
        "crop = 16\nbatch = 2\nhidden_layers = 2\nwidth = 16\ncritic_widths = [8, 16]\n"
        "score_samples = 0\n"
    )
    run = work / "run"
    subprocess.run(
        [cli(), "train", "--maps", ",".join(files), "--config", work / "tiny.toml",
         "--iterations", "2", "--device", "flex", "--out", run, "--quiet"],
        check=True,
    )
    shutil.copy(run / "latest.ipfn", work / "maps.ipfn")


def test_the_addon_paints_and_wires_in_blender(tmp_path):
    blender = shutil.which("blender")
    assert blender, "needs Blender on the PATH (apt-get install blender python3-numpy)"
    work = tmp_path
    synth(work, "honeycomb.npy", "--size", "64x48", "--seed", "2")
    synth(work, "honeycomb-s3.npy", "--size", "64x48", "--seed", "3")
    synth(work, "honeycomb-32x40.npy", "--size", "32x40", "--seed", "3")
    map_set_model(work)
    synth(work, "maps.npy", "--model", work / "maps.ipfn", "--size", "40x32", "--seed", "1")
    addon = work / "ipfn_blender.zip"
    subprocess.run([sys.executable, "-m", "ipfn.blender", str(addon)], check=True)
    # Debian's Blender embeds the system Python and takes its home from the first `python3` on
    # PATH: a Python of one's own first there (pyenv, a virtualenv) would leave it without the
    # system's numpy. So Blender sees the system's directories only.
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(work / "scripts"),
               BLENDER_USER_CONFIG=str(work / "config"),
               PATH=os.pathsep.join([os.path.dirname(blender), "/usr/bin", "/bin"]))
    render = os.environ.get("IPFN_BLENDER_RENDER")
    args = [blender, "-b", "--factory-startup", "--python-exit-code", "1",
            "--python", HERE / "blender_addon.py", "--", addon, work]
    done = subprocess.run(args + ([render] if render else []), env=env,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "ipfn add-on: all checks passed" in done.stdout, done.stdout[-3000:]

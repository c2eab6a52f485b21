"""The numbered Python examples (examples/python/) run as written, from a folder that holds the
shipped exemplars, and write what their docstrings say."""

import os
import subprocess
import sys

import pytest

from test_ipfn import ROOT

EXAMPLES = sorted((ROOT / "examples" / "python").glob("[0-9][0-9]_*.py"))
WRITES = {
    "01_synth.py": ["01_synth.png"],
    "02_train.py": ["02_train.png", "runs/02_train_py/latest.ipfn"],
    "03_tile.py": ["03_tile.png", "03_mirror.png"],
    "08_eval.py": [],
    "11_fit.py": ["11_fit.png", "runs/11_fit_py/tile.ipfn"],
}


def test_every_example_is_listed():
    assert sorted(e.name for e in EXAMPLES) == sorted(WRITES)


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda e: e.name)
def test_example_runs(example, tmp_path):
    os.symlink(ROOT / "exemplars", tmp_path / "exemplars")
    done = subprocess.run([sys.executable, example], cwd=tmp_path, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip(), "the example says what it did"
    for written in WRITES[example.name]:
        assert (tmp_path / written).is_file(), written

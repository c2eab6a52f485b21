"""`Model.paint` of 1024² through Python beside `ipfn synth --size 1024` of the same image, in
the same run: medians of 5, the shipped honeycomb, the CPU's fused path.

    python benches/python_paint.py [IPFN_BINARY]     (default target/release/ipfn)

Python's time is `ipfn.load()` plus `paint` (an array in memory); the command line's is the
whole process (start, model, painting, the .npy written). Prints a table row: both medians and
Python / command line.
"""

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import ipfn

ROOT = Path(__file__).resolve().parents[1]
RUNS = 5


def median_seconds(f):
    times = []
    for seed in range(RUNS):
        start = time.perf_counter()
        f(seed)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "target" / "release" / "ipfn")
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, "x.npy")

        def cli(seed):
            subprocess.run([binary, "synth", "--size", "1024", "--seed", str(seed),
                            "--device", "cpu", "--quiet", "-o", out], check=True)

        def python(seed):
            ipfn.load().paint(1024, 1024, seed=seed, device="cpu")

        python(0)  # the first call loads the module's code
        py, cl = median_seconds(python), median_seconds(cli)
        same = np.array_equal(ipfn.load().paint(1024, 1024, seed=RUNS - 1, device="cpu"),
                              np.load(out))
    print("| size | Python paint | ipfn synth | Python / synth | same values |")
    print("|---|---|---|---|---|")
    print(f"| 1024² | {py:.3f} s | {cl:.3f} s | {py / cl:.2f} | {same} |")


if __name__ == "__main__":
    main()

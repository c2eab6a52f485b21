"""`ipfn train --maps` on real scanned material sets, one after another, and a table of each
map's structure distance against that map's own floor, with SIFID of the colour map beside the
`texture-synthesis` crate's on the same colour map (the targets of the map-set work: every
trained map within 2.5x its floor).

    python3 benches/materials_train.py SETS_DIR OUT_DIR [TIME] [SAMPLES] [PEER_SAMPLES] [IPFN_BINARY]

SETS_DIR holds one folder per set, its maps named by role (`../shared/materials` on the
development machines; the sets are not shipped with ipfn). TIME is each run's budget (default
15m), SAMPLES the samples scored per model (default 4, seeds 0 to SAMPLES - 1, each at the
scan's size), PEER_SAMPLES the crate's samples (default 2: it takes about a minute for a
1024-px sample on 2 cores). For each set: `ipfn train --maps SET --time TIME --seed 0 --out OUT_DIR/NAME`,
then `ipfn synth --model OUT_DIR/NAME/best.ipfn` per seed (seed 0 also `--preview`, the
material lit), each map scored by `ipfn eval --images SCAN_MAP SAMPLE_MAP --json`, and
`texture-synthesis generate COLOUR_MAP` per seed scored the same way when the crate's CLI is on
PATH. The table is printed in Markdown; logs and samples stay in OUT_DIR. IPFN_TRAIN_FLAGS adds
flags to every training (e.g. `IPFN_TRAIN_FLAGS="--resize 0.25"` for another working scale).
"""

import json
import os
import re
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
FLOOR_RATIO = 2.5
ITERATIONS = re.compile(r"iter (\d+)/(\d+)")
TRAIN_FLAGS = os.environ.get("IPFN_TRAIN_FLAGS", "").split()


def run(args, log=None):
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if log is not None:
        with open(log, "a") as f:
            f.write(" ".join(map(str, args)) + "\n" + done.stdout + done.stderr)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed")
    return done


def score(binary, scan, sample):
    """SIFID of `sample` to `scan` and its structure distance (with the scan's floor)."""
    report = json.loads(run([binary, "eval", "--images", scan, sample, "--json"]).stdout)
    return report["sifid"], report["structure"], report["structure_floor"]


def summary(values):
    mean = statistics.fmean(values)
    spread = statistics.pstdev(values) if len(values) > 1 else 0.0
    return mean, spread


def maps_of(folder):
    """The set's scans by stem (its map names)."""
    return {p.stem: p for p in sorted(folder.iterdir()) if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".exr")}


def train_and_score(binary, folder, out, time, samples):
    log = out / f"{folder.name}.log"
    log.write_text("")
    run_dir = out / folder.name
    done = run([binary, "train", "--maps", folder, "--time", time, "--seed", 0, "--out", run_dir,
                "--device", "cpu", *TRAIN_FLAGS], log)
    steps = [m.groups() for m in ITERATIONS.finditer(done.stderr)]
    iterations = steps[-1][0] if steps else "?"
    scans = maps_of(folder)
    width, height = Image.open(next(iter(scans.values()))).size
    per_map = {name: [] for name in scans}
    colour_sifid, floors = [], {}
    for seed in range(samples):
        stem = out / f"{folder.name}-samples" / f"s{seed}.png"
        stem.parent.mkdir(exist_ok=True)
        preview = ["--preview", out / f"{folder.name}-lit.png"] if seed == 0 else []
        run([binary, "synth", "-q", "--model", run_dir / "best.ipfn", "--width", width, "--height",
             height, "--seed", seed, "--out", stem, *preview], log)
        for name, scan in scans.items():
            sample = stem.with_name(f"s{seed}-{name}.png")
            sifid, structure, floor = score(binary, scan, sample)
            per_map[name].append(structure)
            floors[name] = floor
            if name == "color":
                colour_sifid.append(sifid)
    return iterations, per_map, floors, colour_sifid, (width, height)


def texture_synthesis(binary, folder, out, size, samples):
    """SIFID and structure of the crate's samples of the colour map, or None without it."""
    tool = shutil.which("texture-synthesis")
    colour = maps_of(folder).get("color")
    if tool is None or colour is None or samples == 0:
        return None
    sifids, structures = [], []
    for seed in range(samples):
        sample = out / f"{folder.name}-samples" / f"ts{seed}.png"
        run([tool, "--out-size", f"{size[0]}x{size[1]}", "--seed", seed, "--no-progress", "-o",
             sample, "generate", colour], out / f"{folder.name}.log")
        sifid, structure, _ = score(binary, colour, sample)
        sifids.append(sifid)
        structures.append(structure)
    return summary(sifids), summary(structures)


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip())
        return 2
    sets, out = Path(argv[0]), Path(argv[1])
    time = argv[2] if len(argv) > 2 else "15m"
    samples = int(argv[3]) if len(argv) > 3 else 4
    peer_samples = int(argv[4]) if len(argv) > 4 else 2
    binary = argv[5] if len(argv) > 5 else str(ROOT / "target/release/ipfn")
    out.mkdir(parents=True, exist_ok=True)
    flags = "".join(f" {flag}" for flag in TRAIN_FLAGS)
    print(f"`ipfn train --maps SET --time {time} --seed 0{flags}`, best.ipfn, {samples} samples at the "
          f"scan's size ({peer_samples} of texture-synthesis; mean ± std); floor: the scan's "
          "halves against the whole.\n")
    print("| set | map | structure | floor | ratio | target (2.5x floor) | SIFID of colour | "
          "texture-synthesis: SIFID, structure | iterations |")
    print("|---|---|---|---|---|---|---|---|---|")
    for folder in sorted(p for p in sets.iterdir() if p.is_dir()):
        try:
            iterations, per_map, floors, colour_sifid, size = train_and_score(
                binary, folder, out, time, samples)
            peer = texture_synthesis(binary, folder, out, size, peer_samples)
        except RuntimeError as e:
            print(f"| {folder.name} | failed: {e} | | | | | | | |", flush=True)
            continue
        for name, values in per_map.items():
            mean, spread = summary(values)
            floor = floors[name]
            ratio = mean / floor if floor > 0 else float("inf")
            met = "met" if ratio <= FLOOR_RATIO else "not met"
            sifid = "-"
            ts = "-"
            if name == "color":
                sifid = "{:.2f} ± {:.2f}".format(*summary(colour_sifid))
                if peer is not None:
                    (s_mean, s_std), (t_mean, t_std) = peer
                    ts = f"{s_mean:.2f} ± {s_std:.2f}, {t_mean:.4f} ± {t_std:.4f}"
            print(f"| {folder.name} | {name} | {mean:.4f} ± {spread:.4f} | {floor:.4f} | "
                  f"{ratio:.2f} | {met} | {sifid} | {ts} | {iterations} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

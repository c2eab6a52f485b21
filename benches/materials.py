"""`ipfn fit --maps` on real scanned material sets, one after another, and a table of each map's
PSNR and seam score beside its own lines' spread (the targets of the map-set work: every fitted
map's seam within 10% of 1, and at least 28 dB).

    python3 benches/materials.py SETS_DIR OUT_DIR [TIME] [IPFN_BINARY]

SETS_DIR holds one folder per set, its maps named by role (`../shared/materials` on the
development machines; the sets are not shipped with ipfn). TIME is each fit's budget (default
5m). Each fit writes OUT_DIR/NAME/ (the tile's maps), OUT_DIR/NAME-lit.png (the material lit)
and OUT_DIR/NAME.log; the table is printed in Markdown.
"""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAP_LINE = re.compile(
    r"^\s+(?P<name>\S+): PSNR (?P<psnr>[\d.]+) dB \(interior (?P<interior>[\d.]+) dB\), "
    r"seam score 2x2 (?P<seam>[\d.]+)(?: \(its own lines: (?P<lo>[\d.]+) to (?P<hi>[\d.]+)\))?"
)


def fit(binary, folder, out, time):
    log = out / f"{folder.name}.log"
    args = [binary, "fit", "--maps", str(folder), "--time", time, "--run", str(out / folder.name),
            "--preview", str(out / f"{folder.name}-lit.png"), "--device", "cpu"]
    done = subprocess.run(args, capture_output=True, text=True)
    log.write_text(done.stdout + done.stderr)
    if done.returncode != 0:
        return None, done.stderr.strip().splitlines()[-1]
    rows = [m.groupdict() for line in done.stderr.splitlines() if (m := MAP_LINE.match(line))]
    return rows, None


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip())
        return 2
    sets, out = Path(argv[0]), Path(argv[1])
    time = argv[2] if len(argv) > 2 else "5m"
    binary = argv[3] if len(argv) > 3 else str(ROOT / "target/release/ipfn")
    out.mkdir(parents=True, exist_ok=True)
    print(f"| set | map | PSNR (dB) | interior PSNR (dB) | seam 2x2 | its own lines | targets |")
    print("|---|---|---|---|---|---|---|")
    for folder in sorted(p for p in sets.iterdir() if p.is_dir()):
        rows, error = fit(binary, folder, out, time)
        if rows is None:
            print(f"| {folder.name} | refused: {error} | | | | | |", flush=True)
            continue
        for r in rows:
            seam, interior = float(r["seam"]), float(r["interior"])
            ok = abs(seam - 1.0) <= 0.1 and interior >= 28.0
            lines = f"{r['lo']} to {r['hi']}" if r["lo"] else "-"
            print(f"| {folder.name} | {r['name']} | {r['psnr']} | {r['interior']} | {seam:.3f} | "
                  f"{lines} | {'met' if ok else 'not met'} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

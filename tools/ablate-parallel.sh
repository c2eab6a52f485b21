#!/usr/bin/env bash
# Many training runs at once, each on its own cores, then `ipfn eval` of each: for ablations at
# equal time on a machine with many cores, where each run gets the iteration count that its
# settings do in the same time on the 2-core machine (measure that first: tools/rates.sh).
#
#   tools/ablate-parallel.sh JOBS OUT [THREADS_PER_RUN] [TRAIN_LIMIT_S]
#
# JOBS is a file of lines `NAME EXEMPLAR ITERATIONS [FLAGS...]` (# starts a comment). Each run
# trains `EXEMPLAR --iterations ITERATIONS --seed 0 FLAGS` into OUT/NAME with
# RAYON_NUM_THREADS=THREADS_PER_RUN (default 1), stopped after TRAIN_LIMIT_S seconds (default
# 450; a stopped run keeps its last checkpoint). Then every run's latest.ipfn is scored, 8
# samples at the exemplar's size, and one markdown row a run is printed (and written to
# OUT/table.md): the iterations it reached, SIFID and the structure distance (mean ± std) and
# the exemplar's structure floor. Uses IPFN_BIN, else target/release/ipfn.
set -uo pipefail
jobs_file="$1"; out="$2"; threads="${3:-1}"; limit="${4:-450}"
ipfn="${IPFN_BIN:-$(cd "$(dirname "$0")/.." && pwd)/target/release/ipfn}"
mkdir -p "$out"

names=(); photos=()
while read -r name photo iterations flags; do
  [[ -z "$name" || "$name" == \#* ]] && continue
  names+=("$name"); photos+=("$photo")
  # shellcheck disable=SC2086 # the flags are words
  RAYON_NUM_THREADS="$threads" timeout -s INT "$limit" "$ipfn" train "$photo" $flags \
    --iterations "$iterations" --seed 0 --out "$out/$name" --quiet >"$out/$name.log" 2>&1 &
done <"$jobs_file"
wait

score() { # name photo -> json
  RAYON_NUM_THREADS="$threads" "$ipfn" eval --model "$out/$1/latest.ipfn" --exemplar "$2" \
    --samples 8 --json >"$out/$1.json" 2>"$out/$1.eval.log"
}
for i in "${!names[@]}"; do score "${names[$i]}" "${photos[$i]}" & done
wait

{
  echo "| run | iterations | SIFID | structure | floor |"
  echo "|---|---|---|---|---|"
  for name in "${names[@]}"; do
    its="$(tail -n 1 "$out/$name/metrics.csv" 2>/dev/null | cut -d, -f1)"
    python3 - "$out/$name.json" "$name" "${its:-0}" <<'EOF'
import json, sys
path, name, its = sys.argv[1:]
try:
    j = json.load(open(path))
    s, t = j["sifid"], j["structure"]
    print(f"| {name} | {its} | {s['mean']:.2f} ± {s['std']:.2f} | "
          f"{t['mean']:.4f} ± {t['std']:.4f} | {j['structure_floor']:.4f} |")
except Exception as e:
    print(f"| {name} | {its} | failed: {e} | | |")
EOF
  done
} | tee "$out/table.md"

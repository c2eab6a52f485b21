#!/usr/bin/env bash
# An ablation of the training recipe at equal time budgets: for each exemplar, `ipfn train`
# once with flags A and once with flags B (both on top of the defaults for this machine), each
# for the same --time and seed, one after the other on the whole machine; then `ipfn eval` of
# each run's default model (best.ipfn): SIFID mean ± std over 8 samples at the photo's size
# (Keras InceptionV3 stem), and the same samples' mean structure distance beside the photo's
# floor. Prints one markdown table; the ratio is of SIFID.
#
#   tools/ablate.sh BUDGET SEED "FLAGS A" "FLAGS B" EXEMPLAR...
#   tools/ablate.sh 5m 0 "--average 0.98" "" ../shared/exemplars/brick.jpg
#
# BUDGET is a --time (5m) or a number of iterations (450): a change that costs nothing per
# iteration is compared at equal iterations, which other work on the machine cannot skew.
#
# Uses target/release/ipfn (build it first: cargo build --release), or IPFN_BIN (a copy, so that
# building while it runs does not change the binary between A and B). Work goes to
# ${IPFN_MEASURE_DIR:-/tmp/ipfn-ablate}; IPFN_MEASURE_REUSE=1 scores runs already there.
set -euo pipefail
budget="$1"; seed="$2"; a="$3"; b="$4"; shift 4
ipfn="${IPFN_BIN:-$(cd "$(dirname "$0")/.." && pwd)/target/release/ipfn}"
work="${IPFN_MEASURE_DIR:-/tmp/ipfn-ablate}"
mkdir -p "$work"
length="--time $budget"
[[ "$budget" =~ ^[0-9]+$ ]] && length="--iterations $budget"
slug() { local s="${1:-none}"; s="${s//--/}"; s="${s// /_}"; echo "${s//[^A-Za-z0-9_.=-]/}"; }
sifid() { # run exemplar -> "mean ± std, structure S (floor F)"
  "$ipfn" eval --model "$1" --exemplar "$2" --samples 8 --json 2>/dev/null |
    python3 -c 'import json,sys; j=json.load(sys.stdin); r=j["sifid"]; print("%.2f ± %.2f, structure %.3f (floor %.3f)" % (r["mean"], r["std"], j["structure"]["mean"], j["structure_floor"]))'
}
iterations() { tail -n 1 "$1/metrics.csv" | cut -d, -f1; }
echo "| exemplar | A: ${a:-defaults} ($budget, seed $seed) | B: ${b:-defaults} | A / B |"
echo "|---|---|---|---|"
for photo in "$@"; do
  name="$(basename "${photo%.*}")"
  runs=()
  for flags in "$a" "$b"; do
    run="$work/$name-$(slug "$flags")-$budget-s$seed"
    runs+=("$run")
    [ "${IPFN_MEASURE_REUSE:-0}" = 1 ] && [ -f "$run/latest.ipfn" ] && continue
    rm -rf "$run"
    # shellcheck disable=SC2086 # the flags are words
    "$ipfn" train "$photo" $flags $length --seed "$seed" --out "$run" --quiet
  done
  ra="$(sifid "${runs[0]}" "$photo")"; rb="$(sifid "${runs[1]}" "$photo")"
  ratio="$(python3 -c "print('%.2f' % (${ra%% *} / ${rb%% *}))")"
  echo "| $name | $ra ($(iterations "${runs[0]}") it) | $rb ($(iterations "${runs[1]}") it) | $ratio |"
done

#!/usr/bin/env bash
# Training quality on real photographs at equal time budgets, an ablation of the recipe: for
# each exemplar, `ipfn train` with configs/quick.toml, once with the recipe's choices from the
# exemplar (K from its period, gray for a gray photo; evaluated at best.ipfn, the default
# model) and once as the preset ran before (K from 1, colour kept; evaluated at latest.ipfn),
# each for the same --time, then `ipfn eval` (SIFID mean ± std over 8 samples, Keras
# InceptionV3 stem, and the same samples' mean structure distance beside the photo's floor).
# Prints one markdown table; the ratio is of SIFID.
#
#   tools/measure-photos.sh BUDGET SEED EXEMPLAR...
#   tools/measure-photos.sh 5m 0 ../shared/exemplars/brick.jpg ../shared/exemplars/marble.jpg
#
# Uses target/release/ipfn (build it first: cargo build --release). Work goes to
# ${IPFN_MEASURE_DIR:-/tmp/ipfn-photos}. Both trainings of a photo run one after the other on
# the whole machine.
set -euo pipefail
budget="$1"; seed="$2"; shift 2
ipfn="$(cd "$(dirname "$0")/.." && pwd)/target/release/ipfn"
work="${IPFN_MEASURE_DIR:-/tmp/ipfn-photos}"
mkdir -p "$work"
# The earlier quick preset as it ran before the recipe: K starts at 1 and colour stays colour.
quick="$(dirname "$0")/../configs/quick.toml"
{ cat "$quick"; printf 'k_init = [1.0, 1.0]\ngray = false\n'; } > "$work/quick-before.toml"
# The same preset with the recipe's choices from the exemplar (K, gray).
grep -v -E '^iterations ' "$quick" > "$work/recipe.toml"
sifid() { # model exemplar -> "mean ± std, structure S (floor F)"
  "$ipfn" eval --model "$1" --exemplar "$2" --samples 8 --json 2>/dev/null |
    python3 -c 'import json,sys; j=json.load(sys.stdin); r=j["sifid"]; print("%.2f ± %.2f, structure %.3f (floor %.3f)" % (r["mean"], r["std"], j["structure"]["mean"], j["structure_floor"]))'
}
echo "| exemplar | recipe ($budget, seed $seed) | quick.toml ($budget, seed $seed) | recipe / quick |"
echo "|---|---|---|---|"
for photo in "$@"; do
  name="$(basename "${photo%.*}")"
  for how in recipe quick; do
    run="$work/$name-$how-$budget-s$seed"
    # IPFN_MEASURE_REUSE=1 scores runs already there instead of training them again.
    [ "${IPFN_MEASURE_REUSE:-0}" = 1 ] && [ -f "$run/latest.ipfn" ] && continue
    rm -rf "$run"
    config="$work/recipe.toml"
    [ "$how" = quick ] && config="$work/quick-before.toml"
    "$ipfn" train "$photo" --config "$config" --time "$budget" --seed "$seed" --out "$run" --quiet
  done
  r="$(sifid "$work/$name-recipe-$budget-s$seed" "$photo")"
  q="$(sifid "$work/$name-quick-$budget-s$seed/latest.ipfn" "$photo")"
  ratio="$(python3 -c "print('%.2f' % (${r%% *} / ${q%% *}))")"
  echo "| $name | $r | $q | $ratio |"
done

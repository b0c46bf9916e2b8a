#!/usr/bin/env bash
# MC with the fitted alignment against the data it was fitted on (docs/apply.md, "MC with the
# fitted alignment"): for each seed, a paper-like sample (the data), its fit with the shipped
# corrections and with the paper's model alone, an MC sample simulated with each fitted
# alignment (another seed), and emcalign compare of the data against each MC, and against a
# nominal (all-zero) detector.
#   bench/compare_fitted_study.sh [DIR] [SEEDS] [EVENTS]   (default /tmp/emcalign-compare-fitted, 10, 50000)
# Writes DIR/p_values.txt (seed, joint p with the corrected fit's MC, with the paper's model's, with
# the nominal detector) and prints the p-values' means and counts below 0.05.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-compare-fitted}"
seeds="${2:-10}"
events="${3:-50000}"
E="$PWD/build/bin/emcalign"
truth="$PWD/data/examples/paper-like.json"
corrections="$PWD/data/corrections/ee-612.5MeV-40-140deg.json"
sim() { "$E" simulate --events "$events" --theta-min 40 --theta-max 140 --no-hits "$@" > /dev/null 2>&1; }
p() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['p_value'])" "$1/compare.json"; }
mkdir -p "$dir"
: > "$dir/p_values.txt"
for k in $(seq 1 "$seeds"); do
  sim --params "$truth" --seed $((2000 + 3 * k)) -o "$dir/data.h5"
  "$E" fit "$dir/data.h5" --corrections "$corrections" -o "$dir/fit-corrected.json" > /dev/null 2>&1
  "$E" fit "$dir/data.h5" -o "$dir/fit-paper.json" > /dev/null 2>&1
  line="$k"
  for mc in fit-corrected fit-paper nominal; do
    params="$dir/$mc.json"
    [ "$mc" = nominal ] && params="$PWD/data/examples/nominal.json"
    sim --params "$params" --seed $((2001 + 3 * k)) -o "$dir/mc.h5"
    rm -rf "$dir/c"
    "$E" compare --data "$dir/data.h5" --mc "$dir/mc.h5" --corrections "$corrections" -o "$dir/c" > /dev/null
    line="$line $(p "$dir/c")"
  done
  echo "$line" >> "$dir/p_values.txt"
done
python3 - "$dir/p_values.txt" <<'PY'
import sys
rows = [list(map(float, l.split()[1:])) for l in open(sys.argv[1])]
n = len(rows)
for k, name in enumerate(["MC with the corrected fit", "MC with the paper's model's fit", "MC of a nominal detector"]):
    v = [r[k] for r in rows]
    print(f"{name:32s} seeds {n}  mean p {sum(v) / n:.3g}  median {sorted(v)[n // 2]:.3g}  "
          f"below 0.05: {sum(x < 0.05 for x in v)}  below 1e-6: {sum(x < 1e-6 for x in v)}")
PY

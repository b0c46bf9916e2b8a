#!/usr/bin/env bash
# The p-values of emcalign compare on pairs of independent simulated samples of one truth
# (docs/apply.md, "A perfect simulation gives uniform p-values"): a simulation that is the
# data's twin must give p-values uniform in [0, 1].
#   bench/compare_null_study.sh [DIR] [PAIRS] [EVENTS]   (default /tmp/emcalign-compare-null, 40, 30000)
# Writes DIR/p_values.txt (pair, joint p, dphi, dtheta, profile_phi, profile_theta) and
# prints each column's mean, KS distance to the uniform and count below 0.05.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-compare-null}"
pairs="${2:-40}"
events="${3:-30000}"
E="$PWD/build/bin/emcalign"
truth="$PWD/data/examples/paper-like.json"
mkdir -p "$dir"
: > "$dir/p_values.txt"
for k in $(seq 1 "$pairs"); do
  for s in 0 1; do
    "$E" simulate --params "$truth" --events "$events" --seed $((1000 + 2 * k + s)) --theta-min 40 --theta-max 140 \
      --no-hits -o "$dir/s$s.h5" > /dev/null 2>&1
  done
  rm -rf "$dir/c"
  "$E" compare --data "$dir/s0.h5" --mc "$dir/s1.h5" -o "$dir/c" > /dev/null
  python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print($k, j['p_value'], *[d['p_value'] for d in j['distributions']])" \
    "$dir/c/compare.json" >> "$dir/p_values.txt"
done
python3 - "$dir/p_values.txt" <<'PY'
import math, sys
rows = [list(map(float, l.split()[1:])) for l in open(sys.argv[1])]
n = len(rows)
for k, name in enumerate(["all together", "dphi", "dtheta", "profile_phi", "profile_theta"]):
    v = sorted(r[k] for r in rows)
    ks = max(max(abs(x - i / n), abs(x - (i + 1) / n)) for i, x in enumerate(v))
    print(f"{name:14s} pairs {n}  mean {sum(v) / n:.3f}  KS {ks:.3f} (5 % critical {1.36 / math.sqrt(n):.3f})  "
          f"below 0.05: {sum(x < 0.05 for x in v)}")
PY

#!/usr/bin/env bash
# The study of docs/checks.md: the paper's section 5 in simulation. A paper-like misalignment;
# a calibration on e+e- → e+e- events (with and without the model corrections); γγ and
# π+π−π0 samples corrected with the fits and with the truth; and the truth with one group of
# terms left out at a time, to see which terms each check feels.
#   bench/check_study.sh [DIR] [EVENTS]     (default /tmp/emcalign-check-study, 200000)
# Writes DIR/summary.md (bench/check_summary.py) and every check's directory.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-check-study}"
events="${2:-200000}"
E="$PWD/build/bin/emcalign"
truth=data/examples/paper-like.json
corrections=data/corrections/ee-612.5MeV-40-140deg.json
mkdir -p "$dir"
cat > "$dir/zero.json" <<'JSON'
{"format": "emcalign-alignment/1", "parameters": {"alpha": 0, "beta1": 0, "beta2": 0, "dx": 0, "dy": 0, "dz": 0,
 "dp1": 0, "dp2": 0, "dp3": 0, "dy_rel": 0, "dz_rel": 0, "beta_rel": 0}}
JSON
# The truth with one group of terms left out.
/usr/bin/python3 - "$truth" "$dir" <<'PY'
import json, sys
truth = json.load(open(sys.argv[1]))["parameters"]
groups = {"alpha": ["alpha"], "beta12": ["beta1", "beta2"], "shift": ["dx", "dy", "dz"], "gap": ["dp1", "dp2", "dp3"],
          "relative": ["dy_rel", "dz_rel", "beta_rel"]}
for name, keys in groups.items():
    p = dict(truth)
    for k in keys:
        p[k] = 0.0
    json.dump({"format": "emcalign-alignment/1", "parameters": p}, open(f"{sys.argv[2]}/without-{name}.json", "w"))
PY
$E simulate --process ee --events $((events * 5 / 2)) --seed 21 --theta-min 40 --theta-max 140 --params "$truth" \
   --no-hits -o "$dir/ee.h5"
$E fit "$dir/ee.h5" --corrections "$corrections" -o "$dir/fit.json" > /dev/null
$E fit "$dir/ee.h5" -o "$dir/fit-plain.json" > /dev/null
for process in gg 3pi; do
  $E simulate --process $process --events "$events" --seed 22 --params "$truth" -o "$dir/$process.h5"
  $E simulate --process $process --events "$events" --seed 22 --params "$dir/zero.json" -o "$dir/$process-nominal.h5"
  $E check $process "$dir/$process-nominal.h5" --alignment "$dir/zero.json" -o "$dir/$process-nominal"
  $E check $process "$dir/$process.h5" --alignment "$truth" -o "$dir/$process-truth"
  $E check $process "$dir/$process.h5" --alignment "$dir/fit.json" --corrections "$corrections" -o "$dir/$process-fit"
  $E check $process "$dir/$process.h5" --alignment "$dir/fit-plain.json" -o "$dir/$process-fit-plain"
  for g in alpha beta12 shift gap relative; do
    $E check $process "$dir/$process.h5" --alignment "$dir/without-$g.json" -o "$dir/$process-without-$g" > /dev/null
  done
done
/usr/bin/python3 bench/check_summary.py "$dir" | tee "$dir/summary.md"

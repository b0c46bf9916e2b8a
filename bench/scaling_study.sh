#!/usr/bin/env bash
# Time and peak memory of simulate, fit and correct against the number of events (10^4 to
# 10^7 by default), for docs/performance.md:
#
#   bench/scaling_study.sh [DIR] [THREADS] [COUNTS]     e.g. bench/scaling_study.sh /tmp/scaling 2
#
# Each sample: `simulate --process ee` (θ 40°–140°, paper-like truth, with hits, on THREADS
# threads), `fit` of it and `correct --method hits` of it; wall and CPU seconds and peak RSS
# (GNU time) go to DIR/scaling.tsv. 10^7 events take ~2.5 GB of disk (the file is removed
# after its sample) and ~3 min on the 2-core machine.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-scaling}"
threads="${2:-2}"
counts="${3:-10000 100000 1000000 10000000}"
B="$PWD/build/bin/emcalign"
mkdir -p "$dir"
out="$dir/scaling.tsv"
printf "step\tevents\tthreads\twall_s\tcpu_s\tpeak_rss_mb\n" > "$out"
measure() {  # step events command...
  local step="$1" events="$2"
  shift 2
  if ! /usr/bin/time -f "%e %U %S %M" -o "$dir/time.txt" "$@" > /dev/null 2> "$dir/$step.log"; then
    echo "scaling_study.sh: $step of $events events failed:" >&2
    grep -v '^Command exited' "$dir/$step.log" >&2
    exit 1
  fi
  awk -v step="$step" -v n="$events" -v t="$threads" \
    '{ printf "%s\t%s\t%s\t%s\t%.2f\t%.0f\n", step, n, t, $1, $2 + $3, $4 / 1024 }' "$dir/time.txt" | tee -a "$out"
}
for n in $counts; do
  f="$dir/ee-$n.h5"
  measure simulate "$n" "$B" simulate --process ee --events "$n" --seed 1 --params data/examples/paper-like.json \
    --theta-min 40 --theta-max 140 --threads "$threads" -o "$f"
  measure fit "$n" "$B" fit "$f" -o "$dir/fit-$n.json"
  measure correct "$n" "$B" correct "$f" --alignment "$dir/fit-$n.json" -o "$dir/corrected-$n.h5"
  rm -f "$f" "$dir/corrected-$n.h5"
done
echo "-> $out"

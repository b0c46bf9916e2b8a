#!/usr/bin/env bash
# The beam-energy scan of docs/validation.md: the validation campaign at several beam
# energies with the paper's model, with the one corrections file of 612.5 MeV, and with the
# grid interpolated to each energy (the contract's sigma_sys and --sigma-sys auto).
#   bench/energy_scan_study.sh [DIR] [SAMPLES] [EVENTS] [ENERGIES]
#     (default /tmp/emcalign-energy-scan, 100, 50000, "510 612.5 900")
# A rerun resumes every campaign. Writes DIR/summary.md (bench/energy_scan_summary.py).
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-energy-scan}"
samples="${2:-100}"
events="${3:-50000}"
energies="${4:-510 612.5 900}"
E="$PWD/build/bin/emcalign"
single=data/corrections/ee-612.5MeV-40-140deg.json
grid=data/corrections/ee-40-140deg
mkdir -p "$dir"
for energy in $energies; do
  common=(validate --samples "$samples" --events "$events" --beam-energy "$energy")
  $E "${common[@]}" -o "$dir/paper-$energy" > "$dir/paper-$energy.log"
  $E "${common[@]}" --corrections "$grid" -o "$dir/grid-$energy" > "$dir/grid-$energy.log"
  $E "${common[@]}" --corrections "$grid" --sigma-sys auto -o "$dir/grid-auto-$energy" > "$dir/grid-auto-$energy.log"
  if [ "$energy" != "612.5" ]; then
    $E "${common[@]}" --corrections "$single" -o "$dir/single-$energy" > "$dir/single-$energy.log" 2> "$dir/single-$energy.err"
  fi
done
/usr/bin/python3 bench/energy_scan_summary.py "$dir" $energies > "$dir/summary.md"
cat "$dir/summary.md"

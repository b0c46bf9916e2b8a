#!/usr/bin/env bash
# The study of docs/campaign.md: the SND-like 2010-2011 period simulated, calibrated group by
# group (without the model corrections, with the 612.5 MeV file and with the grid over the
# beam energies), its trend analysed against the truth, and the stable periods refitted.
#   bench/campaign_study.sh [DIR] [THREADS]     (default /tmp/emcalign-campaign-study, all cores)
# Writes DIR/period/ (the events, truth.json), DIR/c.db (tags snd.v1, snd.corr, snd.grid, snd.corr.stable),
# DIR/trend-v1/, DIR/trend-corr/ (trend.json, trend.md, figures), DIR/timings.txt and
# DIR/summary.md (bench/campaign_summary.py: steps and drifts against the truth, the refit) and
# DIR/energy.md (bench/energy_period_summary.py: fit − truth by beam-energy band, each tag).
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-campaign-study}"
threads="${2:-0}"
E="$PWD/build/bin/emcalign"
scenario=data/periods/snd-2010-2011-like.json
corrections=data/corrections/ee-612.5MeV-40-140deg.json
grid=data/corrections/ee-40-140deg
mkdir -p "$dir"
: > "$dir/timings.txt"
timed() {  # timed NAME COMMAND...: runs it, appends "NAME SECONDS" to timings.txt
  local name="$1"; shift
  local start end
  start=$(date +%s.%N)
  "$@"
  end=$(date +%s.%N)
  printf '%s %.1f\n' "$name" "$(echo "$end - $start" | bc)" | tee -a "$dir/timings.txt"
}
rm -f "$dir"/c.db*
timed simulate $E simulate --period "$scenario" -o "$dir/period" --no-hits --threads "$threads"
timed campaign $E campaign "$dir/period" --conditions "$dir/c.db" --tag snd.v1 --threads "$threads"
timed campaign-corrections $E campaign "$dir/period" --conditions "$dir/c.db" --tag snd.corr \
  --corrections "$corrections" --threads "$threads"
timed campaign-grid $E campaign "$dir/period" --conditions "$dir/c.db" --tag snd.grid \
  --corrections "$grid" --threads "$threads"
timed trend $E trend --conditions "$dir/c.db" --tag snd.v1 -o "$dir/trend-v1" --truth "$dir/period/truth.json"
timed trend-refit $E trend --conditions "$dir/c.db" --tag snd.corr -o "$dir/trend-corr" \
  --truth "$dir/period/truth.json" --refit "$dir/period" --tag-out snd.corr.stable --corrections "$corrections" \
  --threads "$threads"
du -sh "$dir/period" | tee -a "$dir/timings.txt"
/usr/bin/python3 bench/campaign_summary.py "$dir" "$E" | tee "$dir/summary.md"
/usr/bin/python3 bench/energy_period_summary.py "$dir" "$E" snd.v1 snd.corr snd.grid | tee "$dir/energy.md"

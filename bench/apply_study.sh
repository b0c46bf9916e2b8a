#!/usr/bin/env bash
# The study of docs/apply.md: a paper-like misalignment, corrected with the truth and with
# fitted parameters, by both methods, beside a nominal detector.
#   bench/apply_study.sh [DIR] [EVENTS]      (default /tmp/emcalign-apply-study, 200000)
# Writes DIR/residuals/{residuals.md, residuals.json, residuals.png, residual_columns.png}
# and DIR/figure/ (the same for the five samples of the figure in docs/apply.md).
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-apply-study}"
events="${2:-200000}"
E=build/bin/emcalign
truth=data/examples/paper-like.json
corrections=data/corrections/ee-612.5MeV-40-140deg.json
mkdir -p "$dir"
cat > "$dir/zero.json" <<'JSON'
{"format": "emcalign-alignment/1", "parameters": {"alpha": 0, "beta1": 0, "beta2": 0, "dx": 0, "dy": 0, "dz": 0,
 "dp1": 0, "dp2": 0, "dp3": 0, "dy_rel": 0, "dz_rel": 0, "beta_rel": 0}}
JSON
sim="simulate --events $events --seed 11 --theta-min 40 --theta-max 140"
$E $sim --params "$truth" -o "$dir/misaligned.h5"
$E $sim --params "$dir/zero.json" -o "$dir/nominal.h5"
$E fit "$dir/misaligned.h5" -o "$dir/fit.json" > "$dir/fit.log"
$E fit "$dir/misaligned.h5" --corrections "$corrections" -o "$dir/fit-corrections.json" > "$dir/fit-corrections.log"
for method in hits clusters; do
  $E correct "$dir/misaligned.h5" --alignment "$truth" --method "$method" -o "$dir/truth-$method.h5"
  $E correct "$dir/misaligned.h5" --alignment "$dir/fit.json" --method "$method" -o "$dir/fit-$method.h5"
done
$E correct "$dir/misaligned.h5" --alignment "$dir/fit-corrections.json" --method hits -o "$dir/fitc-hits.h5"
$E correct "$dir/misaligned.h5" --alignment "$dir/fit-corrections.json" --method clusters \
   --corrections "$corrections" -o "$dir/fitc-clusters.h5"
$E residuals -o "$dir/residuals" \
   --sample "nominal=$dir/nominal.h5" --sample "misaligned=$dir/misaligned.h5" \
   --sample "truth, hits=$dir/truth-hits.h5" --sample "truth, clusters=$dir/truth-clusters.h5" \
   --sample "fit, hits=$dir/fit-hits.h5" --sample "fit, clusters=$dir/fit-clusters.h5" \
   --sample "fit with corrections, hits=$dir/fitc-hits.h5" \
   --sample "fit with corrections, clusters + depth offset=$dir/fitc-clusters.h5"
$E residuals -o "$dir/figure" \
   --sample "nominal=$dir/nominal.h5" --sample "misaligned=$dir/misaligned.h5" \
   --sample "corrected with the truth, hits=$dir/truth-hits.h5" \
   --sample "corrected with the fit, hits=$dir/fit-hits.h5" \
   --sample "corrected with the fit, clusters=$dir/fit-clusters.h5" > /dev/null

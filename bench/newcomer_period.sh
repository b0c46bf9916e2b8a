#!/usr/bin/env bash
# The newcomer's period of docs/campaign.md (issue 43): data/periods/newcomer-drift.json — 60
# runs at three beam energies, a dx step at run 45, an alpha drift from run 8 to run 27 inside
# flat runs — simulated, calibrated in IOVs of 20 000 selected events with --sigma-sys auto and
# with the contract's sigma_sys, each trend against the truth, and the refit of each.
#   bench/newcomer_period.sh [DIR]      (default /tmp/emcalign-newcomer; about 40 s)
# Prints the drift, the steps and the periods found beside the truth.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-/tmp/emcalign-newcomer}"
E="$PWD/build/bin/emcalign"
grid=data/corrections/ee-40-140deg
mkdir -p "$dir"
rm -f "$dir"/c.db*
$E simulate --period data/periods/newcomer-drift.json -o "$dir/period" --no-hits
for tag in auto spec; do
  extra=()
  [ "$tag" = auto ] && extra=(--sigma-sys auto)
  $E campaign "$dir/period" --conditions "$dir/c.db" --tag "$tag" --min-events 20000 --corrections "$grid" "${extra[@]}"
  $E trend --conditions "$dir/c.db" --tag "$tag" -o "$dir/trend-$tag" --truth "$dir/period/truth.json" \
    --refit "$dir/period" --tag-out "$tag.refit"
done
/usr/bin/python3 - "$dir" <<'PY'
import json, sys
d = sys.argv[1]
for tag in ("auto", "spec"):
    t = json.load(open(f"{d}/trend-{tag}/trend.json"))
    print(f"\n## --sigma-sys {tag if tag == 'auto' else '0.2 deg'}: {t['iovs']} IOVs\n")
    print("| found | parameter | where | size or change | true | or a step / a drift? |\n|---|---|---|---|---|---|")
    for s in t["steps"]:
        print(f"| step | {s['parameter']} | run {s['first_run_after']} | {s['size']:+.4f} ± {s['error']:.4f} | "
              f"{s.get('true_size', float('nan')):+.4f} | {'yes' if s.get('or_drift') else 'no'} |")
    for x in t["drifts"]:
        start = x["start_run"] if x["start_run"] is not None else f"under way at {x['first_run']}"
        end = x["end_run"] if x["end_run"] is not None else f"going at {x['last_run']}"
        print(f"| drift | {x['parameter']} | runs {start} ({x['start_range'][0]}-{x['start_range'][1]}) to {end} "
              f"({x['end_range'][0]}-{x['end_range'][1]}); slope {x['slope_per_run']:.5f} ± {x['error']:.5f}/run | "
              f"{x['change']:+.4f} ± {x['change_error']:.4f} | {x.get('true_change', float('nan')):+.4f} | "
              f"{'yes' if x.get('or_step') else 'no'} |")
    print("\n| period | stable | drifting | not stable because |\n|---|---|---|---|")
    for g in t["segments"]:
        why = [f"{s['parameter']} scatters {s['scatter_over_error']:.1f}x" for s in g.get("scattering", [])]
        why += [f"{p} undecided" for p in g.get("undecided", [])]
        print(f"| {g['first_run']}-{g['last_run']} ({g['iovs']} IOVs) | {g['stable']} | {', '.join(g['drifting'])} | "
              f"{'; '.join(why)} |")
    r = t["refit"]
    print(f"\nRefit: {r['iovs']} IOVs instead of {r['iovs_before']}:")
    for s in r["segments"]:
        if s["kept"]:
            print(f"- runs {s['first_run']}-{s['last_run']}: kept ({s.get('why', '')})")
        else:
            a = s["precision"]["alpha"]
            print(f"- runs {s['first_run']}-{s['last_run']}: refitted, alpha {a['value']:.4f} (truth {a['truth']:.4f}), "
                  f"its IOVs' scatter / statistical error {a['scatter_over_error_before']:.2f}")
PY

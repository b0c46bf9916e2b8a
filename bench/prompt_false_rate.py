#!/usr/bin/env python3
"""The false update rate of `emcalign prompt` on a long stable season (issue 45; docs/prompt.md).

    bench/prompt_false_rate.py [DIR] [--runs N] [--thresholds THR.json]
        DIR           work directory (default /tmp/emcalign-prompt-false-rate; about 5 minutes)
        --runs N      runs of 6 400 events at 612.5 MeV, nothing moving (default 5000)
        --thresholds  a thresholds file (default: the one bench/prompt_season.py proposed with
                      --sigma-sys auto, /tmp/emcalign-prompt-season/thresholds-auto-0.01.json)

The season is simulated once (seed fixed), then decided with one `prompt --once` (groups of
30 000 selected events, the corrections grid, --sigma-sys auto). Every update after the first
group is a false one: printed is their number against the groups, with the parameter that moved.
"""
import argparse
import collections
import json
import os
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
E = os.environ.get("EMCALIGN", os.path.join(ROOT, "build", "bin", "emcalign"))
GRID = os.path.join(ROOT, "data", "corrections", "ee-40-140deg")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir", nargs="?", default="/tmp/emcalign-prompt-false-rate")
    ap.add_argument("--runs", type=int, default=5000)
    ap.add_argument("--thresholds", default="/tmp/emcalign-prompt-season/thresholds-auto-0.01.json")
    a = ap.parse_args()
    os.makedirs(a.dir, exist_ok=True)
    season = os.path.join(a.dir, "season")
    if not os.path.exists(os.path.join(season, "ready")):
        shutil.rmtree(season, ignore_errors=True)
        with open(os.path.join(a.dir, "period.json"), "w") as f:
            json.dump({"format": "emcalign-period/1", "name": "stable", "first_run": 1, "runs": a.runs,
                       "events_per_run": 6400, "seed": 77, "theta_range_deg": [40, 140],
                       "beam_energy_mev": [{"from_run": 1, "value": 612.5}],
                       "segments": [{"from_run": 1, "parameters": {"alpha": 2.9, "dx": 0.3, "dy": 0.05,
                                                                    "dz": 0.1}}]}, f)
        t0 = time.time()
        subprocess.run([E, "simulate", "--period", "period.json", "--no-hits", "-o", "season"], cwd=a.dir, check=True,
                       stdout=subprocess.DEVNULL)
        open(os.path.join(season, "ready"), "w").close()
        print(f"simulated {a.runs} runs in {time.time() - t0:.0f} s")
    for name in ("state", "c.db", "c.db-wal", "c.db-shm"):
        path = os.path.join(a.dir, name)
        shutil.rmtree(path, ignore_errors=True) if os.path.isdir(path) else (os.path.exists(path) and os.remove(path))
    t0 = time.time()
    r = subprocess.run([E, "prompt", season, "--conditions", "sqlite:" + os.path.join(a.dir, "c.db"), "--tag", "stable",
                        "--thresholds", os.path.abspath(a.thresholds), "--corrections", GRID, "--sigma-sys", "auto",
                        "--min-events", "30000", "--settle", "0", "--once", "-o", os.path.join(a.dir, "state")],
                       capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(r.stderr)
    records = [json.loads(l) for l in open(os.path.join(a.dir, "state", "decisions.jsonl"))]
    false = [x for x in records[1:] if x["decision"] == "update"]
    moved = collections.Counter(reason.split(":")[0] for x in false for reason in x["reasons"])
    print(f"{len(records)} groups decided in {time.time() - t0:.0f} s: {len(false)} false updates among "
          f"{len(records) - 1} ({100 * len(false) / max(1, len(records) - 1):.2f} %), "
          f"{sum(x['decision'] == 'veto' for x in records)} vetoes; the parameters that moved: {dict(moved)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Fit − truth of every IOV of the SND-like period's tags, by beam-energy band: what one
corrections file (612.5 MeV) and the grid (interpolated to each group's energy) leave across
the scan (docs/validation.md, "The beam-energy scan").

  energy_period_summary.py DIR EMCALIGN TAG...

DIR is bench/campaign_study.sh's (DIR/period/truth.json, DIR/c.db). IOVs whose truth changes
inside them by more than 0.01 (cm or deg: a step, not the drift) are left out; the truth of an
IOV is its runs' mean, weighted by events.
"""

import json
import math
import os
import subprocess
import sys
import tempfile

PARAMS = [("dx", "cm"), ("dy", "cm"), ("dz", "cm"), ("dx_rel", "cm"), ("alpha", "deg"), ("mu", "deg")]
BANDS = [(500.0, 650.0), (650.0, 800.0), (800.0, 1000.0)]


def value(result, name):
    if name in result["parameters"]:
        return result["parameters"][name]
    return result["derived"][name]["value"]


def truth_value(run, name):
    return run["parameters"][name] if name in run["parameters"] else run["derived"][name]


def main():
    d, emcalign, tags = sys.argv[1], sys.argv[2], sys.argv[3:]
    truth = {r["run"]: r for r in json.load(open(os.path.join(d, "period", "truth.json")))["runs"]}
    db = os.path.join(d, "c.db")
    print("| tag | band, MeV | IOVs | " + " | ".join(f"{n} ({u}): mean ± err, rms" for n, u in PARAMS) + " |")
    print("|---|---|---|" + "---|" * len(PARAMS))
    with tempfile.TemporaryDirectory() as tmp:
        for tag in tags:
            listing = json.loads(subprocess.run([emcalign, "conditions", "list", db, "--tag", tag, "--json"],
                                                check=True, capture_output=True, text=True).stdout)["iovs"]
            rows = []  # (energy, {name: fit − truth})
            for iov in listing:
                runs = [truth[r] for r in range(iov["first_run"], iov["last_run"] + 1) if r in truth]
                if not runs:
                    continue
                stepped = any(abs(truth_value(r, n) - truth_value(runs[0], n)) > 0.01 for r in runs for n, _ in PARAMS
                              if n not in ("mu",))
                if stepped:
                    continue
                out = os.path.join(tmp, "p.json")
                subprocess.run([emcalign, "conditions", "get", db, "--tag", tag, "--run", str(iov["first_run"]), "-o",
                                out], check=True, capture_output=True)
                result = json.load(open(out))
                events = sum(r["events"] for r in runs)
                energy = sum(r["beam_energy_mev"] * r["events"] for r in runs) / events
                diff = {}
                for name, _ in PARAMS:
                    t = sum(truth_value(r, name) * r["events"] for r in runs) / events
                    diff[name] = value(result, name) - t
                rows.append((energy, diff))
            for lo, hi in BANDS:
                band = [x for e, x in rows if lo <= e <= hi]
                if not band:
                    continue
                cells = []
                for name, _ in PARAMS:
                    v = [x[name] for x in band]
                    mean = sum(v) / len(v)
                    rms = math.sqrt(sum((a - mean) ** 2 for a in v) / max(len(v) - 1, 1))
                    cells.append(f"{mean:+.4f} ± {rms / math.sqrt(len(v)):.4f}, {rms:.4f}")
                print(f"| {tag} | {lo:.0f}–{hi:.0f} | {len(band)} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The numbers of docs/campaign.md from bench/campaign_study.sh's directory: every true step
of the period against the steps the trend found (± one IOV), the false steps, the drift, and
the segment refit against the truth.

  campaign_summary.py DIR EMCALIGN
"""

import json
import os
import subprocess
import sys

STEP = 0.01  # a change of the truth between two runs larger than this (deg or cm) is a step


def iovs(emcalign, db, tag):
    out = subprocess.run([emcalign, "conditions", "list", db, "--tag", tag, "--json"], check=True,
                         capture_output=True, text=True).stdout
    return [(i["first_run"], i["last_run"]) for i in json.loads(out)["iovs"]]


def iov_index(iov_list, run):
    for k, (a, b) in enumerate(iov_list):
        if a <= run <= b:
            return k
    return None


def main():
    d, emcalign = sys.argv[1], sys.argv[2]
    truth = json.load(open(os.path.join(d, "period", "truth.json")))["runs"]
    timings = dict(l.split()[:2] for l in open(os.path.join(d, "timings.txt")) if len(l.split()) == 2
                   and l.split()[1].replace(".", "").isdigit())
    events = sum(r["events"] for r in truth)
    print(f"# Campaign study: {len(truth)} runs ({truth[0]['run']}-{truth[-1]['run']}), {events} events\n")
    print("| step | seconds |\n|---|---|")
    for k, v in timings.items():
        print(f"| {k} | {v} |")
    # The true steps: parameters whose truth changes by more than STEP between listed runs.
    names = list(truth[0]["parameters"]) + list(truth[0]["derived"])
    true_steps = []
    for a, b in zip(truth, truth[1:]):
        for n in names:
            va = a["parameters"].get(n, a["derived"].get(n))
            vb = b["parameters"].get(n, b["derived"].get(n))
            if va is not None and vb is not None and abs(vb - va) > STEP:
                true_steps.append((b["run"], n, vb - va))
    for tag, sub in (("snd.v1", "trend-v1"), ("snd.corr", "trend-corr")):
        t = json.load(open(os.path.join(d, sub, "trend.json")))
        iov_list = iovs(emcalign, os.path.join(d, "c.db"), tag)
        print(f"\n## Tag {tag}: {len(iov_list)} IOVs\n")
        print("| true step | parameter | true size | found at | size found | z | IOVs apart |\n|---|---|---|---|---|---|---|")
        matched = set()
        for run, n, size in true_steps:
            hit = None
            for k, s in enumerate(t["steps"]):
                if s["parameter"] != n:
                    continue
                i_true, i_found = iov_index(iov_list, run), iov_index(iov_list, s["first_run_after"])
                apart = abs(i_true - i_found) if None not in (i_true, i_found) else None
                if apart is not None and apart <= 1:
                    hit = (k, s, apart)
            if hit:
                k, s, apart = hit
                matched.add(k)
                where = s["first_run_after"]
                if s.get("within_iov"):
                    where = f"{where} (inside {s['within_iov'][0]}-{s['within_iov'][1]})"
                print(f"| {run} | {n} | {size:+.4f} | {where} | {s['size']:+.4f} ± {s['error']:.4f} | {s['z']:.1f} | "
                      f"{apart} |")
            else:
                print(f"| {run} | {n} | {size:+.4f} | **not found** | | | |")
        false = [s for k, s in enumerate(t["steps"]) if k not in matched]
        print(f"\nFalse steps: {len(false)}" + "".join(f"; {s['parameter']} at {s['first_run_after']} (z {s['z']:.1f})"
                                                     for s in false))
        for dr in t["drifts"]:
            print(f"\nDrift flagged: {dr['parameter']} runs {dr['first_run']}-{dr['last_run']}, "
                  f"{dr['slope_per_run']:+.3g} ± {dr['error']:.2g} {dr['unit']} (z {dr['z']:.1f})")
        if not t["drifts"]:
            print("\nNo drift flagged.")
        if "refit" in t:
            r = t["refit"]
            print(f"\n### Refit: {r['iovs']} IOVs instead of {r['iovs_before']}\n")
            print("| runs | events | parameter | refit | truth | refit − truth | RMS(IOV − truth) before | "
                  "statistical error before → after | quoted error before → after |\n|---|---|---|---|---|---|---|---|---|")
            for s in r["segments"]:
                if s["kept"]:
                    why = "straddles a step" if s.get("transition") else "drifting: " + ", ".join(s["drifting"])
                    print(f"| {s['first_run']}-{s['last_run']} | | kept ({why}) | | | | | | |")
                    continue
                for n in ("dx", "alpha", "dp1", "psi"):
                    p = s["precision"][n]
                    print(f"| {s['first_run']}-{s['last_run']} | {s['selected_events']} | {n} | {p['value']:.4f} | "
                          f"{p['truth']:.4f} | {p['refit_minus_truth']:+.4f} | {p['rms_before_minus_truth']:.4f} | "
                          f"{p['statistical_error_before']:.4f} → {p['statistical_error_after']:.4f} | "
                          f"{p['quoted_error_before']:.4f} → {p['quoted_error_after']:.4f} |")


if __name__ == "__main__":
    main()

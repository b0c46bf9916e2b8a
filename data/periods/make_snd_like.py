#!/usr/bin/env python3
"""Writes snd-2010-2011-like.json: a period like the one SND calibrated run by run (the paper,
section 5: about 2000 runs of 2010-2011, 25.3 pb^-1).

How many e+e- -> e+e- events a run has:
  N = L_run * sigma_vis(E_beam),
  sigma_vis = the lowest-order Bhabha cross-section for both particles in 40-140 deg (the
              polar range simulated; the selection keeps about 80 % of these events),
              integrated numerically below: 607 nb at E_beam = 525 MeV, 167 nb at 1000 MeV;
  L_run     = 25.3 pb^-1 / 2000 runs = 12.65 nb^-1 on average, drawn uniformly in [6.0, 19.3]
              nb^-1 (runs of one to a few hours at VEPP-2000's 2010-2011 luminosity).
So each energy point gets events_per_run = [6.0, 19.3] nb^-1 * sigma_vis(E), and the period
has about 8.1 million events (6.5 million selected: 106 calibrations of at least 50 000 once the runs
are grouped by energy).

The energy scan: 2010 goes down from 1000 to 525 MeV per beam in 25 MeV steps (20 points),
2011 comes back up from 537.5 to 987.5 MeV (19 points), about 51 runs each, with a few bad
runs missing. The truth: three reassemblies of the detector (steps in dx; the second, between
the two scans, also turns the tilt direction psi), and in the last part a slow drift of dz
(the quality-control signal "steady changes" of the paper).

Usage: make_snd_like.py [OUTPUT]   (default: snd-2010-2011-like.json next to this script)
"""
import json
import math
import os
import sys

ALPHA = 1 / 137.035999
GEV2_NB = 0.3893794e6  # (hbar c)^2 in GeV^2 nb


def sigma_vis_nb(e_beam_mev, theta_min=40.0, theta_max=140.0, steps=20000):
    """Lowest-order Bhabha cross-section (both particles in [theta_min, theta_max]), nb."""
    s = (2 * e_beam_mev / 1000.0) ** 2
    a, b = math.radians(theta_min), math.radians(theta_max)
    total = 0.0
    for i in range(steps):
        th = a + (b - a) * (i + 0.5) / steps
        c2, s2 = math.cos(th / 2) ** 2, math.sin(th / 2) ** 2
        f = (1 + c2 ** 2) / s2 ** 2 - 2 * c2 ** 2 / s2 + (1 + math.cos(th) ** 2) / 2
        total += f * math.sin(th) * (b - a) / steps
    return ALPHA ** 2 / (4 * s) * 2 * math.pi * total * GEV2_NB


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                             "snd-2010-2011-like.json")
    first_run, runs = 10001, 2000
    energies = [1000 - 25 * k for k in range(20)] + [537.5 + 25 * k for k in range(19)]
    per_point = runs / len(energies)
    lumi = (6.0, 19.3)  # nb^-1 per run
    points = []
    for k, e in enumerate(energies):
        sigma = sigma_vis_nb(e)
        points.append({"from_run": first_run + round(k * per_point), "value": e,
                       "events_per_run": [round(lumi[0] * sigma), round(lumi[1] * sigma)],
                       "comment": f"sigma_vis = {sigma:.1f} nb"})
    base = {"alpha": 2.9, "beta1": 0.19, "beta2": 0.16, "dx": 0.25, "dy": -0.10, "dz": 0.15,
            "dp1": 0.55, "dp2": 0.25, "dp3": 0.45, "dy_rel": 0.05, "dz_rel": -0.04, "beta_rel": 0.08}
    scenario = {
        "format": "emcalign-period/1",
        "name": "snd-2010-2011-like",
        "description": "About 2000 runs like SND's 2010-2011 (25.3 pb^-1): two energy scans, three reassemblies "
                       "(steps in dx, one also in psi), a slow dz drift at the end. Made by make_snd_like.py.",
        "first_run": first_run,
        "runs": runs,
        "events_per_run": [1000, 10000],
        "seed": 2011,
        "theta_range_deg": [40, 140],
        "beam_energy_mev": points,
        "segments": [
            {"from_run": 10001, "parameters": base, "comment": "as assembled"},
            {"from_run": 10431, "parameters": {"dx": 0.40}, "comment": "reassembly 1: dx +0.15 cm"},
            {"from_run": 11021, "physical": {"psi": 115.0, "dx": 0.30},
             "comment": "reassembly 2 (between the scans): dx -0.10 cm, psi 40 -> 115 deg"},
            {"from_run": 11601, "parameters": {"dx": 0.45}, "comment": "reassembly 3: dx +0.15 cm"},
        ],
        "drift": [{"parameter": "dz", "from_run": 11601, "to_run": 12000, "per_run": 0.0003,
                   "comment": "0.12 cm over the last 400 runs"}],
        "missing_runs": [10077, [10512, 10514], 11333, [11890, 11893]],
    }
    with open(out, "w") as f:
        json.dump(scenario, f, indent=1)
        f.write("\n")
    total = 0.0
    for k, p in enumerate(points):
        n = (points[k + 1]["from_run"] if k + 1 < len(points) else first_run + runs) - p["from_run"]
        total += n * sum(p["events_per_run"]) / 2
    print(f"wrote {out}: {len(points)} energy points, about {total / 1e6:.2f} million events")


if __name__ == "__main__":
    main()

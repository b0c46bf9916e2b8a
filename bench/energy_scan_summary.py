#!/usr/bin/env python3
"""The tables of bench/energy_scan_study.sh: per beam energy, every parameter's bias and
slope with the paper's model, with the 612.5 MeV corrections file, and with the grid
interpolated to the energy; the pull widths and means of the grid with --sigma-sys auto.

    bench/energy_scan_summary.py DIR ENERGY...

A corrected bias is counted as compatible with zero when it is within 2 combined standard
errors: its campaign's ± and the statistical error the corrections give every fit (the
grid points' derived_from errors, interpolated like the corrections).
"""
import json
import math
import os
import sys

PARAMS = ["alpha", "beta1", "beta2", "dx", "dy", "dz", "dp1", "dp2", "dp3", "dy_rel", "dz_rel", "beta_rel"]
DERIVED = ["mu", "dx_rel"]
GRID = os.path.join(os.path.dirname(__file__), "..", "data", "corrections", "ee-40-140deg")


def table(path):
    p = os.path.join(path, "table.json")
    return json.load(open(p))["parameters"] if os.path.exists(p) else None


def own_errors(energy):
    """The corrections' own statistical error per fit parameter at `energy`: the two grid
    points around it, interpolated linearly."""
    points = []
    for name in sorted(os.listdir(GRID)):
        j = json.load(open(os.path.join(GRID, name)))
        d = j["derived_from"]
        e = {k: math.hypot(d["nominal_profile_parameter_errors"][k], d["response_parameter_errors"][k])
             for k in PARAMS}
        points.append((j["beam_energy_mev"], e))
    points.sort(key=lambda p: p[0])
    for (ea, a), (eb, b) in zip(points, points[1:]):
        if ea <= energy <= eb:
            w = (energy - ea) / (eb - ea)
            return {k: (1 - w) * a[k] + w * b[k] for k in PARAMS}
    return {k: 0.0 for k in PARAMS}


def cell(row, digits):
    if row is None:
        return "—"
    return f"{row['bias']:+.{digits}f} ± {row['bias_error']:.{digits}f}"


def slope(row):
    if row is None or row.get("slope") is None:
        return "—"
    return f"{row['slope']:+.3f}"


def main():
    directory, energies = sys.argv[1], sys.argv[2:]
    print("# Validation across the beam-energy scan\n")
    print(f"`bench/energy_scan_study.sh {directory} ...`: per energy, the same samples fitted with the paper's "
          "model, with the corrections file of 612.5 MeV, and with the grid interpolated to the energy "
          "(the contract's sigma_sys); the pulls of the grid with `--sigma-sys auto`.\n")
    for energy in energies:
        e = float(energy)
        paper = table(os.path.join(directory, f"paper-{energy}"))
        single = table(os.path.join(directory, f"single-{energy}"))
        grid = table(os.path.join(directory, f"grid-{energy}"))
        auto = table(os.path.join(directory, f"grid-auto-{energy}"))
        own = own_errors(e)
        print(f"## {energy} MeV\n")
        print("| parameter | unit | paper's model: bias | slope | 612.5 MeV file: bias | slope | **grid: bias** | "
              "slope | within 2σ | grid, auto: pull width | pull mean |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        compatible, slopes_ok = 0, 0
        for name in PARAMS + DERIVED:
            rows = [t[name] if t else None for t in (paper, single, grid, auto)]
            ref = next((r for r in rows if r is not None), None)
            if ref is None:
                continue
            digits = 4
            g = rows[2]
            within = "—"
            if g is not None and name in own:
                combined = math.hypot(g["bias_error"], own[name])
                ok = abs(g["bias"]) <= 2 * combined
                compatible += ok
                within = "yes" if ok else f"**no** ({abs(g['bias']) / combined:.1f}σ)"
            if g is not None and name in PARAMS and g.get("slope") is not None:
                slopes_ok += abs(g["slope"]) < 0.01
            a = rows[3]
            width = f"{a['pull_width']:.2f} ± {a['pull_width_error']:.2f}" if a else "—"
            mean = f"{a['pull_mean']:+.2f}" if a else "—"
            print(f"| {name} | {ref['unit']} | {cell(rows[0], digits)} | {slope(rows[0])} | {cell(rows[1], digits)} | "
                  f"{slope(rows[1])} | **{cell(g, digits)}** | {slope(g)} | {within} | {width} | {mean} |")
        print(f"\nGrid: {compatible} of 12 biases within 2 combined standard errors, {slopes_ok} of 12 slopes below 1 %.\n")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Outside check of `emcalign correct --method clusters` (docs/contract.md §9, §11).

Simulates a small CSV sample, corrects it with random alignments, and checks every row
against the independent numpy transform of spec_reference.py:
  * a row with a cluster: (phi_emc, theta_emc) = the angles of forward(R(E, theta) * u(phi,
    theta)) with s = sign(cos phi), to 1e-9 rad (phi compared on the circle);
  * every other field, and every row without a cluster, is the same text as in the input;
  * the same rows in the same order, and the output's comment lines name the correction.

usage: check_correct.py EMCALIGN
"""

import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spec_reference as ref  # noqa: E402


def rows_of(path):
    comments, rows = [], []
    with open(path) as f:
        for line in f.read().splitlines():
            (comments if line.startswith("#") else rows).append(line)
    return comments, rows[0], [r.split(",") for r in rows[1:]]


def main():
    emcalign = sys.argv[1]
    rng = np.random.default_rng(7)
    worst = 0.0
    corrected = 0
    with tempfile.TemporaryDirectory() as d:
        truth = os.path.join(d, "truth.json")
        with open(truth, "w") as f:
            json.dump({"format": "emcalign-alignment/1", "parameters": ref.file_from_fit(ref.random_fit(rng))}, f)
        events = os.path.join(d, "ev.csv")
        r = subprocess.run([emcalign, "simulate", "--process", "3pi", "--events", "1500", "--params", truth,
                            "-o", events], capture_output=True, text=True)
        if r.returncode != 0:
            print(r.stderr)
            return 1
        _, header, rows_in = rows_of(events)
        columns = header.split(",")
        i_e, i_phi, i_theta = columns.index("energy_mev"), columns.index("phi_emc_rad"), columns.index("theta_emc_rad")
        for trial in range(4):
            fit = ref.random_fit(rng)
            params = os.path.join(d, f"p{trial}.json")
            with open(params, "w") as f:
                json.dump({"format": "emcalign-alignment/1", "parameters": ref.file_from_fit(fit)}, f)
            out = os.path.join(d, f"c{trial}.csv")
            r = subprocess.run([emcalign, "correct", events, "--alignment", params, "--method", "clusters", "-o", out],
                               capture_output=True, text=True)
            if r.returncode != 0:
                print(r.stderr)
                return 1
            comments, header_out, rows_out = rows_of(out)
            assert header_out == header, "the columns changed"
            assert any(c.startswith("# correction: ") and '"method":"clusters"' in c for c in comments), comments
            assert len(rows_out) == len(rows_in), "the rows changed"
            for a, b in zip(rows_in, rows_out):
                same = [k for k in range(len(a)) if k not in (i_phi, i_theta)]
                assert [a[k] for k in same] == [b[k] for k in same], (a, b)
                if a[i_e] == "":
                    assert a == b
                    continue
                e, phi, theta = float(a[i_e]), float(a[i_phi]), float(a[i_theta])
                p0 = ref.shower_depth(e, theta) * ref.direction(phi, theta)
                s = 1 if math.cos(phi) >= 0.0 else -1
                phi1, theta1 = ref.angles(ref.forward(p0, fit, s, 1))
                dphi = abs(math.remainder(float(b[i_phi]) - phi1, 2.0 * math.pi))
                worst = max(worst, dphi, abs(float(b[i_theta]) - theta1))
                corrected += 1
    print(f"{corrected} corrected clusters against spec_reference: worst deviation {worst:.2e} rad")
    ok = corrected > 1000 and worst <= 1e-9
    print("ok" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

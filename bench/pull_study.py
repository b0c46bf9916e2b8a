#!/usr/bin/env python3
"""Why a pull width of a validation campaign (emcalign validate) is not 1: the widths as
tabulated, and again after the part of (fit − truth) that depends linearly on the truth is
taken out — first on the parameter's own truth (its scale error), then on all 12 truths (its
scale and cross terms). A width that falls to 1 once the truth dependence is out is a scale
error of the model, not an error that is wrong; the largest dependences are listed.

  pull_study.py CAMPAIGN_DIR [CAMPAIGN_DIR...]
"""

import glob
import json
import os
import sys

import numpy as np

NAMES = ["alpha", "beta1", "beta2", "dx", "dy", "dz", "dp1", "dp2", "dp3", "dy_rel", "dz_rel", "beta_rel"]


def load(directory):
    truth, fit, error, sigma = [], [], [], []
    for path in sorted(glob.glob(os.path.join(directory, "samples", "sample_*.json"))):
        with open(path) as f:
            s = json.load(f)
        truth.append([s["truth"]["parameters"][n] for n in NAMES])
        fit.append([s["fit"]["parameters"][n] for n in NAMES])
        error.append([s["fit"]["errors"][n] for n in NAMES])
        sigma.append(s["fit"].get("sigma_sys", {}).get("value_deg", 0.2))
    if len(truth) < 20:
        sys.exit(f"{directory}: {len(truth)} samples; at least 20 are needed")
    return np.array(truth), np.array(fit), np.array(error), np.array(sigma)


def width_after(d, e, x):
    """Pull width of the residuals of d regressed on the columns of x (with a constant)."""
    a = np.column_stack([np.ones(len(d)), x])
    coef = np.linalg.lstsq(a, d, rcond=None)[0]
    r = (d - a @ coef) / e
    return np.sqrt(r @ r / (len(d) - a.shape[1])), coef[1:]


def study(directory):
    truth, fit, error, sigma = load(directory)
    d = fit - truth
    pulls = d / error
    n = len(d)
    print(f"{directory}: {n} samples, sigma_sys median {np.median(sigma):.4f} deg")
    print(f"{'parameter':10} {'width':>13} {'own truth out':>14} {'12 truths out':>14} {'pull mean':>10}  largest dependences "
          "(coefficient, share of the spread)")
    for k, name in enumerate(NAMES):
        w = pulls[:, k].std(ddof=1)
        w1, _ = width_after(d[:, k], error[:, k], truth[:, [k]])
        w12, coef = width_after(d[:, k], error[:, k], truth)
        share = coef * truth.std(axis=0) / d[:, k].std()
        top = np.argsort(-abs(share))[:3]
        deps = "  ".join(f"{NAMES[i]} {coef[i]:+.4f} ({share[i]:+.2f})" for i in top)
        print(f"{name:10} {w:6.3f} ± {w / np.sqrt(2 * (n - 1)):.3f} {w1:14.3f} {w12:14.3f} {pulls[:, k].mean():10.3f}  {deps}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for directory in sys.argv[1:]:
        study(directory)

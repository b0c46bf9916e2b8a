#!/usr/bin/env python3
"""The tables of docs/checks.md from bench/check_study.sh's directory.

  check_summary.py DIR
"""
import json
import os
import sys


def load(d, name):
    return json.load(open(os.path.join(d, name, "check.json")))


def main():
    d = sys.argv[1]
    rows = [("nominal detector (no misalignment)", "nominal"), ("corrected with the truth", "truth"),
            ("corrected with the fit (with corrections)", "fit"), ("corrected with the fit (the contract's model)", "fit-plain")]
    print("## e+e- → γγ: Δφ core width and RMS (deg)\n")
    print("| sample | selected | before: σ_core ± err | RMS | after: σ_core ± err | RMS | better: σ_core | RMS |")
    print("|---|---|---|---|---|---|---|---|")
    for label, name in rows:
        j = load(d, "gg-" + name)
        b, a, i = j["before"], j["after"], j["improvement_percent"]
        print(f"| {label} | {j['selected']} | {b['dphi_width_deg']:.3f} ± {b['dphi_width_error_deg']:.3f} | "
              f"{b['dphi_rms_deg']:.3f} | {a['dphi_width_deg']:.3f} ± {a['dphi_width_error_deg']:.3f} | "
              f"{a['dphi_rms_deg']:.3f} | {i['dphi_width']:.1f} % | {i['dphi_rms']:.1f} % |")
    print("\n## e+e- → π+π−π0: the kinematic fit's χ² (ndf 2)\n")
    print("| sample | selected | before: mean | median | mean < 20 | after: mean | median | mean < 20 | above 20 | "
          "lower: mean | median | mean < 20 | not converged |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for label, name in rows:
        j = load(d, "3pi-" + name)
        b, a, i = j["before"], j["after"], j["improvement_percent"]
        low = 100 * (b['chi2_mean_below_20'] - a['chi2_mean_below_20']) / b['chi2_mean_below_20']
        print(f"| {label} | {j['selected']} | {b['chi2_mean']:.2f} | {b['chi2_median']:.3f} | "
              f"{b['chi2_mean_below_20']:.3f} | {a['chi2_mean']:.2f} | {a['chi2_median']:.3f} | "
              f"{a['chi2_mean_below_20']:.3f} | {100 * a['fraction_above_20']:.1f} % | {i['chi2_mean']:.1f} % | "
              f"{i['chi2_median']:.1f} % | {low:.1f} % | {a['not_converged']} |")
    print("\n## Which terms matter: the truth with one group left out\n")
    print("| left out | γγ: Δφ σ_core better | Δφ RMS better | 3π: mean χ² lower | median χ² lower |")
    print("|---|---|---|---|---|")
    for label, name in [("nothing (the truth)", "truth"), ("α", "without-alpha"), ("β1, β2", "without-beta12"),
                        ("dx, dy, dz", "without-shift"), ("dp1, dp2, dp3 (the gap: μ, τ, dx_rel)", "without-gap"),
                        ("dy_rel, dz_rel, β_rel", "without-relative")]:
        g, p = load(d, "gg-" + name)["improvement_percent"], load(d, "3pi-" + name)["improvement_percent"]
        print(f"| {label} | {g['dphi_width']:.1f} % | {g['dphi_rms']:.1f} % | {p['chi2_mean']:.1f} % | "
              f"{p['chi2_median']:.1f} % |")


if __name__ == "__main__":
    main()

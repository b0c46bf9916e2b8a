#!/usr/bin/python3
"""Acceptance check of `emcalign fit` on independent e+e- -> e+e- events (docs/contract.md §5-§8).

Usage:  /usr/bin/python3 tests/crosscheck/check_fit.py PATH_TO_EMCALIGN [--keep-temp]
                                                        [--events N]

For each of two truth sets (paper-like; a larger misalignment):
  1. `spec_events.py` (a numpy generator written from docs/contract.md alone) writes N = 30 000
     events, ~3 % of them made to fail the docs/contract.md §7 selection, and the truth file;
  2. `emcalign fit EVENTS.csv -o r.json --profile-out p.csv` is run;
  3. checks:
     - the fit exits 0 with status `converged`, and the truth file is accepted by
       `emcalign params show`;
     - (a) every fitted parameter is within 3 x its error of the truth (file units:
       deg, cm; beta1/beta2 as the files write them);
     - the docs/contract.md §7 cut flow of emcalign equals that of the independent selection
       (bench/minuit_crosscheck.py), and the number of selected events equals the
       generator's count of events meant to pass;
     - (b) the independent profile (minuit_crosscheck's --events mode) equals
       emcalign's --profile-out bin by bin (n exactly, means and sigmas to 1e-9 relative);
     - the independent chi2 at emcalign's parameters equals emcalign's chi2 (1e-6), ndf equal;
     - (c) the independent staged MIGRAD fit (docs/contract.md §8 stages, iminuit) reaches the same
       chi2 minimum (relative 1e-6) in every stage, and the same parameters within
       1e-3 x their errors; emcalign's errors equal the independent (J^T J)^-1 (1e-4).
Prints a report and `N passed, M failed`; exit status 1 on any failure.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "..", "bench"))
import minuit_crosscheck as mc  # noqa: E402
import spec_reference as ref    # noqa: E402

GENERATOR = os.path.join(HERE, "spec_events.py")
N_EVENTS = 30000
TIMEOUT = 300

TOL_PULL = 3.0          # |fit - truth| <= 3 x error
TOL_CHI2 = 1e-6         # relative
TOL_PAR = 1e-3          # in units of the parameter's error
TOL_STAT = 4.0         # |fit - truth| <= 4 x its statistical (sigma_sys-free) error
TOL_ERR = 1e-4          # relative, emcalign's error vs the independent (J^T J)^-1

LARGE = {"alpha": 5.0, "beta1": -0.3, "beta2": 0.25, "dx": -0.5, "dy": 0.5, "dz": -0.5,
         "dp1": 0.8, "dp2": 0.3, "dp3": 0.55, "dy_rel": -0.1, "dz_rel": 0.08, "beta_rel": -0.15}
# sphere: where spec_events.py puts the shower point (see its docstring):
#   "ts"  - on the sphere |p| = R(E, theta) around the TS origin (docs/contract.md §5's p_R of the true
#           track), as the acceptance check prescribes;
#   "emc" - at depth R(E, theta) from the actual hemisphere's centre: docs/contract.md §5's model
#           p0 = R(E, theta0) (...) , p1 = forward(p0) taken literally.
# The two differ at second order (~ |xi|^2 / R^2 ~ 1e-4 rad for 0.5-0.7 cm shifts): far
# below the quoted errors (sigma_sys dominates), but ~2 statistical errors on dy_rel,
# alpha, dz_rel for the large set. So the truth is tested at the statistical precision
# (stat_check) only on "emc" events; on "ts" events those pulls are printed for information.
CASES = [
    {"name": "paper-like", "seed": 20240611, "params": None,   # generator's default truth
     "sphere": "ts", "stat_check": False,
     "truth": {"alpha": 3.0, "beta1": 0.2, "beta2": -0.1, "dx": 0.3, "dy": -0.1, "dz": 0.2,
               "dp1": 0.6, "dp2": 0.2, "dp3": 0.4, "dy_rel": 0.05, "dz_rel": -0.05,
               "beta_rel": 0.1}},
    {"name": "large", "seed": 20240612, "params": "given", "sphere": "ts", "stat_check": False,
     "truth": LARGE},
    {"name": "large-emc-sphere", "seed": 20240613, "params": "given", "sphere": "emc",
     "stat_check": True, "truth": LARGE},
]

results = []            # (name, ok, detail)


def check(name, ok, detail=""):
    results.append((name, bool(ok), detail))
    print("  [%s] %s%s" % ("PASS" if ok else "FAIL", name, ("  " + detail) if detail else ""))
    sys.stdout.flush()


def run(cmd, what):
    t0 = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=TIMEOUT)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        print("    %s exited %d:\n%s\n%s" % (what, p.returncode, p.stdout[-2000:], p.stderr[-2000:]))
    return p, dt


def param_file(values):
    return {"format": "emcalign-alignment/1", "units": {"angle": "deg", "length": "cm"},
            "parameters": dict(values)}


def run_case(exe, case, tmp, n_events):
    name = case["name"]
    print("\n== %s (shower sphere %s, seed %d): truth %s =="
          % (name, case["sphere"], case["seed"], json.dumps(case["truth"])))
    d = os.path.join(tmp, name)
    os.makedirs(d)
    events, truth_out = os.path.join(d, "events.csv"), os.path.join(d, "truth.json")
    result, profile = os.path.join(d, "r.json"), os.path.join(d, "p.csv")
    cmd = [sys.executable, GENERATOR, "--events", str(n_events), "--seed", str(case["seed"]),
           "--truth", truth_out, "-o", events, "--shower-sphere", case["sphere"]]
    if case["params"]:
        given = os.path.join(d, "truth_in.json")
        with open(given, "w") as f:
            json.dump(param_file(case["truth"]), f)
        cmd += ["--params", given]
    p, dt_gen = run(cmd, "spec_events.py")
    if p.returncode != 0:
        check("%s: generator runs" % name, False)
        return
    summary = json.loads(p.stdout.strip().splitlines()[-1])
    print("  generated %d events (%d rows) in %.2f s: %s; %d particles in the gap; "
          "%d events expected to pass docs/contract.md §7"
          % (summary["events"], summary["rows"], dt_gen, summary["kinds"],
             summary["particles_without_cluster"], summary["expected_selected"]))
    with open(truth_out) as f:
        truth = json.load(f)["parameters"]
    check("%s: truth file written as given" % name,
          all(abs(truth[k] - case["truth"][k]) < 1e-12 for k in ref.FIT_NAMES))
    p, _ = run([exe, "params", "show", truth_out, "--json"], "emcalign params show")
    check("%s: truth file accepted by `emcalign params show`" % name, p.returncode == 0)

    p, dt_fit = run([exe, "fit", events, "-o", result, "--profile-out", profile], "emcalign fit")
    ok = p.returncode == 0 and os.path.exists(result) and os.path.exists(profile)
    check("%s: `emcalign fit` exits 0 and writes the result and the profile" % name, ok,
          "(%.2f s)" % dt_fit)
    if not ok:
        return
    with open(result) as f:
        res = json.load(f)
    check("%s: status converged, no warnings" % name,
          res.get("status") == "converged" and not res.get("warnings"),
          "status %r, warnings %r" % (res.get("status"), res.get("warnings")))

    # (a) truth within 3 errors
    x_em = np.array([res["parameters"][n] for n in ref.FIT_NAMES], dtype=float)
    e_em = np.array([res["errors"][n] for n in ref.FIT_NAMES], dtype=float)
    x_tr = np.array([truth[n] for n in ref.FIT_NAMES], dtype=float)
    pull = (x_em - x_tr) / e_em
    print("  parameter   truth        emcalign        error      (fit-truth)/error")
    for k, n in enumerate(ref.FIT_NAMES):
        unit = "deg" if n in ref.FIT_ANGLE_NAMES else "cm"
        print("  %-9s %+9.4f   %+12.6f   %9.6f   %+6.2f   %s" % (n, x_tr[k], x_em[k], e_em[k],
                                                               pull[k], unit))
    print("  chi2/ndf = %.4g/%d; RMS pull %.2f" % (res["chi2"], res["ndf"],
                                                   math.sqrt(float(np.mean(pull ** 2)))))
    worst = int(np.argmax(np.abs(pull)))
    check("%s: (a) every parameter within %g x its error of the truth" % (name, TOL_PULL),
          np.all(np.isfinite(pull)) and np.max(np.abs(pull)) <= TOL_PULL,
          "worst %s %+.2f sigma" % (ref.FIT_NAMES[worst], pull[worst]))

    # selection and (b) profile
    t0 = time.perf_counter()
    mine, counts = mc.select_and_fill(mc.read_events(events))
    dt_sel = time.perf_counter() - t0
    flow_em = res.get("input", {}).get("cut_flow", {})
    keys = ["events read", "no muon veto", "2 charged, 0 photons", "track |z0|, |rho|",
            "cluster energies", "acollinearity"]
    print("  cut flow      independent   emcalign")
    for k in keys:
        print("  %-24s %8d   %8s" % (k, counts[k], flow_em.get(k)))
    check("%s: docs/contract.md §7 cut flow equals the independent selection's" % name,
          all(flow_em.get(k) == counts[k] for k in keys))
    check("%s: selected events = the generator's events meant to pass" % name,
          counts["acollinearity"] == summary["expected_selected"]
          and flow_em.get("acollinearity") == summary["expected_selected"],
          "%d independent, %s emcalign, %d expected" % (counts["acollinearity"],
                                                        flow_em.get("acollinearity"),
                                                        summary["expected_selected"]))
    check("%s: every reject kind present (selection exercised)" % name,
          all(summary["kinds"][k] > 0 for k in ("photon", "veto", "low_e", "z0", "acol"))
          and summary["particles_without_cluster"] > 0)
    theirs = mc.read_profile(profile)
    ok, worst_rel, lines = mc.compare_profiles(mine, theirs)
    for ln in lines:
        print(ln)
    check("%s: (b) independent profile equals emcalign's (n exact, means/sigmas <= %g)"
          % (name, mc.TOL_PROFILE), ok,
          "worst relative %.2g (%s); %d particles in the profiles%s"
          % (max(worst_rel.values()) if worst_rel else float("nan"),
             max(worst_rel, key=worst_rel.get) if worst_rel else "-",
             counts["particles in the profiles"], ("; " + lines[0].strip()) if lines else ""))

    # model check and (c) the independent staged Minuit fit
    chi2 = mc.Chi2(mine)
    c_at = chi2(x_em)
    rel = abs(c_at - res["chi2"]) / abs(res["chi2"])
    check("%s: independent chi2 at emcalign's parameters = emcalign's chi2" % name,
          rel <= TOL_CHI2, "%.10g vs %.10g (relative %.2g)" % (c_at, res["chi2"], rel))
    ndf = 2 * chi2.used - len(ref.FIT_NAMES)
    check("%s: ndf = 2 x bins used - 12 equal" % name, ndf == res.get("ndf"),
          "%d vs %s" % (ndf, res.get("ndf")))
    t0 = time.perf_counter()
    m, stages, _, _ = mc.staged_fit(chi2)
    dt_mn = time.perf_counter() - t0
    em_stages = {s["stage"]: s["chi2"] for s in res.get("stages", [])}
    print("  stage  chi2 Minuit          chi2 emcalign        relative")
    worst_stage = 0.0
    for s in stages:
        e = em_stages.get(s["stage"], float("nan"))
        r = abs(s["chi2"] - e) / abs(e)
        worst_stage = max(worst_stage, r) if np.isfinite(r) else float("inf")
        print("  %5d  %-19.12g  %-19.12g  %.2g" % (s["stage"], s["chi2"], e, r))
    check("%s: Minuit minimum valid in every stage" % name, all(s["valid"] for s in stages))
    check("%s: (c) every stage's chi2 equals emcalign's (relative <= %g)" % (name, TOL_CHI2),
          worst_stage <= TOL_CHI2, "worst %.2g" % worst_stage)
    rel_min = abs(m.fval - res["chi2"]) / abs(res["chi2"])
    check("%s: (c) chi2 minimum equal (relative <= %g)" % (name, TOL_CHI2),
          rel_min <= TOL_CHI2, "Minuit %.12g, emcalign %.12g (relative %.2g)"
          % (m.fval, res["chi2"], rel_min))
    x_mn = np.array(m.values)
    dpar = np.abs(x_mn - x_em) / e_em
    k = int(np.argmax(dpar))
    check("%s: (c) parameters equal within %g x their errors" % (name, TOL_PAR),
          dpar.max() <= TOL_PAR, "worst %s %.2e" % (ref.FIT_NAMES[k], dpar[k]))
    # truth at the statistical precision: emcalign's estimate has the sandwich covariance
    # A^-1 J^T D J A^-1 (J the whitened Jacobian, A = J^T J, D = sigma_stat^2 / sigma^2 per
    # residual): sigma_sys inflates the quoted errors ~7x, this tests the truth ~7x tighter.
    e_stat = stat_errors(chi2, mine, x_mn)
    spull = (x_em - x_tr) / e_stat
    print("  (fit-truth)/statistical error: " + " ".join(
        "%s %+.2f" % (n, v) for n, v in zip(ref.FIT_NAMES, spull)))
    k = int(np.argmax(np.abs(spull)))
    what = ("%s: every parameter within %g x its statistical error of the truth" % (name, TOL_STAT))
    detail = ("worst %s %+.2f; RMS %.2f (statistical errors %.2f-%.2f x the quoted ones)"
              % (ref.FIT_NAMES[k], spull[k], math.sqrt(float(np.mean(spull ** 2))),
                 float(np.min(e_stat / e_em)), float(np.max(e_stat / e_em))))
    if case["stat_check"]:
        check(what, np.max(np.abs(spull)) <= TOL_STAT, detail)
    else:
        print("  [info] %s (not a check on `ts` events): %s" % (what, detail))
    e_gn = np.sqrt(np.diag(mc.gauss_newton_cov(chi2, x_mn)))
    derr = np.abs(e_gn - e_em) / e_em
    k = int(np.argmax(derr))
    check("%s: errors equal the independent (J^T J)^-1 (relative <= %g)" % (name, TOL_ERR),
          derr.max() <= TOL_ERR, "worst %s %.2e; HESSE differs by at most %.2e"
          % (ref.FIT_NAMES[k], derr[k], float(np.max(np.abs(np.array(m.errors) - e_em) / e_em))))
    print("  times: generator %.2f s, emcalign fit %.2f s, independent selection %.2f s, "
          "Minuit staged fit + HESSE %.2f s" % (dt_gen, dt_fit, dt_sel, dt_mn))


def stat_errors(chi2, prof, x):
    """Statistical (sandwich) errors of the sigma-weighted least-squares estimate at x."""
    jac = mc.whitened_jacobian(chi2, x)
    use = prof["n"] >= mc.MIN_N
    sig = np.concatenate((prof["sigma_phi"][use], prof["sigma_theta"][use]))
    d = np.maximum(sig ** 2 - mc.SIGMA_SYS ** 2, 0.0) / sig ** 2      # sigma_stat^2 / sigma^2
    a_inv = np.linalg.inv(jac.T @ jac)
    cov = a_inv @ (jac.T @ (d[:, None] * jac)) @ a_inv
    return np.sqrt(np.diag(cov))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("emcalign", help="path to the emcalign executable")
    ap.add_argument("--keep-temp", action="store_true", help="keep the temporary directory")
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="added to the fixed seeds (for studies; default 0)")
    ap.add_argument("--events", type=int, default=N_EVENTS,
                    help="events per truth set (default %d)" % N_EVENTS)
    args = ap.parse_args()
    exe = os.path.abspath(args.emcalign)
    t0 = time.perf_counter()
    print("emcalign fit on independent contract-model events (%s, numpy %s, iminuit %s)"
          % (exe, np.__version__, __import__("iminuit").__version__))
    tmp = tempfile.mkdtemp(prefix="emcalign_check_fit_")
    try:
        for case in CASES:
            try:
                run_case(exe, dict(case, seed=case["seed"] + args.seed_offset), tmp, args.events)
            except Exception as exc:  # a crash is a failure, reported, not a traceback only
                check("%s: no exception in the check" % case["name"], False,
                      "%s: %s" % (type(exc).__name__, exc))
    finally:
        if args.keep_temp:
            print("\nfiles kept in %s" % tmp)
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    nf = sum(1 for _, ok, _ in results if not ok)
    print("\ntotal time %.1f s" % (time.perf_counter() - t0))
    if nf:
        print("FAILED:")
        for n, ok, det in results:
            if not ok:
                print("  - %s %s" % (n, det))
    print("%d passed, %d failed" % (len(results) - nf, nf))
    return 1 if nf else 0


if __name__ == "__main__":
    sys.exit(main())

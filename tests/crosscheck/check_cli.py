#!/usr/bin/python3
"""Cross-check the emcalign command-line tool against the independent reference written from the contract.

Usage:  /usr/bin/python3 tests/crosscheck/check_cli.py PATH_TO_EMCALIGN_BINARY [--keep-temp]

Checks (all against tests/crosscheck/spec_reference.py, written from docs/contract.md alone):
  * the reference's own self-consistency checks;
  * `BIN transform --params P.json [--inverse] [--hemisphere +1|-1|auto] [--layer 1|3]`
    on a few hundred random points per parameter set, forward and inverse, each
    hemisphere explicitly, auto / default, layers 1 and 3 (and the default layer):
    every coordinate to 1e-9 cm, the hemisphere column exactly (gap / overlap with
    empty coordinates in inverse-auto mode);
  * `BIN params show P.json --json`: every value of `parameters` and `physical` to 1e-9
    (deg, cm); psi and tau modulo 360 deg, skipped where beta or mu is ~0.
Parameter sets are written both in the `parameters` form and, for some, the `physical` form.
Prints a report and `N passed, M failed`; exit status 1 on any failure.
"""

import csv
import io
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spec_reference as ref  # noqa: E402

SEED = 20240611
TOL_CM = 1e-9
TOL_SHOW = 1e-9
N_BULK = 300        # isotropic points per case
N_PLANE = 100       # points close to the parting plane x = 0 (gap / overlap region)
TIMEOUT = 120
WORKERS = 4         # invocations of the binary run side by side (each is mostly start-up)

results = []        # (name, ok, detail)


def check(name, ok, detail=""):
    results.append((name, bool(ok), detail))
    print("  [%s] %s%s" % ("PASS" if ok else "FAIL", name, ("  " + detail) if detail else ""))
    sys.stdout.flush()


# --- parameter sets --------------------------------------------------------------------
def build_cases(rng):
    """List of dicts: name, fit (native), form ('parameters' or 'physical'), file_values."""
    cases = []
    zero = {n: 0.0 for n in ref.FIT_NAMES}

    def add(name, fit, physical_too=False):
        cases.append({"name": name, "fit": dict(fit), "form": "parameters",
                      "values": ref.file_from_fit(fit)})
        if physical_too:
            phys_file = ref.physical_to_file(ref.physical_from_fit(fit))
            cases.append({"name": name + "[physical]",
                          "fit": ref.fit_from_physical(ref.physical_from_file(phys_file)),
                          "form": "physical", "values": phys_file})

    add("all_zero", zero, physical_too=True)

    # The contract's example file, verbatim (file units).
    spec_example = {"alpha": 3.0, "beta1": 0.0, "beta2": 0.0, "dx": 0.3, "dy": 0.0, "dz": 0.0,
                    "dp1": 0.4, "dp2": 0.4, "dp3": 0.4, "dy_rel": 0.0, "dz_rel": 0.0,
                    "beta_rel": 0.0}
    cases.append({"name": "spec_example", "fit": ref.fit_from_file(spec_example),
                  "form": "parameters", "values": spec_example})

    # beta1 = beta2 = 0 and all dp equal (mu = 0, psi and tau undefined), other params set.
    f = dict(zero)
    f.update({"alpha": 2.0 * ref.DEG, "dx": 0.25, "dy": -0.4, "dz": 0.6,
              "dp1": 0.35, "dp2": 0.35, "dp3": 0.35,
              "dy_rel": 0.15, "dz_rel": -0.2, "beta_rel": 0.5 * ref.DEG})
    add("beta0_dp_equal", f, physical_too=True)

    # Fully random sets: angles up to a few degrees, beta up to ~1 deg, shifts up to 1 cm,
    # dp_k in [-0.5, 1.0] cm.
    for i in range(8):
        add("random_%d" % (i + 1), ref.random_fit(rng), physical_too=(i < 3))

    # Small spread of dp around a comfortable gap: the layer-3 rule does not trigger.
    for i in range(2):
        f = ref.random_fit(rng)
        c = rng.uniform(0.5, 1.0)
        for k in (1, 2, 3):
            f["dp%d" % k] = c + rng.uniform(-0.05, 0.05)
        add("l3_rule_off_%d" % (i + 1), f, physical_too=(i == 0))

    # Large spread: the layer-3 rule triggers.
    for i in range(2):
        f = ref.random_fit(rng)
        f["dp1"], f["dp2"], f["dp3"] = rng.permutation([rng.uniform(0.8, 1.0),
                                                         rng.uniform(-0.5, -0.3),
                                                         rng.uniform(0.0, 0.3)])
        add("l3_rule_on_%d" % (i + 1), f)

    # All gaps negative (overlap; dx_rel < 0 so mu3 < 0), distinct dp so tau is defined.
    f = ref.random_fit(rng)
    f["dp1"], f["dp2"], f["dp3"] = rng.uniform(-0.5, -0.1, size=3)
    add("all_dp_negative", f)

    # Given directly in physical form (negative tau, psi in the second quadrant).
    phys_file = {"alpha": -2.5, "beta": 0.7, "psi": 130.0, "dx": 0.2, "dy": -0.3, "dz": 0.45,
                 "mu": 0.3, "tau": -135.0, "dx_rel": 0.25, "dy_rel": 0.1, "dz_rel": -0.05,
                 "beta_rel": -0.8}
    cases.append({"name": "physical_direct",
                  "fit": ref.fit_from_physical(ref.physical_from_file(phys_file)),
                  "form": "physical", "values": phys_file})
    return cases


def write_param_file(path, case):
    doc = {"format": "emcalign-alignment/1",
           "units": {"angle": "deg", "length": "cm"},
           case["form"]: {k: float(v) for k, v in case["values"].items()}}
    with open(path, "w") as fh:
        json.dump(doc, fh, indent=2)   # json writes floats with repr: round-trip exact
        fh.write("\n")


# --- points ------------------------------------------------------------------------------
def make_points(rng):
    pts = []
    for _ in range(N_BULK):
        r = rng.uniform(30.0, 70.0)
        cth = rng.uniform(-1.0, 1.0)
        phi = rng.uniform(0.0, 2.0 * math.pi)
        sth = math.sqrt(1.0 - cth * cth)
        pts.append([r * sth * math.cos(phi), r * sth * math.sin(phi), r * cth])
    for _ in range(N_PLANE):
        r = rng.uniform(30.0, 70.0)
        x = rng.uniform(-1.5, 1.5)
        a = rng.uniform(0.0, 2.0 * math.pi)
        rr = math.sqrt(r * r - x * x)
        pts.append([x, rr * math.cos(a), rr * math.sin(a)])
    # exact x = 0: the forward default must use s = +1
    pts.append([0.0, 45.0, 10.0])
    pts.append([0.0, -50.0, -5.0])
    return np.array(pts)


def points_csv(pts):
    out = io.StringIO()
    out.write("x_cm,y_cm,z_cm\n")
    for p in pts:
        out.write("%s,%s,%s\n" % (repr(float(p[0])), repr(float(p[1])), repr(float(p[2]))))
    return out.getvalue()


# --- running the binary ---------------------------------------------------------------------
def run(binary, args, stdin_text=None):
    try:
        cp = subprocess.run([binary] + args, input=stdin_text, capture_output=True,
                            text=True, timeout=TIMEOUT)
    except (OSError, subprocess.SubprocessError) as exc:
        return None, "could not run: %s" % exc
    if cp.returncode != 0:
        return None, "exit %d; stderr: %s" % (cp.returncode, cp.stderr.strip()[:400])
    return cp.stdout, cp.stderr


def parse_transform_output(text, n_expected):
    rows = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not rows:
        raise ValueError("empty output")
    header = [h.strip() for h in rows[0].split(",")]
    if header != ["x_cm", "y_cm", "z_cm", "hemisphere"]:
        raise ValueError("unexpected header %r" % rows[0])
    out = []
    for i, rec in enumerate(csv.reader(rows[1:])):
        if len(rec) != 4:
            raise ValueError("row %d has %d fields: %r" % (i + 1, len(rec), rec))
        hem = rec[3].strip()
        if hem in ("gap", "overlap"):
            h = hem
        else:
            h = int(float(hem))
        coords = [c.strip() for c in rec[:3]]
        if all(c == "" for c in coords):
            xyz = None
        else:
            xyz = np.array([float(c) for c in coords])
        out.append((xyz, h))
    if len(out) != n_expected:
        raise ValueError("%d rows for %d input points" % (len(out), n_expected))
    return out


def transform_args(pfile, inverse, hem, layer):
    """The command line of one invocation; hem in (None, +1, -1, 'auto'); layer in (None, 1, 3)."""
    args = ["transform", "--params", pfile]
    if inverse:
        args.append("--inverse")
    if hem is not None:
        args += ["--hemisphere", {1: "+1", -1: "-1", "auto": "auto"}[hem]]
    if layer is not None:
        args += ["--layer", str(layer)]
    return args


def check_transform(output, case, pts, inverse, hem, layer):
    """One invocation's `run` output (stdout, stderr) against the reference."""
    fit = case["fit"]
    ref_layer = 1 if layer is None else layer
    name = "%s: %s hem=%s layer=%s" % (case["name"], "inverse" if inverse else "forward",
                                       "default" if hem is None else
                                       {1: "+1", -1: "-1", "auto": "auto"}[hem],
                                       "default(1)" if layer is None else layer)
    stdout, err = output
    if stdout is None:
        check(name, False, err)
        return
    try:
        rows = parse_transform_output(stdout, len(pts))
    except ValueError as exc:
        check(name, False, "bad output: %s" % exc)
        return
    # The reference on all points at once (the same maps as ref.forward / ref.inverse /
    # ref.inverse_auto point by point); NaN rows where no coordinates are expected.
    if not inverse:
        exp_h = [ref.hemisphere_of(p) if hem is None else hem for p in pts]
        exp_xyz = ref.forward_many(pts, fit, np.array(exp_h), ref_layer)
    elif hem in (1, -1):
        exp_h = [hem] * len(pts)
        exp_xyz = ref.inverse_many(pts, fit, hem, ref_layer)
    else:
        exp_xyz, exp_h = ref.inverse_auto_many(pts, fit, ref_layer)
        ties = ref.auto_margin_many(pts, fit, ref_layer) < 1e-9
    worst, bad, n_gap, n_ovl, n_tie = 0.0, [], 0, 0, 0
    for i, (p, (xyz, h)) in enumerate(zip(pts, rows)):
        if inverse and hem not in (1, -1) and ties[i]:
            # decision within rounding of a tie: accept any consistent answer
            n_tie += 1
            exp_h[i] = h
            exp_xyz[i] = ref.inverse(p, fit, h, ref_layer) if h in (1, -1) else np.nan
        if exp_h[i] == "gap":
            n_gap += 1
        elif exp_h[i] == "overlap":
            n_ovl += 1
        if h != exp_h[i]:
            bad.append("pt %d: hemisphere %r, expected %r" % (i, h, exp_h[i]))
            continue
        if h not in (1, -1):
            if xyz is not None:
                bad.append("pt %d: %s with coordinates %r" % (i, h, xyz))
            continue
        if xyz is None:
            bad.append("pt %d: empty coordinates" % i)
            continue
    # Coordinates of the rows whose hemisphere matched and that have some, all at once.
    have = [i for i, (xyz, h) in enumerate(rows)
            if xyz is not None and h in (1, -1) and h == exp_h[i]]
    if have:
        got = np.array([rows[i][0] for i in have])
        dev = np.max(np.abs(got - exp_xyz[have]), axis=1)
        worst = float(np.max(dev))
        for k in np.flatnonzero(~(dev <= TOL_CM)):
            i = have[k]
            p = pts[i]
            bad.append("pt %d (%.6g,%.6g,%.6g): got %r expected %r (dev %.3g cm)"
                       % (i, p[0], p[1], p[2], list(got[k]), list(exp_xyz[i]), dev[k]))
    detail = "%d pts, max dev %.2e cm" % (len(pts), worst)
    if inverse and hem not in (1, -1):
        detail += ", %d gap, %d overlap%s" % (n_gap, n_ovl,
                                             (", %d near-tie" % n_tie) if n_tie else "")
    if bad:
        detail += "; %d bad, e.g. %s" % (len(bad), " | ".join(bad[:3]))
    check(name, not bad, detail)


def angle_diff_deg(a, b):
    return abs((a - b + 180.0) % 360.0 - 180.0)


def check_show(output, case):
    """`params show --json`'s `run` output (stdout, stderr) against the reference."""
    name = "%s: params show" % case["name"]
    stdout, err = output
    if stdout is None:
        check(name, False, err)
        return
    try:
        doc = json.loads(stdout)
    except ValueError as exc:
        check(name, False, "output is not JSON: %s" % exc)
        return
    fit = case["fit"]
    exp_par = ref.file_from_fit(fit)
    phys = ref.physical_from_fit(fit)
    exp_phy = ref.physical_to_file(phys)
    skip = set()
    if phys["beta"] < 1e-6:
        skip.add("psi")
    if phys["mu"] < 1e-6:
        skip.add("tau")
    for section, expected, names in (("parameters", exp_par, ref.FIT_NAMES),
                                     ("physical", exp_phy, ref.PHYS_NAMES)):
        got = doc.get(section)
        if not isinstance(got, dict):
            check("%s.%s" % (name, section), False, "missing section %r" % section)
            continue
        bad, worst = [], 0.0
        for n in names:
            if n not in got:
                bad.append("%s missing" % n)
                continue
            if section == "physical" and n in skip:
                continue
            try:
                v = float(got[n])
            except (TypeError, ValueError):
                bad.append("%s = %r not a number" % (n, got[n]))
                continue
            if section == "physical" and n in ("psi", "tau"):
                d = angle_diff_deg(v, expected[n])
            else:
                d = abs(v - expected[n])
            worst = max(worst, d)
            if not d <= TOL_SHOW:
                bad.append("%s = %r, expected %r" % (n, v, expected[n]))
        extra = sorted(set(got) - set(names))
        detail = "max dev %.2e" % worst
        if section == "physical" and skip:
            detail += " (skipped %s: undefined)" % ",".join(sorted(skip))
        if extra:
            detail += " (extra keys %s)" % extra
        if bad:
            detail += "; " + "; ".join(bad[:6])
        check("%s.%s" % (name, section), not bad, detail)


# --- main ------------------------------------------------------------------------------------
def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    binary = os.path.abspath(argv[1])
    keep = "--keep-temp" in argv[2:]

    print("== reference self-consistency checks (spec_reference.py)")
    for n, ok, d in ref.self_test(verbose=False):
        check("reference: " + n, ok, d)

    rng = np.random.default_rng(SEED)
    cases = build_cases(rng)
    pts = make_points(rng)
    pts_csv = points_csv(pts)

    tmp = tempfile.mkdtemp(prefix="emcalign-crosscheck-")
    print("== parameter sets (files in %s)" % tmp)
    n_on = n_off = 0
    for i, case in enumerate(cases):
        case["file"] = os.path.join(tmp, "p%02d_%s.json" % (i, case["name"].replace("[", "_")
                                                             .replace("]", "")))
        write_param_file(case["file"], case)
        on = ref.layer3_rule_active(case["fit"])
        n_on += on
        n_off += not on
        ph = ref.physical_from_fit(case["fit"])
        print("  %-28s form=%-10s layer-3 rule %-3s  mu=%.4f deg tau=%.1f deg dx_rel=%.4f cm"
              % (case["name"], case["form"], "ON" if on else "off",
                 ph["mu"] / ref.DEG, ph["tau"] / ref.DEG, ph["dx_rel"]))
    check("test sets include layer-3 rule on and off", n_on >= 2 and n_off >= 2,
          "(%d on, %d off)" % (n_on, n_off))
    with open(os.path.join(tmp, "points.csv"), "w") as fh:
        fh.write(pts_csv)

    try:
        print("== command-line tool: %s" % binary)
        if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
            check("binary present and executable", False, binary)
        else:
            # (inverse, hem, layer) of every transform invocation of a case.
            modes = []
            for layer in (1, 3):
                modes += [(False, hem, layer) for hem in (None, 1, -1)]
                modes += [(True, hem, layer) for hem in (None, 1, -1, "auto")]
            modes += [(False, None, None), (True, "auto", None)]
            # Every invocation is started at once (WORKERS at a time); the checks take
            # their outputs in order.
            with ThreadPoolExecutor(max_workers=WORKERS) as pool:
                outputs = [(pool.submit(run, binary, ["params", "show", case["file"], "--json"]),
                            [pool.submit(run, binary, transform_args(case["file"], *m), pts_csv)
                             for m in modes])
                           for case in cases]
                for case, (show, transforms) in zip(cases, outputs):
                    print("-- %s" % case["name"])
                    check_show(show.result(), case)
                    for m, out in zip(modes, transforms):
                        check_transform(out.result(), case, pts, *m)
    finally:
        if keep:
            print("temp files kept in %s" % tmp)
        else:
            shutil.rmtree(tmp, ignore_errors=True)

    n_fail = sum(1 for _, ok, _ in results if not ok)
    if n_fail:
        print("== failures:")
        for n, ok, d in results:
            if not ok:
                print("  %s  %s" % (n, d[:300]))
    print("%d passed, %d failed" % (len(results) - n_fail, n_fail))
    return 1 if n_fail else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

#!/usr/bin/python3
"""Independent Minuit cross-check of emcalign's alignment fit (docs/contract.md §4, §5, §7, §8).

Everything here is written from docs/contract.md alone, in numpy, without looking at the
C++ fit: the model f_phi, f_theta (docs/contract.md §4-§5, the transform built literally as
R_z(psi) R_y(beta) R_z(alpha - psi) etc. with atan2/asin), the chi2 of docs/contract.md §8, the staged
MIGRAD minimisation and HESSE errors (iminuit), and optionally (--events) the docs/contract.md §7
selection and profile filling from an event CSV.

Usage
    /usr/bin/python3 bench/minuit_crosscheck.py PROFILE.csv RESULT.json
    /usr/bin/python3 bench/minuit_crosscheck.py --events EVENTS.csv PROFILE.csv RESULT.json

PROFILE.csv is `emcalign fit ... --profile-out PROFILE.csv`'s profile, RESULT.json is
`emcalign fit --profile-in PROFILE.csv -o RESULT.json`'s result. With --events the
profile is rebuilt from EVENTS.csv, compared bin by bin with PROFILE.csv, and the
re-built profile is the one fitted.

Checks (exit status 1 if any fails):
  * (--events) n equal in every bin; means/sigmas equal to 1e-9 relative;
  * chi2 of this model at emcalign's parameters equal to emcalign's chi2 (1e-6 relative);
  * ndf = 2 * bins used - 12 equal;
  * chi2 minimum: relative difference <= 1e-6;
  * every parameter: |delta| <= 1e-3 * its error (emcalign's), in file units;
  * every error: relative difference <= 2 %;
  * Minuit's minimum valid, HESSE's covariance accurate.
It also times MIGRAD+HESSE over the six stages (wall time) and the whole
`emcalign fit --profile-in` process (several runs) and prints the ratio.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from iminuit import Minuit

# ---------------------------------------------------------------- constants (docs/contract.md §2-§3, §5, §7)
NAMES = ["alpha", "beta1", "beta2", "dx", "dy", "dz",
         "dp1", "dp2", "dp3", "dy_rel", "dz_rel", "beta_rel"]
UNITS = {"alpha": "deg", "beta1": "deg", "beta2": "deg", "beta_rel": "deg"}
DEG = math.pi / 180.0
# file unit -> internal unit (rad, dimensionless sin-vector components, cm)
TO_INTERNAL = np.array([DEG if n in UNITS else 1.0 for n in NAMES])

R0, X0, EC, XPRE = 32.8, 2.56, 13.16, 0.13   # cm, cm, MeV, in X0
R1 = 53.7                                     # cm, outer radius of support sphere 1
SIGMA_SYS = 0.2 * DEG                         # rad, for both y_phi and y_theta
MIN_N = 10                                    # bins with n < 10 are left out of chi2
N_PHI, N_THETA = 16, 10
THETA_LO, THETA_HI = 45.0 * DEG, 135.0 * DEG

STAGES = [["alpha"], ["dx", "dy"], ["dz", "beta1", "beta2"], ["dp1", "dp2", "dp3"],
          ["dy_rel", "dz_rel"], ["beta_rel"]]

# tolerances of the comparison (from the brief)
TOL_PROFILE = 1e-9      # relative, profile means and sigmas
TOL_CHI2 = 1e-6         # relative, chi2 minimum
TOL_PAR = 1e-3          # |delta| in units of the parameter's error
TOL_ERR = 0.02          # relative, errors

PROFILE_COLUMNS = ["i_phi", "i_theta", "n", "phi_mean_rad", "theta_mean_rad", "e_mean_mev",
                   "y_phi", "sigma_phi", "y_theta", "sigma_theta"]
EVENT_COLUMNS = ["run", "event", "beam_energy_mev", "muon_veto", "charged", "z0_cm", "rho_cm",
                 "phi_ts_rad", "theta_ts_rad", "energy_mev", "phi_emc_rad", "theta_emc_rad"]


# ---------------------------------------------------------------- model (docs/contract.md §1, §4, §5)
def shower_radius(e_mev, theta):
    """R(E, theta) = R0 + X0 (ln(E/Ec) - 0.5 - x_pre / sin theta)."""
    return R0 + X0 * (np.log(e_mev / EC) - 0.5 - XPRE / np.sin(theta))


def rot(axis, angle):
    """Active right-handed rotation R_a(g) p = p cos g + (a x p) sin g + a (a.p)(1 - cos g)."""
    a = np.asarray(axis, dtype=float)
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return c * np.eye(3) + s * k + (1.0 - c) * np.outer(a, a)


EX, EY, EZ = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def hemisphere_maps(eta):
    """eta in internal units -> {s: (R_s, t_s)} with p1 = R_s p0 + t_s (docs/contract.md §4 forward)."""
    alpha, b1, b2, dx, dy, dz, dp1, dp2, dp3, dy_rel, dz_rel, beta_rel = eta
    beta = math.asin(math.sqrt(b1 * b1 + b2 * b2))
    psi = math.atan2(b2, b1)
    t_zyz = rot(EZ, psi) @ rot(EY, beta) @ rot(EZ, alpha - psi)
    dx_rel = (dp1 + dp2 + dp3) / 6.0
    u = dp1 - 2.0 * dx_rel
    t = (dp3 - dp2) / (2.0 * math.sqrt(3.0))
    tau = math.atan2(2.0 * t, u)
    mu = math.asin(math.sqrt(4.0 * t * t + u * u) / (2.0 * R1))
    n = (0.0, -math.sin(tau), math.cos(tau))
    xi = np.array([dx, dy, dz])
    maps = {}
    for s in (+1, -1):
        t_mu = rot(n, -s * mu)
        t_brel = rot(EX, s * beta_rel)
        xi_rel = s * np.array([dx_rel, dy_rel, dz_rel])
        maps[s] = (t_zyz @ t_mu @ t_brel, t_zyz @ xi_rel + xi)
    return maps


class Model:
    """f_phi, f_theta at the bins' means (phi0, theta0, E)."""

    def __init__(self, phi0, theta0, e):
        self.phi0 = phi0
        self.theta0 = theta0
        r = shower_radius(e, theta0)
        if np.any(r >= R1):
            # the model points are always in layers 1-2 for E ~ E_beam; the layer-3 rule
            # of docs/contract.md §4 would apply beyond R1 and is not implemented here
            raise SystemExit("model point beyond R1: the layer-3 rule is not implemented")
        self.p0 = r[:, None] * np.column_stack((np.sin(theta0) * np.cos(phi0),
                                                np.sin(theta0) * np.sin(phi0),
                                                np.cos(theta0)))
        s = np.where(np.cos(phi0) >= 0.0, 1, -1)     # sign(cos phi0), +1 at 0
        self.sel = {+1: s == 1, -1: s == -1}

    def __call__(self, eta):
        maps = hemisphere_maps(eta)
        p1 = np.empty_like(self.p0)
        for s, (r_s, t_s) in maps.items():
            m = self.sel[s]
            p1[m] = self.p0[m] @ r_s.T + t_s
        phi1 = np.arctan2(p1[:, 1], p1[:, 0])
        theta1 = np.arctan2(np.hypot(p1[:, 0], p1[:, 1]), p1[:, 2])   # = arccos(z/|p|)
        return np.sin(phi1 - self.phi0), theta1 - self.theta0


class Chi2:
    """chi2(eta in file units) of docs/contract.md §8 over the bins with n >= 10."""

    errordef = Minuit.LEAST_SQUARES

    def __init__(self, prof):
        use = prof["n"] >= MIN_N
        self.used = int(use.sum())
        self.model = Model(prof["phi_mean_rad"][use], prof["theta_mean_rad"][use],
                           prof["e_mean_mev"][use])
        self.y_phi, self.s_phi = prof["y_phi"][use], prof["sigma_phi"][use]
        self.y_theta, self.s_theta = prof["y_theta"][use], prof["sigma_theta"][use]
        self.ncall = 0

    def residuals(self, x_file):
        f_phi, f_theta = self.model(np.asarray(x_file, dtype=float) * TO_INTERNAL)
        return np.concatenate(((self.y_phi - f_phi) / self.s_phi,
                               (self.y_theta - f_theta) / self.s_theta))

    def __call__(self, x_file):
        self.ncall += 1
        r = self.residuals(x_file)
        return float(r @ r)


# ---------------------------------------------------------------- profile I/O
def read_profile(path):
    with open(path) as f:
        lines = [ln.rstrip("\n") for ln in f if ln.strip() and not ln.startswith("#")]
    header = lines[0].split(",")
    if header != PROFILE_COLUMNS:
        raise SystemExit(f"{path}: unexpected header {header}")
    rows = [ln.split(",") for ln in lines[1:]]
    cols = {}
    for j, name in enumerate(header):
        vals = [r[j] for r in rows]
        if name in ("i_phi", "i_theta", "n"):
            cols[name] = np.array([int(v) for v in vals])
        else:
            cols[name] = np.array([float(v) if v != "" else np.nan for v in vals])
    return cols


# ---------------------------------------------------------------- selection and profile (docs/contract.md §5, §7)
def read_events(path):
    with open(path) as f:
        lines = [ln for ln in f if not ln.startswith("#")]
    header = lines[0].strip().split(",")
    missing = [c for c in EVENT_COLUMNS if c not in header]
    if missing:
        raise SystemExit(f"{path}: missing columns {missing}")
    data = np.genfromtxt(lines[1:], delimiter=",", dtype=float)   # empty fields -> NaN
    data = np.atleast_2d(data)
    return {c: data[:, header.index(c)] for c in EVENT_COLUMNS}


def select_and_fill(ev):
    """docs/contract.md §7 selection of e+e- -> e+e- and the 16 x 10 profile; returns (profile, counts)."""
    run, event = ev["run"], ev["event"]
    nrow = len(run)
    start = np.ones(nrow, dtype=bool)
    start[1:] = (run[1:] != run[:-1]) | (event[1:] != event[:-1])
    first = np.flatnonzero(start)                       # first row of each event
    nrows = np.diff(np.append(first, nrow))
    counts = {"events read": len(first)}

    def per_event(mask_rows, how):
        v = np.add.reduceat(mask_rows.astype(int), first)
        return v == nrows if how == "all" else v

    veto_ok = per_event(ev["muon_veto"] == 0, "all")
    n_charged = per_event(ev["charged"] == 1, "sum")
    n_photon = per_event(ev["charged"] == 0, "sum")
    ok = veto_ok
    counts["no muon veto"] = int(ok.sum())
    ok = ok & (n_charged == 2) & (n_photon == 0) & (nrows == 2)
    counts["2 charged, 0 photons"] = int(ok.sum())

    i1 = first[ok]
    i2 = i1 + 1

    def both(cond):
        return cond[i1] & cond[i2]

    trk = (np.abs(ev["z0_cm"]) < 10.0) & (np.abs(ev["rho_cm"]) < 1.0)
    keep = both(trk)
    counts["track |z0|, |rho|"] = int(keep.sum())
    eb = ev["beam_energy_mev"]
    ecut = (ev["energy_mev"] > 0.8 * eb) & (ev["energy_mev"] < 1.1 * eb)
    keep &= both(ecut)
    counts["cluster energies"] = int(keep.sum())
    dphi_deg = np.abs(ev["phi_ts_rad"][i1] * (180.0 / math.pi) - ev["phi_ts_rad"][i2] * (180.0 / math.pi))
    keep &= np.abs(180.0 - dphi_deg) < 10.0
    counts["acollinearity"] = int(keep.sum())

    rows = np.concatenate((i1[keep], i2[keep]))
    rows.sort()
    z0, rho = ev["z0_cm"][rows], ev["rho_cm"][rows]
    phi, theta = ev["phi_ts_rad"][rows], ev["theta_ts_rad"][rows]
    e = ev["energy_mev"][rows]
    phi_emc, theta_emc = ev["phi_emc_rad"][rows], ev["theta_emc_rad"][rows]

    # outward intersection of the track line with the sphere R(E_cluster, theta_ts)
    c = np.column_stack((-rho * np.sin(phi), rho * np.cos(phi), z0))
    d = np.column_stack((np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)))
    r = shower_radius(e, theta)
    cd = np.einsum("ij,ij->i", c, d)
    disc = cd * cd - np.einsum("ij,ij->i", c, c) + r * r
    hit = disc >= 0.0
    counts["particles selected"] = len(rows)
    counts["tracks missing the sphere"] = int((~hit).sum())
    tpar = -cd + np.sqrt(np.where(hit, disc, 0.0))
    p_r = c + tpar[:, None] * d
    phi_r = np.arctan2(p_r[:, 1], p_r[:, 0])
    theta_r = np.arctan2(np.hypot(p_r[:, 0], p_r[:, 1]), p_r[:, 2])
    y_phi = np.sin(phi_r - phi_emc)
    y_theta = theta_r - theta_emc

    # profile: 16 bins in phi_emc over [0, 360) deg, 10 in theta_emc over [45, 135) deg
    i_phi = np.floor(phi_emc / (2.0 * math.pi / N_PHI)).astype(int)
    i_theta = np.floor((theta_emc - THETA_LO) / ((THETA_HI - THETA_LO) / N_THETA)).astype(int)
    inside = hit & (theta_emc >= THETA_LO) & (theta_emc < THETA_HI) & (i_phi >= 0) & (i_phi < N_PHI)
    i_phi = np.clip(i_phi, 0, N_PHI - 1)
    i_theta = np.clip(i_theta, 0, N_THETA - 1)
    counts["particles in the profiles"] = int(inside.sum())
    b = (i_phi * N_THETA + i_theta)[inside]
    nb = N_PHI * N_THETA
    n = np.bincount(b, minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        def mean(x):
            return np.bincount(b, weights=x[inside], minlength=nb) / n

        def sig(x, xm):
            dev = x[inside] - xm[b]
            var = np.bincount(b, weights=dev * dev, minlength=nb) / (n - 1)   # sample variance
            s_stat = np.sqrt(var) / np.sqrt(n)
            return np.sqrt(s_stat * s_stat + SIGMA_SYS * SIGMA_SYS)

        prof = {"i_phi": np.repeat(np.arange(N_PHI), N_THETA),
                "i_theta": np.tile(np.arange(N_THETA), N_PHI), "n": n,
                "phi_mean_rad": mean(phi_emc), "theta_mean_rad": mean(theta_emc),
                "e_mean_mev": mean(e)}
        prof["y_phi"] = mean(y_phi)
        prof["sigma_phi"] = sig(y_phi, prof["y_phi"])
        prof["y_theta"] = mean(y_theta)
        prof["sigma_theta"] = sig(y_theta, prof["y_theta"])
    return prof, counts


def compare_profiles(mine, theirs):
    """Bin by bin: n exactly, means and sigmas to 1e-9 relative. Returns (ok, worst, lines)."""
    lines = []
    ok = True
    key = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(theirs["i_phi"], theirs["i_theta"]))}
    if len(key) != N_PHI * N_THETA:
        return False, {}, [f"emcalign profile has {len(key)} distinct bins, expected 160"]
    order = np.array([key[(int(a), int(b))] for a, b in zip(mine["i_phi"], mine["i_theta"])])
    th = {c: v[order] for c, v in theirs.items()}
    bad_n = np.flatnonzero(mine["n"] != th["n"])
    if len(bad_n):
        ok = False
        for k in bad_n[:10]:
            lines.append(f"  bin ({mine['i_phi'][k]},{mine['i_theta'][k]}): n {mine['n'][k]} here, "
                         f"{th['n'][k]} in emcalign")
    worst = {}
    for c in PROFILE_COLUMNS[3:]:
        need = mine["n"] >= (2 if c.startswith("sigma") else 1)
        a, b = mine[c][need], th[c][need]
        scale = np.maximum(np.abs(a), np.abs(b))
        rel = np.abs(a - b) / np.where(scale > 0, scale, 1.0)
        rel = np.where(np.isfinite(rel), rel, np.inf)
        worst[c] = float(rel.max()) if len(rel) else 0.0
        if worst[c] > TOL_PROFILE:
            ok = False
            k = int(np.argmax(rel))
            kb = int(np.flatnonzero(need)[k])
            lines.append(f"  {c}: worst relative difference {worst[c]:.3g} in bin "
                         f"({mine['i_phi'][kb]},{mine['i_theta'][kb]}) "
                         f"({a[k]!r} here, {b[k]!r} in emcalign); "
                         f"{int((rel > TOL_PROFILE).sum())} bin(s) off")
    return ok, worst, lines


# ---------------------------------------------------------------- fitting
def staged_fit(chi2):
    m = Minuit(chi2, np.zeros(len(NAMES)), name=NAMES)
    m.errordef = Minuit.LEAST_SQUARES
    m.errors = [0.05] * len(NAMES)     # first steps: 0.05 deg or 0.05 cm
    m.tol = 1e-5                       # EDM < 2e-8: the minimum to far below 1e-6 in chi2
    m.strategy = 1
    for n in NAMES:
        m.fixed[n] = True
    stages = []
    free = []
    t0 = time.perf_counter()
    for k, st in enumerate(STAGES, start=1):
        for n in st:
            m.fixed[n] = False
            free.append(n)
        m.migrad(ncall=100000)
        stages.append({"stage": k, "free": list(free), "chi2": m.fval, "nfcn": m.nfcn,
                       "valid": m.valid, "edm": m.fmin.edm})
    t_migrad = time.perf_counter() - t0
    m.hesse()
    t_total = time.perf_counter() - t0
    return m, stages, t_migrad, t_total


def whitened_jacobian(chi2, x):
    """d(whitened residuals)/d(parameters) at x, by central differences."""
    h = 1e-5
    cols = []
    for j in range(len(x)):
        xp, xm = np.array(x, float), np.array(x, float)
        xp[j] += h
        xm[j] -= h
        cols.append((chi2.residuals(xp) - chi2.residuals(xm)) / (2 * h))
    return np.column_stack(cols)


def gauss_newton_cov(chi2, x):
    """(J^T J)^-1 of the whitened residuals (docs/contract.md §8 definition)."""
    jac = whitened_jacobian(chi2, x)
    return np.linalg.inv(jac.T @ jac)


def time_in_process(bench, profile):
    """Median wall time (s) of the staged fit of `profile` inside emcalign_bench_fit."""
    p = subprocess.run([bench, "--profile", profile, "--benchmark_filter=OfProfile",
                        "--benchmark_format=json", "--benchmark_repetitions=5",
                        "--benchmark_report_aggregates_only=true"],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{bench} failed: {p.stderr.strip()}")
    for b in json.loads(p.stdout)["benchmarks"]:
        if b.get("aggregate_name") == "median":
            scale = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
            return b["real_time"] * scale
    raise RuntimeError(f"{bench}: no median in its output")


def time_emcalign(exe, profile, runs):
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "r.json")
        for _ in range(runs):
            t0 = time.perf_counter()
            p = subprocess.run([exe, "fit", "--profile-in", profile, "-o", out],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            times.append(time.perf_counter() - t0)
            if p.returncode != 0:
                raise RuntimeError(f"emcalign fit --profile-in failed: {p.stderr.strip()}")
    return times


# ---------------------------------------------------------------- main
def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("profile", help="emcalign's --profile-out CSV")
    ap.add_argument("result", help="emcalign fit --profile-in PROFILE -o RESULT.json")
    ap.add_argument("--events", help="event CSV: re-do the selection and profile here and compare")
    ap.add_argument("--emcalign", default=os.path.join(here, "..", "build", "bin", "emcalign"),
                    help="emcalign executable to time (default: ../build/bin/emcalign)")
    ap.add_argument("--timing-runs", type=int, default=5, help="emcalign runs to time (default 5)")
    ap.add_argument("--bench-fit", default=os.path.join(here, "..", "build", "bin", "emcalign_bench_fit"),
                    help="the fit benchmark, for the in-process time (default: ../build/bin/emcalign_bench_fit)")
    args = ap.parse_args()

    failures = []

    def check(ok, what):
        print(f"  [{'ok' if ok else 'FAIL'}] {what}")
        if not ok:
            failures.append(what)

    print(f"Minuit cross-check of emcalign (iminuit {__import__('iminuit').__version__}, "
          f"numpy {np.__version__})")
    print(f"profile: {args.profile}\nresult:  {args.result}")
    theirs = read_profile(args.profile)
    res = json.load(open(args.result))

    prof = theirs
    if args.events:
        print(f"\n== Selection and profile from {args.events} (docs/contract.md §7) ==")
        t0 = time.perf_counter()
        prof, counts = select_and_fill(read_events(args.events))
        print(f"  ({time.perf_counter() - t0:.2f} s)")
        for k, v in counts.items():
            print(f"  {k:30s} {v:8d}")
        ok, worst, lines = compare_profiles(prof, theirs)
        for ln in lines:
            print(ln)
        print("  worst relative difference per column: "
              + ", ".join(f"{c} {w:.2g}" for c, w in worst.items()))
        check(ok, f"profile equals emcalign's bin by bin (n exact, means/sigmas to {TOL_PROFILE:g})")

    chi2 = Chi2(prof)
    ndf = 2 * chi2.used - len(NAMES)
    print(f"\n== Model check: chi2 at emcalign's parameters ==")
    x_em = np.array([res["parameters"][n] for n in NAMES], dtype=float)
    chi2_at_em = chi2(x_em)
    rel = abs(chi2_at_em - res["chi2"]) / abs(res["chi2"])
    print(f"  chi2 here {chi2_at_em:.12g}, emcalign {res['chi2']:.12g}, relative {rel:.2g}")
    check(rel <= TOL_CHI2, f"chi2 of this model at emcalign's minimum equals emcalign's (<= {TOL_CHI2:g})")
    print(f"  bins used {chi2.used}, ndf {ndf} (emcalign {res.get('ndf')})")
    check(ndf == res.get("ndf"), "ndf = 2 * bins used - 12 equal")

    print(f"\n== Staged MIGRAD (docs/contract.md §8) + HESSE ==")
    chi2.ncall = 0
    m, stages, t_migrad, t_total = staged_fit(chi2)
    em_stages = {s["stage"]: s for s in res.get("stages", [])}
    print("  stage  chi2 (Minuit)       chi2 (emcalign)     rel. diff  nfcn  valid  free")
    for s in stages:
        e = em_stages.get(s["stage"], {}).get("chi2", float("nan"))
        print(f"  {s['stage']:5d}  {s['chi2']:<18.12g}  {e:<18.12g}  {abs(s['chi2'] - e) / abs(e):9.2g}"
              f"  {s['nfcn']:4d}  {str(s['valid']):5s}  +{','.join(STAGES[s['stage'] - 1])}")
    check(all(s["valid"] for s in stages), "MIGRAD minimum valid in every stage")
    check(m.accurate and not m.fmin.hesse_failed, "HESSE covariance accurate")
    x_mn = np.array(m.values)
    e_mn = np.array(m.errors)
    e_em = np.array([res["errors"][n] for n in NAMES], dtype=float)

    rel_chi2 = abs(m.fval - res["chi2"]) / abs(res["chi2"])
    print(f"\n== Comparison (file units: deg, cm; beta1/beta2 x 180/pi) ==")
    print(f"  chi2 minimum: Minuit {m.fval:.12g}, emcalign {res['chi2']:.12g}, "
          f"difference {m.fval - res['chi2']:.3g} (relative {rel_chi2:.2g})")
    gn = gauss_newton_cov(chi2, x_mn)
    e_gn = np.sqrt(np.diag(gn))
    print("  parameter    emcalign            Minuit              delta/err   "
          "err emcalign  err Minuit  rel.diff  err (J^T J)^-1 here")
    dpar = np.abs(x_mn - x_em) / e_em
    derr = np.abs(e_mn - e_em) / e_em
    for k, n in enumerate(NAMES):
        print(f"  {n:10s} {x_em[k]:+.12f}  {x_mn[k]:+.12f}  {dpar[k]:9.2e}   {e_em[k]:.6f}"
              f"      {e_mn[k]:.6f}    {derr[k]:8.3%}   {e_gn[k]:.6f} ({(e_gn[k] - e_em[k]) / e_em[k]:+.2e})")
    kp, ke = int(np.argmax(dpar)), int(np.argmax(derr))
    print(f"  worst parameter difference: {dpar[kp]:.2e} x its error ({NAMES[kp]})")
    print(f"  worst error difference:     {derr[ke]:.3%} ({NAMES[ke]})")
    if "covariance" in res:
        cov_em = np.array(res["covariance"], dtype=float)
        cov_mn = np.array(m.covariance)
        d = np.sqrt(np.outer(e_em, e_em))
        print(f"  worst correlation difference (HESSE vs emcalign): "
              f"{np.abs(cov_mn / d - cov_em / d).max():.2e};  "
              f"worst (J^T J)^-1 vs emcalign covariance (relative to sigma_i sigma_j): "
              f"{np.abs((gn - cov_em) / d).max():.2e}")
    check(rel_chi2 <= TOL_CHI2, f"chi2 minimum agrees (relative {rel_chi2:.2g} <= {TOL_CHI2:g})")
    check(dpar.max() <= TOL_PAR, f"every parameter agrees (worst {dpar.max():.2e} <= {TOL_PAR:g} x error)")
    check(derr.max() <= TOL_ERR, f"every error agrees (worst {derr.max():.3%} <= {TOL_ERR:.0%})")

    print(f"\n== Timing (wall) ==")
    print(f"  Minuit: MIGRAD over 6 stages {t_migrad * 1e3:.1f} ms + HESSE = {t_total * 1e3:.1f} ms, "
          f"{chi2.ncall} chi2 calls")
    try:
        times = time_emcalign(os.path.abspath(args.emcalign), args.profile, args.timing_runs)
        med = float(np.median(times))
        print(f"  emcalign fit --profile-in (whole process, {len(times)} runs): median {med * 1e3:.1f} ms, "
              f"min {min(times) * 1e3:.1f} ms")
        print(f"  ratio Minuit / emcalign = {t_total / med:.2f} (emcalign is {t_total / med:.1f}x faster)"
              if t_total >= med else
              f"  ratio Minuit / emcalign = {t_total / med:.2f} (Minuit is {med / t_total:.1f}x faster)")
    except (OSError, RuntimeError) as exc:
        check(False, f"timing emcalign: {exc}")
    try:
        inner = time_in_process(os.path.abspath(args.bench_fit), args.profile)
        print(f"  emcalign's staged fit in process (emcalign_bench_fit --profile, median of 5): "
              f"{inner * 1e3:.2f} ms")
        print(f"  ratio Minuit / emcalign in process = {t_total / inner:.0f}")
    except (OSError, RuntimeError, ValueError, KeyError) as exc:
        check(False, f"timing the fit in process: {exc}")

    print()
    if failures:
        print(f"FAILED: {len(failures)} check(s):")
        for f in failures:
            print(f"  - {f}")
        return 1
    print("PASSED: emcalign's fit agrees with the independent Minuit fit")
    return 0


if __name__ == "__main__":
    sys.exit(main())

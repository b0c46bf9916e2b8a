#!/usr/bin/python3
"""Independent generator of e+e- -> e+e- events in the docs/contract.md §6 CSV format.

Written from docs/contract.md alone (no C++ code of emcalign was read), on top of
the independent docs/contract.md §3-§5 reference `spec_reference.py` (alignment transform, its
exact inverse, shower depth, track/sphere intersection). Plain numpy, seeded.

Usage
    /usr/bin/python3 spec_events.py --events N --seed S --truth OUT.json -o OUT.csv
                                    [--params IN.json] [--reject-fraction F]
                                    [--gap-policy {track-only,drop-event}]
                                    [--shower-sphere {ts,emc}]

The model (native units cm, MeV, rad):
  * vertex: x, y ~ N(0, 0.03 cm), z ~ N(0, 1 cm);
  * e-: cos(theta) uniform for theta in [40, 140] deg, phi uniform; e+ back to back;
  * energies: each cluster E = E_beam (612.5 MeV) x (1 + 0.04 N(0, 1));
  * tracks: the true straight line from the vertex, its direction smeared by
    N(0, 0.25 deg) in theta and in phi; reported as (z0, rho, phi_ts, theta_ts) of the
    smeared line with docs/contract.md §5's convention: closest approach to the Z axis
    (-rho sin(phi), rho cos(phi), z0);
  * EMC cluster: p1 = the outward intersection of the *true* line with the sphere
    |p| = R(E, theta_true) (docs/contract.md §5 p_R of the true track) is the actual shower position
    in the TS frame. Its nominal position p0 is the docs/contract.md §4 exact inverse (layers 1-2:
    R(E, theta) < R1 always here) in the hemisphere chosen by the inverse's `auto` rule
    (the s whose pre-image lies on its own side). A particle whose p1 falls in the gap
    between the hemispheres (neither pre-image qualifies) or in an overlap (both do)
    has no cluster: by default its track row is written with empty cluster fields
    (docs/contract.md §6), so the event fails the docs/contract.md §7 selection (`--gap-policy drop-event`
    leaves such events out instead).
    `--shower-sphere emc` puts the shower instead at depth R(E, theta_true) from the
    centre of the *actual* hemisphere, i.e. |p0| = R exactly: docs/contract.md §5's model
    (p0 = R(E, theta0)(...), p1 = forward(p0)) taken literally. The default (`ts`, the
    sphere around the TS origin) differs from it at second order, ~|xi|^2/R^2 ~ 1e-4 rad
    for 0.5-0.7 cm shifts, which is ~2 statistical errors of alpha, dy_rel, dz_rel on
    30 000 events (but ~0.3 of the errors the fit quotes, sigma_sys dominating them).
  * (phi_emc, theta_emc) = the angles of p0, smeared by N(0, 0.5 deg) each.
    Subtlety: docs/contract.md §5's model takes the hemisphere as sign(cos phi_emc) of the
    *reconstructed* phi. A cluster is made of counters of one hemisphere, so its
    reconstructed phi stays on that hemisphere's side of x = 0: the phi smearing is a
    Gaussian truncated at the parting plane (draws that would move phi_emc across
    phi = 90 or 270 deg, i.e. change the sign of cos(phi_emc) relative to the
    hemisphere s, are re-drawn). theta smearing never crosses anything (theta is in
    40-140 deg). So the hemisphere of the model is always the hemisphere the cluster
    was made in. (The price: within ~1 sigma = 0.5 deg of the parting plane the phi
    smearing is not centred; it shifts the mean residual of the bins next to
    phi = 90/270 deg by ~0.005 deg, negligible against sigma_sys = 0.2 deg. A plain
    Gaussian would instead put ~1 % of those bins' clusters on the wrong side, whose
    residuals carry the other hemisphere's relative terms: a bias of the gaps dp_k.)

Events to be rejected by docs/contract.md §7 (a fraction --reject-fraction, default 3 %, split
evenly, each an otherwise normal e+e- event):
  photon  - an extra photon row (charged = 0, empty track fields, a 20-200 MeV cluster);
  veto    - muon_veto = 1;
  low_e   - one cluster with E = (0.3-0.6) E_beam;
  z0      - the vertex at |z| = 12-20 cm (both |z0| > 10 cm);
  acol    - the e+ turned by 15-40 deg in phi (|180 deg - |dphi|| > 10 deg).

Output: the CSV with the docs/contract.md §6 header (after two `#` comment lines), 17 significant
digits, phi folded into [0, 2pi); the truth as a docs/contract.md §3 parameter file (deg, cm). A
one-line JSON summary (event counts per kind, the number of events expected to pass the
docs/contract.md §7 selection) is printed on stdout.
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spec_reference as ref  # noqa: E402

DEG = math.pi / 180.0
TWO_PI = 2.0 * math.pi

E_BEAM = 612.5            # MeV
SIGMA_E = 0.04            # relative
SIGMA_VXY = 0.03          # cm
SIGMA_VZ = 1.0            # cm
THETA_MIN, THETA_MAX = 40.0 * DEG, 140.0 * DEG
SIGMA_TRACK = 0.25 * DEG  # rad, in theta and in phi
SIGMA_EMC = 0.5 * DEG     # rad, in theta and in phi

COLUMNS = ["run", "event", "beam_energy_mev", "muon_veto", "charged", "z0_cm", "rho_cm",
           "phi_ts_rad", "theta_ts_rad", "energy_mev", "phi_emc_rad", "theta_emc_rad"]
REJECT_KINDS = ("photon", "veto", "low_e", "z0", "acol")
EVENTS_PER_RUN = 10000
FIRST_RUN = 1001

# The paper-like truth (file units: deg, cm; beta1/beta2 as sin(beta)cos/sin(psi) x 180/pi).
PAPER_LIKE = {"alpha": 3.0, "beta1": 0.2, "beta2": -0.1, "dx": 0.3, "dy": -0.1, "dz": 0.2,
              "dp1": 0.6, "dp2": 0.2, "dp3": 0.4, "dy_rel": 0.05, "dz_rel": -0.05,
              "beta_rel": 0.1}


# --------------------------------------------------------------------------- helpers
def unit_vectors(phi, theta):
    return np.column_stack((np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                            np.cos(theta)))


def angles_of(p):
    """(phi in [0, 2pi), theta in [0, pi]) of rows of p."""
    phi = np.mod(np.arctan2(p[:, 1], p[:, 0]), TWO_PI)
    phi = np.where(phi >= TWO_PI, 0.0, phi)
    theta = np.arccos(np.clip(p[:, 2] / np.linalg.norm(p, axis=1), -1.0, 1.0))
    return phi, theta


def shower_depth(e, theta):
    """docs/contract.md §5: R(E, theta) = R0 + X0 (ln(E/Ec) - 0.5 - x_pre / sin(theta)), cm."""
    return ref.R0 + ref.X0 * (np.log(e / ref.EC) - 0.5 - ref.X_PRE / np.sin(theta))


def sphere_exit(c, d, r):
    """Outward intersection of the lines c + l d (|d| = 1) with the spheres |p| = r."""
    b = np.einsum("ij,ij->i", c, d)
    disc = b * b - (np.einsum("ij,ij->i", c, c) - r * r)
    if np.any(disc < 0.0):
        raise RuntimeError("a track misses its sphere (cannot happen for vertices near 0)")
    return c + (-b + np.sqrt(disc))[:, None] * d


def inverse_auto(p1, fit):
    """docs/contract.md §4 exact inverse with the `auto` hemisphere rule, vectorised (layers 1-2).

    Returns (p0, s) with s = +1 / -1, or 0 for a point in the gap or in an overlap.
    """
    pre = {}
    for s in (1, -1):
        t_zyz, t_mu, t_br, xi_rel, xi = ref.matrices(fit, s, layer=1)
        # p0 = T_br^T T_mu^T (T_zyz^T (p1 - xi) - xi_rel); row vectors: v @ M == M^T v
        pre[s] = (((p1 - xi) @ t_zyz) - xi_rel) @ t_mu @ t_br
    ok_p = pre[1][:, 0] >= 0.0
    ok_m = pre[-1][:, 0] < 0.0
    s = np.where(ok_p & ~ok_m, 1, np.where(ok_m & ~ok_p, -1, 0))
    p0 = np.where((s == 1)[:, None], pre[1], pre[-1])
    return p0, s


def emc_sphere_point(v, d, r, fit):
    """Shower at depth r from the centre of the *actual* hemisphere (`--shower-sphere emc`).

    The inverse of hemisphere s is an isometry, so |p0| = r means |p1 - c_s| = r with
    c_s = forward_s(0): intersect the line with that sphere for s = +1 and -1 and keep the
    s whose pre-image lies on its own side (0: gap or overlap, as in the auto rule).
    """
    cand = {}
    for s in (1, -1):
        c = ref.forward(np.zeros(3), fit, s, layer=1)
        p1 = sphere_exit(v - c, d, r) + c
        t_zyz, t_mu, t_br, xi_rel, xi = ref.matrices(fit, s, layer=1)
        cand[s] = (p1, (((p1 - xi) @ t_zyz) - xi_rel) @ t_mu @ t_br)
    ok_p = cand[1][1][:, 0] >= 0.0
    ok_m = cand[-1][1][:, 0] < 0.0
    s = np.where(ok_p & ~ok_m, 1, np.where(ok_m & ~ok_p, -1, 0))
    plus = (s == 1)[:, None]
    return (np.where(plus, cand[1][0], cand[-1][0]), np.where(plus, cand[1][1], cand[-1][1]), s)


def smear_phi_same_side(rng, phi0, s, sigma):
    """phi0 + N(0, sigma) truncated so that sign(cos phi) stays the hemisphere s.

    s = +1 needs cos(phi) >= 0 (docs/contract.md §5: s = +1 at cos = 0), s = -1 needs cos(phi) < 0.
    """
    phi = phi0 + rng.normal(0.0, sigma, size=phi0.shape)
    for _ in range(1000):
        bad = np.where(s > 0, np.cos(phi) < 0.0, np.cos(phi) >= 0.0)
        if not bad.any():
            return phi
        phi[bad] = phi0[bad] + rng.normal(0.0, sigma, size=int(bad.sum()))
    raise RuntimeError("truncated phi smearing did not converge")


def fmt(x):
    return "%.17g" % x


# --------------------------------------------------------------------------- generator
def generate(n_events, seed, truth_file_units, reject_fraction=0.03, gap_policy="track-only",
             e_beam=E_BEAM, shower_sphere="ts"):
    """Returns (rows as list of CSV strings, summary dict)."""
    fit = ref.fit_from_file(truth_file_units)
    rng = np.random.default_rng(seed)
    n = int(n_events)

    # kinds of event: 0 normal, 1.. the reject kinds
    kind = np.zeros(n, dtype=int)
    n_rej = int(round(reject_fraction * n))
    if n_rej:
        idx = rng.choice(n, size=n_rej, replace=False)
        kind[idx] = 1 + np.arange(n_rej) % len(REJECT_KINDS)

    # vertex
    vtx = np.column_stack((rng.normal(0.0, SIGMA_VXY, n), rng.normal(0.0, SIGMA_VXY, n),
                           rng.normal(0.0, SIGMA_VZ, n)))
    is_z0 = kind == 1 + REJECT_KINDS.index("z0")
    vtx[is_z0, 2] = rng.choice([-1.0, 1.0], int(is_z0.sum())) * rng.uniform(12.0, 20.0,
                                                                           int(is_z0.sum()))

    # directions: e- uniform in cos(theta) within 40-140 deg, e+ back to back
    cth = rng.uniform(math.cos(THETA_MAX), math.cos(THETA_MIN), n)
    th_m = np.arccos(cth)
    ph_m = rng.uniform(0.0, TWO_PI, n)
    th_p = math.pi - th_m
    ph_p = ph_m + math.pi
    is_acol = kind == 1 + REJECT_KINDS.index("acol")
    ph_p[is_acol] += (rng.choice([-1.0, 1.0], int(is_acol.sum()))
                      * rng.uniform(15.0, 40.0, int(is_acol.sum())) * DEG)

    # particles: index 2i (e-) and 2i+1 (e+) of event i
    m = 2 * n
    theta_t = np.empty(m)
    phi_t = np.empty(m)
    theta_t[0::2], theta_t[1::2] = th_m, th_p
    phi_t[0::2], phi_t[1::2] = ph_m, ph_p
    phi_t = np.mod(phi_t, TWO_PI)
    v = np.repeat(vtx, 2, axis=0)
    d_true = unit_vectors(phi_t, theta_t)

    energy = e_beam * (1.0 + SIGMA_E * rng.standard_normal(m))
    is_low = kind == 1 + REJECT_KINDS.index("low_e")
    low_rows = 2 * np.flatnonzero(is_low) + rng.integers(0, 2, int(is_low.sum()))
    energy[low_rows] = e_beam * rng.uniform(0.3, 0.6, len(low_rows))

    # measured track: the smeared direction through the vertex
    theta_ts = theta_t + rng.normal(0.0, SIGMA_TRACK, m)
    phi_ts = np.mod(phi_t + rng.normal(0.0, SIGMA_TRACK, m), TWO_PI)
    phi_ts = np.where(phi_ts >= TWO_PI, 0.0, phi_ts)        # np.mod(-tiny, 2pi) == 2pi
    d_ts = unit_vectors(phi_ts, theta_ts)
    lam = -(v[:, 0] * d_ts[:, 0] + v[:, 1] * d_ts[:, 1]) / (d_ts[:, 0] ** 2 + d_ts[:, 1] ** 2)
    pca = v + lam[:, None] * d_ts
    rho = -pca[:, 0] * np.sin(phi_ts) + pca[:, 1] * np.cos(phi_ts)
    z0 = pca[:, 2]
    # pca is exactly (-rho sin(phi), rho cos(phi), z0)
    assert np.allclose(pca[:, 0], -rho * np.sin(phi_ts), atol=1e-12)
    assert np.allclose(pca[:, 1], rho * np.cos(phi_ts), atol=1e-12)

    # EMC cluster: actual shower point of the true track, its nominal pre-image
    r = shower_depth(energy, theta_t)
    if np.any(r >= ref.R1):
        raise RuntimeError("shower point beyond R1: the layer-3 rule would be needed")
    if shower_sphere == "ts":
        p1 = sphere_exit(v, d_true, r)
        p0, hemi = inverse_auto(p1, fit)
    else:
        p1, p0, hemi = emc_sphere_point(v, d_true, r, fit)
    has_cluster = hemi != 0
    phi0, theta0 = angles_of(p0)
    s_model = np.where(np.cos(phi0) >= 0.0, 1, -1)
    assert np.all(s_model[has_cluster] == hemi[has_cluster])
    theta_emc = theta0 + rng.normal(0.0, SIGMA_EMC, m)
    phi_emc = smear_phi_same_side(rng, phi0, np.where(has_cluster, hemi, s_model), SIGMA_EMC)
    phi_emc = np.mod(phi_emc, TWO_PI)
    phi_emc = np.where(phi_emc >= TWO_PI, 0.0, phi_emc)
    s_reco = np.where(np.cos(phi_emc) >= 0.0, 1, -1)
    assert np.all(s_reco[has_cluster] == hemi[has_cluster])

    veto = (kind == 1 + REJECT_KINDS.index("veto")).astype(int)
    is_photon = kind == 1 + REJECT_KINDS.index("photon")
    lost = ~(has_cluster[0::2] & has_cluster[1::2])            # per event

    # summary: what the docs/contract.md §7 selection must keep
    e_ok = (energy > 0.8 * e_beam) & (energy < 1.1 * e_beam)
    normal = kind == 0
    expect_sel = normal & ~lost & e_ok[0::2] & e_ok[1::2]
    summary = {"events": n, "seed": int(seed), "gap_policy": gap_policy,
               "shower_sphere": shower_sphere,
               "kinds": {"normal": int(normal.sum())},
               "particles_without_cluster": int((~has_cluster).sum()),
               "normal_events_with_a_particle_in_the_gap": int((normal & lost).sum()),
               "normal_events_with_energy_outside_window": int((normal & ~lost & ~(e_ok[0::2] & e_ok[1::2])).sum())}
    for k, name in enumerate(REJECT_KINDS, start=1):
        summary["kinds"][name] = int((kind == k).sum())

    rows = []
    eb = fmt(e_beam)
    written = 0
    for i in range(n):
        if lost[i] and gap_policy == "drop-event":
            continue
        run = FIRST_RUN + i // EVENTS_PER_RUN
        evno = i % EVENTS_PER_RUN + 1
        head = "%d,%d,%s,%d," % (run, evno, eb, veto[i])
        for j in (2 * i, 2 * i + 1):
            trk = ",".join((fmt(z0[j]), fmt(rho[j]), fmt(phi_ts[j]), fmt(theta_ts[j])))
            if has_cluster[j]:
                clu = ",".join((fmt(energy[j]), fmt(phi_emc[j]), fmt(theta_emc[j])))
            else:
                clu = ",,"
            rows.append(head + "1," + trk + "," + clu)
        if is_photon[i]:
            eg = rng.uniform(20.0, 200.0)
            ctg = rng.uniform(math.cos(THETA_MAX), math.cos(THETA_MIN))
            rows.append(head + "0,,,,," + ",".join((fmt(eg), fmt(rng.uniform(0.0, TWO_PI)),
                                                     fmt(math.acos(ctg)))))
        written += 1
    summary["events_written"] = written
    summary["rows"] = len(rows)
    summary["expected_selected"] = int(expect_sel.sum())
    return rows, summary


def write_truth(path, truth_file_units):
    doc = {"format": "emcalign-alignment/1", "units": {"angle": "deg", "length": "cm"},
           "parameters": {k: float(truth_file_units[k]) for k in ref.FIT_NAMES}}
    with open(path, "w") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")


def read_truth(path):
    with open(path) as f:
        doc = json.load(f)
    fit = ref.fit_from_file(doc)                 # accepts `parameters` or `physical`
    return ref.file_from_fit(fit)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--events", type=int, required=True, help="number of events")
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--truth", required=True, help="write the truth parameter file (JSON) here")
    ap.add_argument("-o", "--output", required=True, help="event CSV to write")
    ap.add_argument("--params", help="truth parameter file (docs/contract.md §3); default: paper-like")
    ap.add_argument("--reject-fraction", type=float, default=0.03,
                    help="fraction of events made to fail the docs/contract.md §7 selection (default 0.03)")
    ap.add_argument("--gap-policy", choices=("track-only", "drop-event"), default="track-only",
                    help="a particle in the gap: track with empty cluster fields (default) "
                         "or leave the event out")
    ap.add_argument("--shower-sphere", choices=("ts", "emc"), default="ts",
                    help="sphere |p| = R(E, theta) of the shower point: centred at the TS origin "
                         "(default, docs/contract.md §5 p_R) or at the actual hemisphere's centre")
    args = ap.parse_args(argv)
    if args.events <= 0:
        ap.error("--events must be positive")

    truth = read_truth(args.params) if args.params else dict(PAPER_LIKE)
    rows, summary = generate(args.events, args.seed, truth, args.reject_fraction,
                             args.gap_policy, shower_sphere=args.shower_sphere)
    tmp = args.output + ".part"
    with open(tmp, "w") as f:
        f.write("# e+e- -> e+e- events from tests/crosscheck/spec_events.py (the contract's model), "
                "seed %d, %d events\n" % (args.seed, args.events))
        f.write("# truth: %s\n" % json.dumps(truth, sort_keys=False))
        f.write(",".join(COLUMNS) + "\n")
        f.write("\n".join(rows))
        f.write("\n")
    os.replace(tmp, args.output)
    write_truth(args.truth, truth)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Independent reference implementation of the emcalign alignment transform.

Written from docs/contract.md sections 1-5 alone (no C++ code was read), to
cross-check the C++ library and command-line tool. Plain numpy, explicit rotation
matrices, atan2/asin used freely (this code is never differentiated).

Units inside this module are native: cm, MeV, rad. Parameter files use deg and cm;
`fit_from_file` / `file_from_fit` / `physical_to_file` / `physical_from_file`
convert at the boundary. beta1/beta2 are dimensionless inside, and written in
files as value*180/pi ("degrees").

Run `python3 spec_reference.py` for the module's self-consistency checks.
"""

import functools
import math

import numpy as np

# --- contract §2: detector constants -------------------------------------------
R0 = 32.8      # cm, EMC inner radius
R1 = 53.7      # cm, outer radius of support sphere 1 (layers 1-2)
RP3 = 69.5     # cm, outer radius of support sphere 2 (layer 3)
X0 = 2.56      # cm, NaI radiation length
EC = 13.16     # MeV, NaI critical energy
X_PRE = 0.13   # material before the EMC, in X0

DEG = math.pi / 180.0

FIT_NAMES = ("alpha", "beta1", "beta2", "dx", "dy", "dz",
             "dp1", "dp2", "dp3", "dy_rel", "dz_rel", "beta_rel")
PHYS_NAMES = ("alpha", "beta", "psi", "dx", "dy", "dz",
              "mu", "tau", "dx_rel", "dy_rel", "dz_rel", "beta_rel")
# Names that are angles (or "degree-scaled" dimensionless numbers) in files.
FIT_ANGLE_NAMES = ("alpha", "beta1", "beta2", "beta_rel")
PHYS_ANGLE_NAMES = ("alpha", "beta", "psi", "mu", "tau", "beta_rel")

GAMMAS = (0.0, 120.0 * DEG, 240.0 * DEG)   # parting-plane points of dp1, dp2, dp3


# --- unit conversion at I/O ----------------------------------------------------------
def fit_from_file(params_deg_cm):
    """12 fit parameters as in a file (deg, cm) -> native dict (rad, dimensionless, cm).

    Also accepts a whole parameter-file dict ({"parameters": ...} or {"physical": ...}).
    """
    if "parameters" in params_deg_cm and isinstance(params_deg_cm["parameters"], dict):
        params_deg_cm = params_deg_cm["parameters"]
    elif "physical" in params_deg_cm and isinstance(params_deg_cm["physical"], dict):
        return fit_from_physical(physical_from_file(params_deg_cm["physical"]))
    missing = [n for n in FIT_NAMES if n not in params_deg_cm]
    unknown = [n for n in params_deg_cm if n not in FIT_NAMES]
    if missing or unknown:
        raise ValueError("bad parameter set: missing %s, unknown %s" % (missing, unknown))
    return {n: float(params_deg_cm[n]) * (DEG if n in FIT_ANGLE_NAMES else 1.0)
            for n in FIT_NAMES}


def file_from_fit(fit):
    """Native fit dict -> file units (deg, cm)."""
    return {n: float(fit[n]) / (DEG if n in FIT_ANGLE_NAMES else 1.0) for n in FIT_NAMES}


def physical_from_file(phys_deg_cm):
    missing = [n for n in PHYS_NAMES if n not in phys_deg_cm]
    unknown = [n for n in phys_deg_cm if n not in PHYS_NAMES]
    if missing or unknown:
        raise ValueError("bad physical set: missing %s, unknown %s" % (missing, unknown))
    return {n: float(phys_deg_cm[n]) * (DEG if n in PHYS_ANGLE_NAMES else 1.0)
            for n in PHYS_NAMES}


def physical_to_file(phys):
    return {n: float(phys[n]) / (DEG if n in PHYS_ANGLE_NAMES else 1.0) for n in PHYS_NAMES}


# --- contract §3: fit <-> physical parameters --------------------------------------
def gap_quantities(fit):
    """(dx_rel, u, t) from dp1..dp3 (contract §3)."""
    dp1, dp2, dp3 = fit["dp1"], fit["dp2"], fit["dp3"]
    dx_rel = (dp1 + dp2 + dp3) / 6.0
    u = dp1 - 2.0 * dx_rel
    t = (dp3 - dp2) / (2.0 * math.sqrt(3.0))
    return dx_rel, u, t


def physical_from_fit(fit):
    """Native fit dict -> native physical dict (alpha, beta, psi, ..., mu, tau, dx_rel ...)."""
    b1, b2 = fit["beta1"], fit["beta2"]
    beta = math.asin(min(1.0, math.sqrt(b1 * b1 + b2 * b2)))
    psi = math.atan2(b2, b1)
    dx_rel, u, t = gap_quantities(fit)
    tau = math.atan2(2.0 * t, u)          # atan2(0, 0) == 0 in Python
    mu = math.asin(min(1.0, math.sqrt(4.0 * t * t + u * u) / (2.0 * R1)))
    return {"alpha": fit["alpha"], "beta": beta, "psi": psi,
            "dx": fit["dx"], "dy": fit["dy"], "dz": fit["dz"],
            "mu": mu, "tau": tau, "dx_rel": dx_rel,
            "dy_rel": fit["dy_rel"], "dz_rel": fit["dz_rel"], "beta_rel": fit["beta_rel"]}


def fit_from_physical(phys):
    """Native physical dict -> native fit dict (contract §3 inverse relations)."""
    beta, psi = phys["beta"], phys["psi"]
    out = {"alpha": phys["alpha"],
           "beta1": math.sin(beta) * math.cos(psi),
           "beta2": math.sin(beta) * math.sin(psi),
           "dx": phys["dx"], "dy": phys["dy"], "dz": phys["dz"],
           "dy_rel": phys["dy_rel"], "dz_rel": phys["dz_rel"], "beta_rel": phys["beta_rel"]}
    for k, g in enumerate(GAMMAS):
        out["dp%d" % (k + 1)] = (2.0 * phys["dx_rel"]
                                 + 2.0 * R1 * math.sin(phys["mu"]) * math.cos(g + phys["tau"]))
    return {n: out[n] for n in FIT_NAMES}


# --- contract §1: active right-handed rotations ----------------------------------------
def rot_x(g):
    c, s = math.cos(g), math.sin(g)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(g):
    c, s = math.cos(g), math.sin(g)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(g):
    c, s = math.cos(g), math.sin(g)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_axis(a, g):
    """Rodrigues: R_a(g) p = p cos g + (a x p) sin g + a (a.p)(1 - cos g), |a| = 1."""
    a = np.asarray(a, dtype=float)
    a = a / np.linalg.norm(a)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return (math.cos(g) * np.eye(3) + math.sin(g) * K
            + (1.0 - math.cos(g)) * np.outer(a, a))


# --- contract §4: the alignment transform ------------------------------------------
def _mu_tau(fit, layer):
    """(mu, tau) used for a layer, with the third-layer mu3 rule."""
    dx_rel, u, t = gap_quantities(fit)
    tau = math.atan2(2.0 * t, u)
    mu = math.asin(min(1.0, math.sqrt(4.0 * t * t + u * u) / (2.0 * R1)))
    if layer == 3 and dx_rel - RP3 * math.sin(mu) < 0.0:
        mu = math.asin(dx_rel / RP3)
    return mu, tau


def layer3_rule_active(fit):
    dx_rel, u, t = gap_quantities(fit)
    mu = math.asin(min(1.0, math.sqrt(4.0 * t * t + u * u) / (2.0 * R1)))
    return dx_rel - RP3 * math.sin(mu) < 0.0


def matrices(fit, s, layer=1):
    """(T_zyz, T_mu, T_betarel, xi_rel, xi) for hemisphere s (+1/-1) and a layer.

    Built once per (parameter values, s, layer) and shared: the arrays are read-only.
    The key is the exact bits of every value (float.hex), so -0.0 and 0.0, which give
    different atan2 angles, are different sets.
    """
    if s not in (1, -1):
        raise ValueError("hemisphere must be +1 or -1")
    return _matrices(tuple(float(fit[n]).hex() for n in FIT_NAMES), s, layer)


@functools.lru_cache(maxsize=1024)
def _matrices(key, s, layer):
    fit = {n: float.fromhex(v) for n, v in zip(FIT_NAMES, key)}
    phys = physical_from_fit(fit)
    beta, psi, alpha = phys["beta"], phys["psi"], fit["alpha"]
    T_zyz = rot_z(psi) @ rot_y(beta) @ rot_z(alpha - psi)
    mu, tau = _mu_tau(fit, layer)
    n = np.array([0.0, -math.sin(tau), math.cos(tau)])
    T_mu = rot_axis(n, -s * mu)
    T_br = rot_x(s * fit["beta_rel"])
    xi_rel = s * np.array([phys["dx_rel"], fit["dy_rel"], fit["dz_rel"]])
    xi = np.array([fit["dx"], fit["dy"], fit["dz"]])
    out = (T_zyz, T_mu, T_br, xi_rel, xi)
    for a in out:
        a.setflags(write=False)
    return out


def forward(p0, fit, s, layer=1):
    """Nominal point p0 (cm) of hemisphere s -> actual point p1 in the TS frame."""
    T_zyz, T_mu, T_br, xi_rel, xi = matrices(fit, s, layer)
    p0 = np.asarray(p0, dtype=float)
    return T_zyz @ (T_mu @ T_br @ p0 + xi_rel) + xi


def inverse(p1, fit, s, layer=1):
    """Exact inverse: p0 = T_br^T T_mu^T (T_zyz^T (p1 - xi) - xi_rel)."""
    T_zyz, T_mu, T_br, xi_rel, xi = matrices(fit, s, layer)
    p1 = np.asarray(p1, dtype=float)
    return T_br.T @ T_mu.T @ (T_zyz.T @ (p1 - xi) - xi_rel)


# The same maps on many points at once: rows of an (N, 3) array, p @ M.T being M p per row.
def forward_many(p0, fit, s, layer=1):
    """forward() of every row of p0; s is +1, -1 or an array of them, one per row."""
    p0 = np.asarray(p0, dtype=float)
    if np.ndim(s) == 0:
        T_zyz, T_mu, T_br, xi_rel, xi = matrices(fit, int(s), layer)
        return (p0 @ (T_mu @ T_br).T + xi_rel) @ T_zyz.T + xi
    s = np.asarray(s)
    if not np.all((s == 1) | (s == -1)):
        raise ValueError("hemisphere must be +1 or -1")
    return np.where((s == 1)[:, None], forward_many(p0, fit, 1, layer),
                    forward_many(p0, fit, -1, layer))


def inverse_many(p1, fit, s, layer=1):
    """inverse() of every row of p1 for one hemisphere s."""
    T_zyz, T_mu, T_br, xi_rel, xi = matrices(fit, s, layer)
    p1 = np.asarray(p1, dtype=float)
    # p0 = T_br^T T_mu^T v per row: v^T (T_mu T_br)
    return ((p1 - xi) @ T_zyz - xi_rel) @ (T_mu @ T_br)


def inverse_auto_many(p1, fit, layer=1):
    """inverse_auto() of every row: (p0 with NaN rows for gap/overlap, list of s or label)."""
    q_plus = inverse_many(p1, fit, 1, layer)
    q_minus = inverse_many(p1, fit, -1, layer)
    ok_plus = q_plus[:, 0] >= 0.0
    ok_minus = q_minus[:, 0] < 0.0
    labels = [("overlap" if m else 1) if p else (-1 if m else "gap")
              for p, m in zip(ok_plus.tolist(), ok_minus.tolist())]
    p0 = np.full_like(q_plus, np.nan)
    only_plus, only_minus = ok_plus & ~ok_minus, ok_minus & ~ok_plus
    p0[only_plus] = q_plus[only_plus]
    p0[only_minus] = q_minus[only_minus]
    return p0, labels


def auto_margin_many(p1, fit, layer=1):
    """auto_margin() of every row."""
    return np.minimum(np.abs(inverse_many(p1, fit, 1, layer)[:, 0]),
                      np.abs(inverse_many(p1, fit, -1, layer)[:, 0]))


def hemisphere_of(p):
    """s of a nominal point: x >= 0 -> +1, else -1."""
    return 1 if p[0] >= 0.0 else -1


def inverse_auto(p1, fit, layer=1):
    """Pick the s whose pre-image lies on its own side.

    Returns (p0, s) with s in {+1, -1}, or (None, 'gap') when neither pre-image
    qualifies, (None, 'overlap') when both do.
    """
    q_plus = inverse(p1, fit, 1, layer)
    q_minus = inverse(p1, fit, -1, layer)
    ok_plus = q_plus[0] >= 0.0
    ok_minus = q_minus[0] < 0.0
    if ok_plus and ok_minus:
        return None, "overlap"
    if ok_plus:
        return q_plus, 1
    if ok_minus:
        return q_minus, -1
    return None, "gap"


def auto_margin(p1, fit, layer=1):
    """min |x| of the two candidate pre-images: how close the auto decision is to a tie."""
    return min(abs(inverse(p1, fit, 1, layer)[0]), abs(inverse(p1, fit, -1, layer)[0]))


# --- contract §5: shower depth, track point, model -------------------------------------
def shower_depth(E, theta):
    """R(E, theta) = R0 + X0 (ln(E/Ec) - 0.5 - x_pre / sin(theta)), cm."""
    return R0 + X0 * (math.log(E / EC) - 0.5 - X_PRE / math.sin(theta))


def direction(phi, theta):
    return np.array([math.sin(theta) * math.cos(phi),
                     math.sin(theta) * math.sin(phi), math.cos(theta)])


def angles(p):
    """(phi in [0, 2pi), theta in [0, pi]) of a point."""
    phi = math.atan2(p[1], p[0])
    if phi < 0.0:
        phi += 2.0 * math.pi
    if phi >= 2.0 * math.pi:
        phi = 0.0
    r = float(np.linalg.norm(p))
    theta = math.acos(max(-1.0, min(1.0, p[2] / r)))
    return phi, theta


def track_sphere_point(z0, rho, phi, theta, R):
    """Outward intersection of the straight track with the sphere |p| = R (None if none)."""
    c = np.array([-rho * math.sin(phi), rho * math.cos(phi), z0])
    d = direction(phi, theta)
    b = float(c @ d)
    disc = b * b - (float(c @ c) - R * R)
    if disc < 0.0:
        return None
    lam = -b + math.sqrt(disc)
    return c + lam * d


def track_residual_angles(z0, rho, phi, theta, E):
    """(phi_TS,R, theta_TS,R) of the track point at the shower depth R(E, theta_ts)."""
    p = track_sphere_point(z0, rho, phi, theta, shower_depth(E, theta))
    return None if p is None else angles(p)


def model_residuals(phi0, theta0, E, fit):
    """(f_phi, f_theta) of contract §5 (layers 1-2 transform, no mu3 rule)."""
    p0 = shower_depth(E, theta0) * direction(phi0, theta0)
    s = 1 if math.cos(phi0) >= 0.0 else -1
    p1 = forward(p0, fit, s, layer=1)
    phi1, theta1 = angles(p1)
    return math.sin(phi1 - phi0), theta1 - theta0


# --- self-consistency checks -------------------------------------------------------------
def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rot_from_sin_vector(v):
    """R_a(g) from v = sin(g) a, |g| <= pi/2: cI + [v]x + v v^T/(1+c)."""
    v = np.asarray(v, dtype=float)
    c = math.sqrt(max(0.0, 1.0 - float(v @ v)))
    return c * np.eye(3) + _skew(v) + np.outer(v, v) / (1.0 + c)


def random_fit(rng):
    f = {"alpha": rng.uniform(-5, 5) * DEG,
         "beta1": rng.uniform(-1, 1) * DEG, "beta2": rng.uniform(-1, 1) * DEG,
         "dx": rng.uniform(-1, 1), "dy": rng.uniform(-1, 1), "dz": rng.uniform(-1, 1),
         "dp1": rng.uniform(-0.5, 1.0), "dp2": rng.uniform(-0.5, 1.0),
         "dp3": rng.uniform(-0.5, 1.0),
         "dy_rel": rng.uniform(-1, 1), "dz_rel": rng.uniform(-1, 1),
         "beta_rel": rng.uniform(-2, 2) * DEG}
    return f


def self_test(verbose=True):
    """Returns list of (name, ok, detail)."""
    results = []

    def check(name, ok, detail=""):
        results.append((name, bool(ok), detail))
        if verbose:
            print("  [%s] %s %s" % ("PASS" if ok else "FAIL", name, detail))

    rng = np.random.default_rng(12345)
    zero = {n: 0.0 for n in FIT_NAMES}

    # 1. inverse(forward(p)) == p, both hemispheres, layers 1 and 3.
    worst = 0.0
    for _ in range(20):
        fit = random_fit(rng)
        for layer in (1, 3):
            for s in (1, -1):
                for _ in range(20):
                    p = rng.normal(size=3) * 40.0
                    worst = max(worst, np.max(np.abs(inverse(forward(p, fit, s, layer),
                                                             fit, s, layer) - p)))
    check("inverse(forward(p)) == p", worst < 1e-12, "max dev %.3g cm" % worst)

    # 2. explicit ZYZ == R_a(beta) R_z(alpha) == smooth form from (-beta2, beta1, 0);
    #    T_mu explicit == smooth form from -s*sin(mu)*n = -s*(0, -t/R1, u/(2R1)).
    worst_zyz = worst_mu = 0.0
    for _ in range(50):
        fit = random_fit(rng)
        ph = physical_from_fit(fit)
        a = np.array([-math.sin(ph["psi"]), math.cos(ph["psi"]), 0.0])
        A = rot_axis(a, ph["beta"]) @ rot_z(fit["alpha"])
        B = _rot_from_sin_vector([-fit["beta2"], fit["beta1"], 0.0]) @ rot_z(fit["alpha"])
        for s in (1, -1):
            T_zyz, T_mu, _, _, _ = matrices(fit, s, 1)
            worst_zyz = max(worst_zyz, np.max(np.abs(T_zyz - A)), np.max(np.abs(T_zyz - B)))
            _, u, t = gap_quantities(fit)
            C = _rot_from_sin_vector(-s * np.array([0.0, -t / R1, u / (2 * R1)]))
            worst_mu = max(worst_mu, np.max(np.abs(T_mu - C)))
    check("T_zyz: ZYZ == R_a(beta)R_z(alpha) == smooth", worst_zyz < 1e-14,
          "max dev %.3g" % worst_zyz)
    check("T_mu: Rodrigues(n, -s mu) == smooth sin-vector form", worst_mu < 1e-14,
          "max dev %.3g" % worst_mu)

    # 3. geometric meaning of dp_k (beta_rel = 0, zero common parameters).
    worst = 0.0
    for _ in range(30):
        fit = dict(zero)
        for k in (1, 2, 3):
            fit["dp%d" % k] = rng.uniform(-0.5, 1.0)
        fit["dy_rel"], fit["dz_rel"] = rng.uniform(-1, 1, size=2)
        for k, g in enumerate(GAMMAS):
            q = R1 * np.array([0.0, math.cos(g), -math.sin(g)])
            sep = forward(q, fit, 1)[0] - forward(q, fit, -1)[0]
            worst = max(worst, abs(sep - fit["dp%d" % (k + 1)]))
    check("x-separation at R1(0,cos g_k,-sin g_k) == dp_k", worst < 1e-13,
          "max dev %.3g cm" % worst)

    # 4. mu > 0 opens the gap on the side (0, cos tau, sin tau).
    ok = True
    for _ in range(20):
        ph = physical_from_fit(zero)
        ph["mu"], ph["tau"] = rng.uniform(0.001, 0.02), rng.uniform(-math.pi, math.pi)
        fit = fit_from_physical(ph)
        q = R1 * np.array([0.0, math.cos(ph["tau"]), math.sin(ph["tau"])])
        sep = forward(q, fit, 1)[0] - forward(q, fit, -1)[0]
        ok &= abs(sep - 2 * R1 * math.sin(ph["mu"])) < 1e-12
    check("mu > 0 opens the gap at (0, cos tau, sin tau) by 2 R1 sin mu", ok)

    # 5. pure alpha rotates phi by alpha (and keeps theta and radius).
    worst = 0.0
    for _ in range(20):
        fit = dict(zero)
        fit["alpha"] = rng.uniform(-10, 10) * DEG
        for _ in range(10):
            p = rng.normal(size=3) * 40.0
            q = forward(p, fit, hemisphere_of(p))
            dphi = math.atan2(q[1], q[0]) - math.atan2(p[1], p[0])
            dphi = (dphi - fit["alpha"] + math.pi) % (2 * math.pi) - math.pi
            worst = max(worst, abs(dphi), abs(q[2] - p[2]),
                        abs(np.linalg.norm(q) - np.linalg.norm(p)))
    check("pure alpha rotates phi by alpha", worst < 1e-12, "max dev %.3g" % worst)

    # 6. fit <-> physical round trips.
    worst = 0.0
    for _ in range(50):
        fit = random_fit(rng)
        back = fit_from_physical(physical_from_fit(fit))
        worst = max(worst, max(abs(back[n] - fit[n]) for n in FIT_NAMES))
        back = fit_from_file(file_from_fit(fit))
        worst = max(worst, max(abs(back[n] - fit[n]) for n in FIT_NAMES))
    check("fit -> physical -> fit and file round trips", worst < 1e-14,
          "max dev %.3g" % worst)

    # 7. third-layer rule: when active the hemispheres touch at RP3 (min separation 0),
    #    else the layer-3 transform equals the layer-1 transform.
    n_on = n_off = 0
    ok = True
    for _ in range(200):
        fit = dict(zero)
        for k in (1, 2, 3):
            fit["dp%d" % k] = rng.uniform(-0.5, 1.0)
        if fit["dp1"] + fit["dp2"] + fit["dp3"] <= 0.0:
            continue   # dx_rel < 0 : mu3 < 0, touching is not what the rule gives
        gs = np.linspace(0.0, 2 * math.pi, 721)
        if layer3_rule_active(fit):
            n_on += 1
            ring = RP3 * np.column_stack((np.zeros_like(gs), np.cos(gs), -np.sin(gs)))
            seps = forward_many(ring, fit, 1, 3)[:, 0] - forward_many(ring, fit, -1, 3)[:, 0]
            ok &= abs(min(seps)) < 1e-4 and min(seps) > -1e-12
        else:
            n_off += 1
            p = rng.normal(size=3) * 60.0
            ok &= np.allclose(forward(p, fit, 1, 3), forward(p, fit, 1, 1), atol=1e-14)
    check("layer-3 rule: hemispheres touch at RP3 when active, else layer 3 == layer 1",
          ok and n_on > 0 and n_off > 0, "(%d active, %d inactive)" % (n_on, n_off))

    # 8. inverse_auto: pre-image of a nominal point away from x=0 is found again.
    ok = True
    for _ in range(10):
        fit = random_fit(rng)
        for _ in range(20):
            p = rng.normal(size=3) * 40.0
            if abs(p[0]) < 3.0:
                continue
            q, s = inverse_auto(forward(p, fit, hemisphere_of(p)), fit)
            ok &= s == hemisphere_of(p) and np.allclose(q, p, atol=1e-12)
    check("inverse_auto recovers nominal points away from the parting plane", ok)

    # 9. track point: on the sphere, on the line, outward; centred track keeps its angles.
    ok = True
    for _ in range(50):
        z0, rho = rng.uniform(-10, 10), rng.uniform(-1, 1)
        phi, theta = rng.uniform(0, 2 * math.pi), rng.uniform(0.3, math.pi - 0.3)
        R = shower_depth(rng.uniform(100, 1000), theta)
        p = track_sphere_point(z0, rho, phi, theta, R)
        c = np.array([-rho * math.sin(phi), rho * math.cos(phi), z0])
        d = direction(phi, theta)
        lam = float((p - c) @ d)
        ok &= abs(np.linalg.norm(p) - R) < 1e-11 and lam > 0
        ok &= np.linalg.norm(p - c - lam * d) < 1e-11
        p = track_sphere_point(0.0, 0.0, phi, theta, R)
        ph, th = angles(p)
        ok &= abs(ph - phi) < 1e-12 and abs(th - theta) < 1e-12
    check("track_sphere_point on sphere/line/outward; centred track keeps angles", ok)

    # 10. model residuals vanish for zero parameters; small alpha gives f_phi ~ sin(alpha).
    ok = True
    for _ in range(20):
        phi0, th0, E = rng.uniform(0, 2 * math.pi), rng.uniform(0.5, 2.6), rng.uniform(200, 1000)
        fp, ft = model_residuals(phi0, th0, E, zero)
        ok &= abs(fp) < 1e-14 and abs(ft) < 1e-14
        fit = dict(zero)
        fit["alpha"] = 0.01
        fp, ft = model_residuals(phi0, th0, E, fit)
        ok &= abs(fp - math.sin(0.01)) < 1e-14 and abs(ft) < 1e-14
    check("model_residuals: zero at eta = 0, sin(alpha) for pure alpha", ok)

    # 11. the maps on many points at once equal the point-by-point ones.
    worst, ok = 0.0, True
    for _ in range(10):
        fit = random_fit(rng)
        pts = rng.normal(size=(50, 3)) * 40.0
        pts[:10, 0] *= 0.01     # near the parting plane: gaps and overlaps
        for layer in (1, 3):
            s = np.where(pts[:, 0] >= 0.0, 1, -1)
            many = [forward_many(pts, fit, s, layer)]
            one = [[forward(p, fit, hemisphere_of(p), layer) for p in pts]]
            for h in (1, -1):
                many.append(inverse_many(pts, fit, h, layer))
                one.append([inverse(p, fit, h, layer) for p in pts])
            worst = max([worst] + [float(np.max(np.abs(np.array(b) - a)))
                                   for a, b in zip(many, one)])
            q, labels = inverse_auto_many(pts, fit, layer)
            for i, p in enumerate(pts):
                q1, s1 = inverse_auto(p, fit, layer)
                ok &= s1 == labels[i] and (np.all(np.isnan(q[i])) if q1 is None
                                           else np.allclose(q[i], q1, rtol=0.0, atol=1e-12))
            ok &= np.allclose(auto_margin_many(pts, fit, layer),
                              [auto_margin(p, fit, layer) for p in pts], rtol=0.0, atol=1e-12)
    check("forward/inverse/inverse_auto on many points == point by point",
          ok and worst < 1e-12, "max dev %.3g cm" % worst)

    # 12. shower depth value.
    r = shower_depth(500.0, math.pi / 2)
    ok = abs(r - (R0 + X0 * (math.log(500.0 / EC) - 0.5 - X_PRE))) < 1e-12
    check("shower_depth(500 MeV, 90 deg) = %.6f cm" % r, ok)
    return results


if __name__ == "__main__":
    res = self_test()
    nf = sum(1 for _, ok, _ in res if not ok)
    print("%d passed, %d failed" % (len(res) - nf, nf))
    raise SystemExit(1 if nf else 0)

# %% [markdown]
# # The emcalign demo in Python
#
# `scripts/demo` with the command-line tool, done again from Python on the same C++ code:
# a paper-like misalignment, simulated e+e- -> e+e- events, the calibration (the paper's
# model, then with the model corrections), the events corrected with the result, and the
# result stored in a conditions database. Each `# %%` is a notebook cell (Jupyter, VS Code);
# as a script it writes its figures and results into a directory:
#
#     scripts/build
#     PYTHONPATH=build/python /usr/bin/python3 docs/examples/demo.py out/demo-python
#
# Units are the library's (cm, MeV, rad); `emcalign.file_units()` gives the files' (deg, cm).

# %%
import os
import sys

import matplotlib

matplotlib.use("Agg")  # files, not windows (a notebook shows them inline anyway)
import matplotlib.pyplot as plt
import numpy as np

import emcalign

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OUT = sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("-") else "out/demo-python"
EVENTS = int(os.environ.get("EMCALIGN_DEMO_EVENTS", "50000"))
os.makedirs(OUT, exist_ok=True)
units = emcalign.file_units()

# %% [markdown]
# ## The detector and a paper-like misalignment

# %%
det = emcalign.Detector()
truth, warnings = emcalign.read_alignment(os.path.join(ROOT, "data", "examples", "paper-like.json"), det)
print(f"{det.size} counters, support sphere 1 at r1 = {det.r1} cm")
print("truth:", {name: round(v, 4) for name, v in zip(emcalign.PARAMETERS, truth / units)})

# Nominal points near the parting plane x = 0 and where they really are (the transform of docs/contract.md §4).
nominal = np.array([[41.0, 0, 0], [0.5, 41, 0], [-0.5, 41, 0], [-41, 0, 0], [29, 0, 29], [-29, 0, -29]])
actual = emcalign.forward(det, truth, nominal)
print("shift (mm):", np.round(10 * np.linalg.norm(actual - nominal, axis=1), 2))
# Every counter moved, in the geometry database; the two hemispheres move apart.
moved = det.aligned_centres(truth) - det.counters()["centre_cm"]
print(f"largest counter displacement: {10 * np.linalg.norm(moved, axis=1).max():.2f} mm")

# %% [markdown]
# ## Simulated e+e- -> e+e- events for this misalignment

# %%
events_path = os.path.join(OUT, "events.h5")
emcalign.simulate(truth, EVENTS, output=events_path, seed=1, theta_min_deg=40, theta_max_deg=140)
ev = emcalign.read_events(events_path)
cut = emcalign.select(ev)  # docs/contract.md §7, per row: 0 when the event is selected
print(f"{EVENTS} events, {len(ev['run'])} particle rows, {np.count_nonzero(cut == 0)} rows selected")

# %% [markdown]
# ## The calibration: the paper's model, and with the model corrections

# %%
fit = emcalign.fit(events_path, det)
fit.write(os.path.join(OUT, "result.json"))
fit.write_profile(os.path.join(OUT, "profile.csv"))
corrected_fit = emcalign.fit(events_path, det,
                             corrections=os.path.join(ROOT, "data", "corrections", "ee-612.5MeV-40-140deg.json"))
corrected_fit.write(os.path.join(OUT, "result-corrected.json"))
print(fit)
print(corrected_fit)
print(f"{'':10} {'truth':>9} {'fit':>17} {'corrected':>17}   ({'deg or cm'})")
for k, name in enumerate(emcalign.PARAMETERS):
    u = units[k]
    print(f"{name:10} {truth[k] / u:9.4f} {fit.parameters[k] / u:9.4f} ± {fit.errors[k] / u:.4f}"
          f" {corrected_fit.parameters[k] / u:9.4f} ± {corrected_fit.errors[k] / u:.4f}")

# %% [markdown]
# The profiles the fit saw: the mean residuals y_φ and y_θ per φ bin, one line per θ slice.

# %%
bins = fit.bins
fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharex=True)
for ax, key, label in ((axes[0], "phi", r"$y_\varphi$"), (axes[1], "theta", r"$y_\theta$")):
    for i_theta in np.unique(bins["i_theta"]):
        row = (bins["i_theta"] == i_theta) & bins["used"]
        ax.errorbar(np.degrees(bins["phi_mean_rad"][row]), np.degrees(bins[f"y_{key}"][row]),
                    yerr=np.degrees(bins[f"sigma_{key}"][row]), fmt=".", ms=3, lw=0.6,
                    label=f"θ ≈ {np.degrees(np.nanmean(bins['theta_mean_rad'][row])):.0f}°")
    ax.axvline(90, color="grey", lw=0.5)
    ax.axvline(270, color="grey", lw=0.5)
    ax.set_xlabel("φ (deg)")
    ax.set_ylabel(f"{label} (deg)")
axes[1].legend(fontsize=6, ncol=2)
fig.suptitle(f"profiles ({fit.bins_used} bins used), χ²/ndf = {fit.chi2:.1f}/{fit.ndf}")
fig.tight_layout()
fig.savefig(os.path.join(OUT, "profiles.png"), dpi=110)

# %% [markdown]
# ## The fitted parameters against the truth

# %%
fig, ax = plt.subplots(figsize=(9, 3.8))
x = np.arange(len(emcalign.PARAMETERS))
for shift, result, label in ((-0.15, fit, "paper's model"), (0.15, corrected_fit, "with corrections")):
    ax.errorbar(x + shift, (result.parameters - truth) / result.errors, yerr=1.0, fmt="o", ms=4, label=label)
ax.axhline(0, color="grey", lw=0.5)
ax.set_xticks(x, emcalign.PARAMETERS, rotation=45)
ax.set_ylabel("(fit − truth) / error")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(OUT, "pulls.png"), dpi=110)

# %% [markdown]
# ## Using the result: the events corrected, the residuals before and after
#
# The hemispheres' residuals: Δφ = φ_EMC − φ_TS of the selected particles, which the
# misalignment shifts in opposite directions in the two hemispheres (cos φ > 0 and < 0).

# %%
corrected_path = os.path.join(OUT, "events-corrected.h5")
report = emcalign.correct(events_path, corrected_path, det, alignment=os.path.join(OUT, "result-corrected.json"))
print(f"corrected {report['clusters']} clusters of {report['events']} events ({report['method']} method)")
after = emcalign.read_events(corrected_path)


def residuals(columns):
    rows = (cut == 0) & (columns["charged"] == 1) & ~np.isnan(columns["energy_mev"])
    dphi = np.remainder(columns["phi_emc_rad"] - columns["phi_ts_rad"] + np.pi, 2 * np.pi) - np.pi
    plus = np.cos(columns["phi_emc_rad"]) > 0
    return np.degrees(dphi[rows & plus]), np.degrees(dphi[rows & ~plus])


fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
everything = np.concatenate(residuals(ev) + residuals(after))
edges = np.linspace(*np.percentile(everything, [0.5, 99.5]), 121)
for ax, columns, title in ((axes[0], ev, "as reconstructed"), (axes[1], after, "corrected")):
    plus, minus = residuals(columns)
    ax.hist(plus, edges, histtype="step", label=f"x > 0: mean {plus.mean():+.3f}°")
    ax.hist(minus, edges, histtype="step", label=f"x < 0: mean {minus.mean():+.3f}°")
    ax.set_title(title)
    ax.set_xlabel("Δφ = φ_EMC − φ_TS (deg)")
    ax.legend(fontsize=8)
    print(f"{title:17} mean dphi: x > 0 {plus.mean():+.4f} deg, x < 0 {minus.mean():+.4f} deg")
fig.tight_layout()
fig.savefig(os.path.join(OUT, "residuals.png"), dpi=110)

# %% [markdown]
# ## The result in a conditions database, by run range

# %%
db_path = os.path.join(OUT, "conditions.sqlite")
if os.path.exists(db_path):
    os.remove(db_path)  # the demo starts afresh each time
db = emcalign.Conditions(f"sqlite:{db_path}", create=True)
db.put("demo", (1, 100), os.path.join(OUT, "result-corrected.json"), description="Python demo")
got = db.get("demo", 42)
print(f"run 42: IOV {got['first_run']}-{got['last_run']}, payload {got['payload'][:12]},",
      "the stored parameters are the fit's:", bool(np.allclose(got["parameters"], corrected_fit.parameters,
                                                                 rtol=1e-12, atol=1e-15)))
print(f"Wrote {OUT}/: events.h5, result.json, result-corrected.json, profile.csv, events-corrected.h5,",
      "conditions.sqlite, profiles.png, pulls.png, residuals.png")

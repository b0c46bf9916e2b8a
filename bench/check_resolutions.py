#!/usr/bin/env python3
"""The measurement errors of the π+π−π0 kinematic fit (apply/physics_checks.hpp,
ResolutionModel; docs/checks.md), measured in the simulation: a 3π HDF5 file of a nominal
detector (zero alignment, with truth), photons' EMC directions seen from the true vertex
against their generated directions, in bins of energy; the pions' TS angles likewise.
Robust σ = 1.4826·MAD (the core), and the RMS (with the tails).

  check_resolutions.py FILE.h5       (Debian's /usr/bin/python3 with h5py and numpy)
"""
import sys

import h5py
import numpy as np

# The shower depth of the default detector (docs/contract.md §5): R0, X0, Ec, x_pre.
R0, X0, EC, XPRE = 32.8, 2.56, 13.16, 0.13


def robust(x):
    x = x[np.isfinite(x)]
    return 1.4826 * np.median(np.abs(x - np.median(x))), np.std(x)


def main():
    f = h5py.File(sys.argv[1], "r")
    e, t = f["events"], f["truth"]
    energy, theta, phi, charged = (e[k][:] for k in ("energy_mev", "theta_emc_rad", "phi_emc_rad", "charged"))
    theta_ts, phi_ts = e["theta_ts_rad"][:], e["phi_ts_rad"][:]
    pdg, e_true, th_true, ph_true, vz = (t[k][:] for k in ("pdg", "energy_mev", "theta_rad", "phi_rad", "vertex_z_cm"))
    photon = (pdg == 22) & (charged == 0) & np.isfinite(energy) & (th_true > np.radians(40)) & (th_true < np.radians(140))
    r = R0 + X0 * (np.log(energy / EC) - 0.5 - XPRE / np.sin(theta))
    px, py, pz = r * np.sin(theta) * np.cos(phi), r * np.sin(theta) * np.sin(phi), r * np.cos(theta) - vz
    th_v = np.arccos(pz / np.sqrt(px ** 2 + py ** 2 + pz ** 2))
    ph_v = np.arctan2(py, px)
    d_theta = np.degrees(th_v - th_true)
    d_phi_sin = np.degrees(np.angle(np.exp(1j * (ph_v - ph_true)))) * np.sin(th_true)
    d_energy = energy / e_true - 1
    print("| photon energy, MeV | photons | σ_θ core / rms, deg | σ_φ·sinθ core / rms, deg | σE/E core / rms | "
          "4.2%/E(GeV)^¼ |\n|---|---|---|---|---|---|")
    for lo, hi in [(20, 50), (50, 100), (100, 150), (150, 200), (200, 300), (300, 400), (400, 600)]:
        k = photon & (e_true >= lo) & (e_true < hi)
        if k.sum() < 50:
            continue
        a, b, c = robust(d_theta[k]), robust(d_phi_sin[k]), robust(d_energy[k])
        design = 4.2 / (np.median(e_true[k]) / 1000) ** 0.25
        print(f"| {lo}–{hi} | {k.sum()} | {a[0]:.2f} / {a[1]:.2f} | {b[0]:.2f} / {b[1]:.2f} | "
              f"{100 * c[0]:.1f} % / {100 * c[1]:.1f} % | {design:.1f} % |")
    pion = (np.abs(pdg) == 211) & np.isfinite(theta_ts)
    a = robust(np.degrees(theta_ts[pion] - th_true[pion]))
    b = robust(np.degrees(np.angle(np.exp(1j * (phi_ts[pion] - ph_true[pion])))))
    print(f"\npions ({pion.sum()} tracks): σ_θ core / rms {a[0]:.2f} / {a[1]:.2f} deg, "
          f"σ_φ core / rms {b[0]:.2f} / {b[1]:.2f} deg")


if __name__ == "__main__":
    main()

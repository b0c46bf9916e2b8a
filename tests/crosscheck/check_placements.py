#!/usr/bin/env python3
"""Outside check of `emcalign export` (docs/contract.md §9, §11; docs/apply.md).

For random alignments:
  * JSON: each placement (R, t) moves nominal points exactly as the independent numpy
    transform of spec_reference.py (layer 1 for support sphere 1, layer 3 for sphere 2,
    the μ3 rule included): |R p0 + t − forward(p0)| ≤ 1e-9 cm;
  * GDML: decoded the way Geant4 reads it — M = Rz(z)·Ry(y)·Rx(x) from the angles
    (G4GDMLReadDefine::GetRotationMatrix), the volume placed with M⁻¹ and the position
    (G4GDMLReadStructure::PhysvolRead), mm and deg — it gives the same R and t to 1e-9.

usage: check_placements.py EMCALIGN
"""

import json
import math
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import spec_reference as ref  # noqa: E402


def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    m = np.eye(3)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def geant4_placement(physvol):
    """(R, t in cm) that Geant4's GDML reader gives a <physvol>."""
    pos = physvol.find("position")
    ang = physvol.find("rotation")
    assert pos.get("unit") == "mm" and ang.get("unit") == "deg"
    t = np.array([float(pos.get(k)) for k in "xyz"]) / 10.0
    x, y, z = (float(ang.get(k)) * ref.DEG for k in "xyz")
    m = rot(2, z) @ rot(1, y) @ rot(0, x)
    return np.linalg.inv(m), t


def main():
    emcalign = sys.argv[1]
    rng = np.random.default_rng(20261125)
    worst_json = worst_gdml = 0.0
    checks = 0
    with tempfile.TemporaryDirectory() as d:
        for trial in range(25):
            fit = ref.random_fit(rng)
            # Stay within emcalign's plausibility limits (lengths within ±10 cm).
            params = {"format": "emcalign-alignment/1", "parameters": ref.file_from_fit(fit)}
            p = os.path.join(d, f"p{trial}.json")
            with open(p, "w") as f:
                json.dump(params, f)
            out_json = os.path.join(d, f"pl{trial}.json")
            out_gdml = os.path.join(d, f"pl{trial}.gdml")
            for fmt, out in (("json", out_json), ("gdml", out_gdml)):
                r = subprocess.run([emcalign, "export", "--alignment", p, "--format", fmt, "-o", out],
                                   capture_output=True, text=True)
                if r.returncode != 0:
                    print("export failed:", r.stderr)
                    return 1
            with open(out_json) as f:
                placements = json.load(f)["placements"]
            physvols = {pv.get("name"): pv for pv in ET.parse(out_gdml).getroot().iter("physvol")}
            assert sorted(physvols) == sorted(["sphere1_plus", "sphere1_minus", "sphere2_plus", "sphere2_minus"])
            for q in placements:
                R = np.array(q["rotation"])
                t = np.array(q["translation_cm"])
                s, layer = q["hemisphere"], 1 if q["support"] == 1 else 3
                for _ in range(20):
                    p0 = rng.uniform(-70, 70, 3)
                    worst_json = max(worst_json, float(np.linalg.norm(R @ p0 + t - ref.forward(p0, fit, s, layer))))
                    checks += 1
                name = "sphere%d_%s" % (q["support"], "plus" if s == 1 else "minus")
                G, u = geant4_placement(physvols[name])
                worst_gdml = max(worst_gdml, float(np.abs(G - R).max()), float(np.abs(u - t).max()))
    print(f"{checks} points through the JSON placements: worst deviation from spec_reference {worst_json:.2e} cm")
    print(f"100 GDML physvols decoded as Geant4 reads them: worst deviation from the JSON {worst_gdml:.2e}")
    ok = worst_json <= 1e-9 and worst_gdml <= 1e-9
    print("ok" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

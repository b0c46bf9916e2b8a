#!/usr/bin/python3
"""Compares two HDF5 event files column by column (bench/README.md).

    /usr/bin/python3 bench/compare_event_files.py A.h5 B.h5

For every dataset of /events, /truth and /hits: whether the shapes and the NaN patterns
agree, how many values differ and the largest absolute difference. Used to show that a
change to the simulation's arithmetic gives the same events to rounding (issue 15). Exits 1
when a shape, a NaN pattern or an integer column differs, 2 when a file cannot be read.
"""
import sys

import h5py
import numpy as np


def main(a_path, b_path):
    try:
        a, b = h5py.File(a_path, "r"), h5py.File(b_path, "r")
    except OSError as exc:
        print(f"compare_event_files.py: cannot read the files: {exc}", file=sys.stderr)
        return 2
    status = 0
    for group in ("events", "truth", "hits"):
        if (group in a) != (group in b):
            print(f"/{group}: only in one file")
            status = 1
            continue
        if group not in a:
            continue
        for name in sorted(a[group]):
            x, y = a[group][name][:], b[group][name][:]
            where = f"/{group}/{name}"
            if x.shape != y.shape:
                print(f"{where}: shapes {x.shape} and {y.shape}")
                status = 1
                continue
            if x.dtype.kind == "f":
                nan_x, nan_y = np.isnan(x), np.isnan(y)
                same_nan = bool((nan_x == nan_y).all())
                both = ~(nan_x | nan_y)
                differing = int(np.sum(x[both] != y[both]))
                largest = float(np.max(np.abs(x[both] - y[both]))) if both.any() else 0.0
                print(f"{where}: {differing} of {x.size} differ, largest |difference| {largest:.3g}"
                      + ("" if same_nan else ", NaN patterns DIFFER"))
                status |= 0 if same_nan else 1
            else:
                differing = int(np.sum(x != y))
                print(f"{where}: {differing} of {x.size} differ")
                status |= 1 if differing else 0
    return status


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))

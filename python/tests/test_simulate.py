"""The simulation from Python: the file emcalign simulate writes (byte for byte), or its columns."""

import subprocess

import numpy as np
import pytest

import emcalign
from cli_helpers import CLI, PAPER_LIKE, cli, cli_error

CASES = {
    "ee-h5": ([], {}),
    "gg-ideal-csv": (["--process", "gg", "--ideal"], dict(process="gg", ideal=True)),
    "switches": (["--off", "noise,cosmics", "--dead-counters", "3,5", "--no-hits", "--run", "44", "--theta-min", "50",
                  "--theta-max", "130", "--beam-energy", "500"],
                 dict(off=["noise", "cosmics"], dead_counters=[3, 5], hits=False, run=44, theta_min_deg=50,
                      theta_max_deg=130, beam_energy=500)),
    "3pi-no-dead": (["--process", "3pi", "--dead-counters", "none"], dict(process="3pi", dead_counters=[])),
}


@pytest.mark.parametrize("case", CASES)
def test_simulate_writes_the_cli_file(tmp_path, case):
    args, kwargs = CASES[case]
    suffix = ".csv" if case.endswith("csv") else ".h5"
    ours, theirs = tmp_path / f"py{suffix}", tmp_path / f"cli{suffix}"
    report = emcalign.simulate(PAPER_LIKE, 1500, output=ours, seed=5, **kwargs)
    cli("simulate", "--params", PAPER_LIKE, "--events", "1500", "--seed", "5", *args, "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    assert report["events"] == 1500 and report["rows"] == len(emcalign.read_events(ours)["run"])


def test_columns_are_the_file_read_back(tmp_path, paper_like):
    path = tmp_path / "ev.h5"
    emcalign.simulate(PAPER_LIKE, 1000, output=path, seed=8)
    ev = emcalign.simulate(paper_like, 1000, seed=8, threads=1)  # the truth as numbers, one thread
    back = emcalign.read_events(path)
    assert set(ev) == set(back)
    for key, value in back.items():
        if isinstance(value, dict):
            for sub in value:
                np.testing.assert_array_equal(ev[key][sub], value[sub], err_msg=f"{key}.{sub}")
        else:
            np.testing.assert_array_equal(ev[key], value, err_msg=key)
    np.testing.assert_array_equal(emcalign.simulate(paper_like, 1000, seed=8, threads=2)["phi_emc_rad"],
                                  ev["phi_emc_rad"])
    assert not np.array_equal(emcalign.simulate(paper_like, 1000, seed=9)["phi_emc_rad"][:50],
                              ev["phi_emc_rad"][:50])


def test_refused_simulations(tmp_path):
    out = tmp_path / "x.h5"
    with pytest.raises(emcalign.Error) as ours:
        emcalign.simulate(PAPER_LIKE, 10, theta_min_deg=100, theta_max_deg=140)
    assert str(ours.value) == cli_error("simulate", "--params", PAPER_LIKE, "--events", "10", "--theta-min", "100",
                                        "--theta-max", "140", "-o", out)
    assert not out.exists()
    with pytest.raises(emcalign.Error, match="unknown process"):
        emcalign.simulate(PAPER_LIKE, 10, process="mumu")
    with pytest.raises(emcalign.Error, match="off: "):
        emcalign.simulate(PAPER_LIKE, 10, off=["gravity"])
    with pytest.raises(emcalign.Error, match="12 values"):
        emcalign.simulate(np.zeros(5), 10)
    with pytest.raises(emcalign.Error):  # never over its own truth file
        emcalign.simulate(PAPER_LIKE, 10, output=PAPER_LIKE)
    with pytest.raises(emcalign.Error, match=r"events: -1 is not in \[0, "):
        emcalign.simulate(PAPER_LIKE, -1)


def test_a_truth_file_warns_as_the_cli_does(tmp_path, detector, paper_like):
    overlap = tmp_path / "overlap.json"
    values = paper_like.copy()
    values[emcalign.PARAMETERS.index("dp1")] = -0.2  # cm: the hemispheres overlap
    emcalign.write_alignment(overlap, values, detector)
    _, warnings = emcalign.read_alignment(overlap, detector)
    assert len(warnings) == 1 and "dp1 = -0.2000 cm is negative" in warnings[0]
    with pytest.warns(UserWarning) as caught:
        emcalign.simulate(overlap, 10, seed=1)
    assert [str(w.message) for w in caught] == warnings
    done = subprocess.run([CLI, "simulate", "--params", str(overlap), "--events", "10", "-o", str(tmp_path / "x.csv")],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0 and f"emcalign: warning: {warnings[0]}" in done.stderr

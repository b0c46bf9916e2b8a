"""The Python module against the command-line tool: the same numbers, bit for bit.

Run by ctest (python.pytest) with EMCALIGN_CLI set to the emcalign binary and PYTHONPATH to
build/python.
"""

import csv
import io
import json
import subprocess
import threading

import numpy as np
import pytest

import emcalign
from cli_helpers import CLI, PAPER_LIKE, cli


def test_names_follow_spec(detector):
    assert emcalign.PARAMETERS[0] == "alpha" and emcalign.PARAMETERS[-1] == "beta_rel"
    assert len(emcalign.PARAMETERS) == 12 and len(emcalign.PHYSICAL) == 12
    assert emcalign.DERIVED == ["beta", "psi", "mu", "tau", "dx_rel"]
    units = emcalign.file_units()
    assert units[emcalign.PARAMETERS.index("alpha")] == pytest.approx(np.pi / 180)
    assert units[emcalign.PARAMETERS.index("dx")] == 1.0


def test_read_alignment_is_the_file_in_native_units(detector, paper_like):
    with open(PAPER_LIKE) as f:
        given = json.load(f)["parameters"]
    units = emcalign.file_units()
    for k, name in enumerate(emcalign.PARAMETERS):
        assert paper_like[k] == given[name] * units[k]


def test_physical_round_trip(detector, paper_like):
    phys = emcalign.to_physical(paper_like, detector.r1)
    back = emcalign.from_physical(phys, detector.r1)
    np.testing.assert_allclose(back, paper_like, rtol=0, atol=1e-14)
    # params show --json prints the physical set in file units: the same numbers.
    shown = json.loads(cli("params", "show", PAPER_LIKE, "--json"))["physical"]
    deg = np.pi / 180
    for k, name in enumerate(emcalign.PHYSICAL):
        unit = 1.0 if name in ("dx", "dy", "dz", "dx_rel", "dy_rel", "dz_rel") else deg
        assert phys[k] / unit == pytest.approx(shown[name], rel=1e-15, abs=1e-15), name


def test_counters_are_the_cli_geometry_database(detector, paper_like):
    counters = detector.counters()
    assert counters["centre_cm"].shape == (detector.size, 3)
    rows = list(csv.DictReader(io.StringIO(cli("geometry", "--counters"))))
    assert len(rows) == detector.size
    theta = np.array([float(r["theta_deg"]) for r in rows])
    np.testing.assert_array_equal(np.array([int(r["layer"]) for r in rows]), counters["layer"])
    np.testing.assert_allclose(np.degrees(counters["theta_rad"]), theta, rtol=0, atol=1e-12)
    actual = list(csv.DictReader(io.StringIO(cli("geometry", "--counters", "--params", PAPER_LIKE))))
    centres = detector.aligned_centres(paper_like)
    xyz = np.array([[float(r["x_cm"]), float(r["y_cm"]), float(r["z_cm"])] for r in actual])
    np.testing.assert_allclose(centres, xyz, rtol=0, atol=1e-12)


def test_locate_finds_every_counter_at_its_centre(detector):
    centres = detector.counters()["centre_cm"]
    np.testing.assert_array_equal(detector.locate(centres), np.arange(detector.size))
    assert detector.locate(np.array([[0.0, 0.0, 0.0], [500.0, 0.0, 0.0]])).tolist() == [-1, -1]


def test_transform_is_the_cli_transform_bit_for_bit(detector, paper_like):
    rng = np.random.default_rng(3)
    points = rng.uniform(-60.0, 60.0, size=(200, 3))
    ours = emcalign.forward(detector, paper_like, points)
    text = "x_cm,y_cm,z_cm\n" + "".join(f"{x!r},{y!r},{z!r}\n" for x, y, z in points)
    out = list(csv.DictReader(io.StringIO(cli("transform", "--params", PAPER_LIKE, stdin=text))))
    theirs = np.array([[float(r["x_cm"]), float(r["y_cm"]), float(r["z_cm"])] for r in out])
    np.testing.assert_array_equal(ours, theirs)  # 17 significant digits: exact
    # inverse ∘ forward = identity, hemisphere by hemisphere
    for h in (1, -1):
        mine = points[(points[:, 0] >= 0) == (h == 1)]
        back = emcalign.inverse(detector, paper_like, emcalign.forward(detector, paper_like, mine), h)
        np.testing.assert_allclose(back, mine, rtol=0, atol=1e-12)


def test_read_events_equals_the_csv_the_cli_wrote(sample):
    h5, text = sample
    ev = emcalign.read_events([str(h5)])
    assert set(ev["truth"]) >= {"pdg", "vertex_cm", "shower_centre_cm"}
    assert len(ev["hits"]["counter"]) == ev["hit_count"].sum()
    with open(text) as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    assert len(rows) == len(ev["run"])
    for key in ("run", "event", "charged", "muon_veto"):
        np.testing.assert_array_equal(ev[key], [int(r[key]) for r in rows], err_msg=key)
    for key in ("beam_energy_mev", "z0_cm", "rho_cm", "phi_ts_rad", "theta_ts_rad", "energy_mev",
                "phi_emc_rad", "theta_emc_rad"):
        csv_values = np.array([float(r[key]) if r[key] else np.nan for r in rows])
        np.testing.assert_array_equal(ev[key], csv_values, err_msg=key)  # NaN where CSV is empty
    only = emcalign.read_events([str(h5)], truth=False, hits=False)
    assert "truth" not in only and "hits" not in only
    np.testing.assert_array_equal(only["phi_emc_rad"], ev["phi_emc_rad"])


def test_errors_are_the_cli_messages(tmp_path, detector):
    missing = str(tmp_path / "none.h5")
    with pytest.raises(emcalign.Error) as ours:
        emcalign.read_events([missing])
    assert str(ours.value).startswith(missing)  # the file named first, as every reader does
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "emcalign-alignment/1", "parameters": {"alpha": 1e9}}')
    with pytest.raises(emcalign.Error) as ours:
        emcalign.read_alignment(str(bad), detector)
    done = subprocess.run([CLI, "params", "show", str(bad)], capture_output=True, text=True)
    assert done.returncode == 1
    assert f"emcalign: error: {ours.value}" in done.stderr
    with pytest.raises(emcalign.Error, match="12 values"):
        emcalign.to_physical(np.zeros(11), detector.r1)
    with pytest.raises(emcalign.Error, match=r"\(N, 3\)"):
        emcalign.forward(detector, np.zeros(12), np.zeros((4, 2)))


def test_write_alignment_reads_back(tmp_path, detector, paper_like):
    path = tmp_path / "p.json"
    emcalign.write_alignment(str(path), paper_like, detector)
    back, _ = emcalign.read_alignment(str(path), detector)
    np.testing.assert_allclose(back, paper_like, rtol=1e-15, atol=1e-17)
    assert json.loads(cli("params", "show", str(path), "--json"))["parameters"]["alpha"] == pytest.approx(3.0)


def test_long_calls_release_the_gil(detector, paper_like):
    """Two threads transforming at once give the same answers as one after the other."""
    points = np.random.default_rng(5).uniform(-60.0, 60.0, size=(200000, 3))
    expected = emcalign.forward(detector, paper_like, points)
    results = [None, None]

    def work(k):
        results[k] = emcalign.forward(detector, paper_like, points)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        np.testing.assert_array_equal(r, expected)


@pytest.mark.parametrize("sigma_sys", [None, "auto", 0.15])
def test_fit_writes_the_cli_result_byte_for_byte(tmp_path, detector, fit_sample, sigma_sys):
    args = [] if sigma_sys is None else ["--sigma-sys", str(sigma_sys)]
    result, profile = tmp_path / "r.json", tmp_path / "p.csv"
    done = subprocess.run([CLI, "fit", str(fit_sample), "-o", str(result), "--profile-out", str(profile), *args],
                          capture_output=True, text=True, check=False)
    assert done.returncode in (0, 3), done.stderr
    r = emcalign.fit([str(fit_sample)], detector, sigma_sys=sigma_sys)
    assert r.json == result.read_text()
    assert r.profile_csv == profile.read_text()
    saved = json.loads(r.json)
    assert r.status == saved["status"]
    units = emcalign.file_units()
    for k, name in enumerate(emcalign.PARAMETERS):
        assert r.parameters[k] / units[k] == saved["parameters"][name]
        assert r.errors[k] / units[k] == saved["errors"][name]
    assert r.cut_flow["events read"] == 40000
    value, error = r.derived["dx_rel"]
    assert value == saved["derived"]["dx_rel"]["value"] and error == saved["derived"]["dx_rel"]["error"]
    assert r.covariance.shape == (12, 12) and np.allclose(r.covariance, r.covariance.T, rtol=1e-12, atol=0)
    written = tmp_path / "again.json"
    r.write(str(written))
    assert written.read_text() == result.read_text()


def test_fit_errors_are_the_cli_messages(tmp_path, detector, sample):
    h5, _ = sample
    empty = tmp_path / "few.csv"
    cli("simulate", "--params", PAPER_LIKE, "--events", "5", "--seed", "1", "--process", "gg", "-o", str(empty))
    with pytest.raises(emcalign.Error) as ours:
        emcalign.fit([str(empty)], detector)
    done = subprocess.run([CLI, "fit", str(empty), "-o", str(tmp_path / "r.json")], capture_output=True, text=True)
    assert done.returncode == 1
    assert f"emcalign: error: {ours.value}" in done.stderr
    with pytest.raises(emcalign.Error, match="sigma_sys"):
        emcalign.fit([str(h5)], detector, sigma_sys="spec")


def test_select_gives_the_cut_flow_of_the_fit(detector, fit_sample):
    ev = emcalign.read_events([str(fit_sample)])
    cut = emcalign.select(ev)
    assert cut.shape == ev["run"].shape and set(np.unique(cut)) <= set(range(len(emcalign.CUTS)))
    first_rows = np.ones(len(cut), bool)
    first_rows[1:] = (ev["event"][1:] != ev["event"][:-1]) | (ev["run"][1:] != ev["run"][:-1])
    per_event = cut[first_rows]
    flow = emcalign.fit([str(fit_sample)], detector).cut_flow
    # events left after cut k: those failing a later cut, or none
    for k, name in enumerate(emcalign.CUTS):
        if k == 0:
            assert flow[name] == len(per_event)
        else:
            assert flow[name] == np.count_nonzero((per_event == 0) | (per_event > k)), name
    # a tighter acollinearity cut selects fewer events, never more
    tight = emcalign.select(ev, max_acollinearity_deg=2.0)
    assert np.count_nonzero(tight == 0) < np.count_nonzero(cut == 0)
    assert np.all((tight == 0) <= (cut == 0))
    with pytest.raises(emcalign.Error, match="no column 'z0_cm'"):
        emcalign.select({k: v for k, v in ev.items() if k != "z0_cm"})


def test_read_output_checks_a_file_with_its_kinds_reader(tmp_path, detector, fit_sample):
    r = emcalign.fit([str(fit_sample)], detector)
    path = tmp_path / "r.json"
    r.write(str(path))
    read = emcalign.read_output(str(path))
    assert read == json.loads(path.read_text())
    assert read["status"] == r.status and read["ndf"] == r.ndf
    bad = dict(read)
    bad["errors"] = dict(read["errors"], dz="small")
    path.write_text(json.dumps(bad))
    with pytest.raises(emcalign.Error, match=r"r\.json: key 'errors\.dz': expected a number or null, got string"):
        emcalign.read_output(str(path))
    path.write_text('{"format": "emcalign-trend/1", "iovs": 2, "steps": [{"parameter": "gamma"}]}')
    with pytest.raises(emcalign.Error, match=r"key 'steps\[0\]\.parameter': unknown parameter 'gamma'"):
        emcalign.read_output(str(path))
    path.write_text('{"a": 1}')
    with pytest.raises(emcalign.Error, match="not an output of emcalign"):
        emcalign.read_output(str(path))


def test_profile_columns_are_the_profile_file(tmp_path, detector, fit_sample):
    r = emcalign.fit([str(fit_sample)], detector)
    path = tmp_path / "p.csv"
    path.write_text(r.profile_csv)
    read = emcalign.read_profile(str(path))
    assert len(read["n"]) == 160 and read["used"].sum() == r.bins_used
    for key in ("i_phi", "i_theta", "n", "used"):
        np.testing.assert_array_equal(read[key], r.bins[key], err_msg=key)
    for key in ("phi_mean_rad", "theta_mean_rad", "e_mean_mev", "y_phi", "sigma_phi", "y_theta", "sigma_theta"):
        np.testing.assert_array_equal(read[key], r.bins[key], err_msg=key)  # 17 digits: exact, NaN alike
    with pytest.raises(emcalign.Error, match="header"):
        bad = tmp_path / "bad.csv"
        bad.write_text("a,b\n")
        emcalign.read_profile(str(bad))

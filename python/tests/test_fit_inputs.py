"""The fit with model corrections and of saved profiles, against emcalign fit: byte for byte."""

import json
import math

import pytest

import emcalign
from cli_helpers import CORRECTIONS, GRID, PAPER_LIKE, cli, cli_error


@pytest.mark.parametrize("corrections", [CORRECTIONS, GRID], ids=["file", "grid"])
def test_fit_with_corrections_writes_the_cli_result(tmp_path, fit_sample, corrections):
    result, profile = tmp_path / "r.json", tmp_path / "p.csv"
    cli("fit", fit_sample, "-o", result, "--profile-out", profile, "--corrections", corrections)
    r = emcalign.fit(str(fit_sample), corrections=corrections)
    assert r.json == result.read_text()
    assert r.profile_csv == profile.read_text()
    assert r.corrections["path"] == corrections
    saved = json.loads(r.json)
    assert r.corrections["depth_offset_cm"] == saved["input"]["model_corrections"]["depth_offset_cm"]
    if corrections == GRID:  # interpolated to the sample's energy between two points
        assert r.corrections["interpolation"]["beam_energy_mev"] == 612.5
        assert sum(p["weight"] for p in r.corrections["interpolation"]["points"]) == pytest.approx(1.0)
    else:
        assert r.corrections["interpolation"] is None
    assert r.input_warnings == []
    # the shipped file and grid carry their systematic errors (docs/systematics.md): the same
    # numbers as the result file's, in native units
    for k, name in enumerate(emcalign.PARAMETERS):
        want = saved["systematic_errors"][name] / saved["errors"][name]
        assert r.systematic_errors[k] / r.errors[k] == pytest.approx(want, rel=1e-12)
        assert 0 < saved["systematic_errors"][name] < 0.1
    # the corrections move the result: the test could fail
    plain = emcalign.fit(str(fit_sample))
    assert r.json != plain.json
    assert plain.systematic_errors is None
    # the statistical errors: those of the result file, smaller than the quoted ones (the contract's
    # sigma_sys), none for a saved profile's fit
    for k, name in enumerate(emcalign.PARAMETERS):
        unit = saved["errors"][name] / r.errors[k]
        assert r.statistical_errors[k] * unit == pytest.approx(saved["statistical_errors"][name], rel=1e-12)
        assert 0 < r.statistical_errors[k] < r.errors[k]


def test_fit_of_a_saved_profile_writes_the_cli_result(tmp_path, fit_sample):
    profile, plain = tmp_path / "p.csv", tmp_path / "rp.json"
    cli("fit", fit_sample, "-o", tmp_path / "r.json", "--profile-out", profile)
    cli("fit", "--profile-in", profile, "-o", plain)
    r = emcalign.fit(profile=profile)
    assert r.json == plain.read_text()
    assert r.cut_flow is None and math.isnan(r.sigma_sys) and r.corrections is None
    assert r.statistical_errors is None and "statistical_errors" not in json.loads(r.json)
    # written with corrections: they come again for the depth offset
    weighted, withc = tmp_path / "pc.csv", tmp_path / "rpc.json"
    cli("fit", fit_sample, "-o", tmp_path / "rc.json", "--profile-out", weighted, "--corrections", CORRECTIONS)
    cli("fit", "--profile-in", weighted, "-o", withc, "--corrections", CORRECTIONS)
    assert emcalign.fit(profile=str(weighted), corrections=CORRECTIONS).json == withc.read_text()
    # a grid needs the beam energy, which a profile does not say; the profile says its corrections
    gridded = tmp_path / "pg.csv"
    cli("fit", fit_sample, "-o", tmp_path / "rg.json", "--profile-out", gridded, "--corrections", GRID)
    assert gridded.read_text().startswith("# filled with the corrections sha256 ")
    assert emcalign.fit(fit_sample, corrections=GRID).profile_csv == gridded.read_text()
    cli("fit", "--profile-in", gridded, "-o", withc, "--corrections", GRID, "--beam-energy", "612.5")
    assert emcalign.fit(profile=str(gridded), corrections=GRID, beam_energy=612.5).json == withc.read_text()


def test_refused_profile_fits_give_the_cli_messages(tmp_path, fit_sample):
    profile, weighted = tmp_path / "p.csv", tmp_path / "pc.csv"
    cli("fit", fit_sample, "-o", tmp_path / "r.json", "--profile-out", profile)
    cli("fit", fit_sample, "-o", tmp_path / "rc.json", "--profile-out", weighted, "--corrections", CORRECTIONS)
    out = tmp_path / "never.json"
    cases = [
        (dict(profile=str(profile), sigma_sys=0.1), ["--profile-in", profile, "--sigma-sys", "0.1"]),
        (dict(profile=str(profile), corrections=CORRECTIONS), ["--profile-in", profile, "--corrections", CORRECTIONS]),
        (dict(profile=str(weighted)), ["--profile-in", weighted]),
        (dict(profile=str(weighted), corrections=GRID), ["--profile-in", weighted, "--corrections", GRID]),
        # filled with the single file: the grid's interpolation at 612.5 MeV is other corrections
        (dict(profile=str(weighted), corrections=GRID, beam_energy=612.5),
         ["--profile-in", weighted, "--corrections", GRID, "--beam-energy", "612.5"]),
    ]
    for kwargs, args in cases:
        with pytest.raises(emcalign.Error) as ours:
            emcalign.fit(**kwargs)
        assert str(ours.value) == cli_error("fit", *args, "-o", out), kwargs
    assert not out.exists()
    with pytest.raises(emcalign.Error, match="one of them"):
        emcalign.fit(str(fit_sample), profile=str(profile))
    with pytest.raises(emcalign.Error, match="one of them"):
        emcalign.fit()
    with pytest.raises(emcalign.Error, match="bring their own"):
        emcalign.fit(str(fit_sample), corrections=CORRECTIONS, depth_offset=0.5)


def test_paths_may_be_pathlib_and_a_single_path(fit_sample):
    assert emcalign.fit(fit_sample).json == emcalign.fit([str(fit_sample)]).json


def test_fit_notes_and_the_truth_are_the_cli_report(tmp_path, fit_sample):
    """The notes and the comparison with the truth a simulated file carries, as the CLI prints them."""
    r = emcalign.fit(str(fit_sample))
    assert any("without corrections" in n for n in r.notes)
    truth = r.against_truth
    assert truth is not None and set(emcalign.PARAMETERS) <= set(truth)
    fit, true, difference, pull, unit = truth["dx"]
    assert true == pytest.approx(0.3) and unit == "cm"
    assert difference == pytest.approx(fit - true)
    # the CLI prints the same row
    report = cli("fit", fit_sample, "-o", tmp_path / "r.json")
    row = next(line for line in report.splitlines() if line.startswith("dx ") and "%.5f" % true in line)
    assert "%+.2f" % pull in row
    # the result keeps the notes the CLI printed (the report shows them)
    printed = [line[len("note: "):] for line in report.splitlines() if line.startswith("note: ")]
    assert printed and json.loads((tmp_path / "r.json").read_text())["notes"] == printed
    assert json.loads(r.json)["notes"] == printed
    corrected = emcalign.fit(str(fit_sample), corrections=CORRECTIONS)
    assert not any("without corrections" in n for n in corrected.notes)


def test_fit_and_compare_take_the_columns_of_an_ntuple(tmp_path, fit_sample):
    """Data from the user's own framework (issue 30): a dict of numpy columns, as an ntuple's
    branches give them, fits to the file's result and compares as the file does; the rows get
    the checks a file's rows get."""
    import numpy as np

    ev = emcalign.read_events(fit_sample, truth=False, hits=False)
    from_file = emcalign.fit(str(fit_sample))
    # an ntuple's branches: plain float64 arrays, the event number too
    ntuple = {k: np.asarray(v, dtype=np.float64) for k, v in ev.items()}
    from_dict = emcalign.fit(ntuple)
    np.testing.assert_array_equal(from_dict.parameters, from_file.parameters)
    np.testing.assert_array_equal(from_dict.errors, from_file.errors)
    assert json.loads(from_dict.json)["input"]["files"] == ["events"]
    assert from_dict.against_truth is None and from_file.against_truth is not None  # rows carry no truth

    # the same checks as a file's rows: a value out of range, two samples concatenated
    bad = dict(ntuple, theta_emc_rad=np.where(np.arange(len(ntuple["run"])) == 7, 4.0, ntuple["theta_emc_rad"]))
    with pytest.raises(emcalign.Error, match=r"events: row 7 \(run \d+, event \d+\): column 'theta_emc_rad'"):
        emcalign.fit(bad)
    twice = {k: np.concatenate([v, v]) for k, v in ntuple.items()}
    with pytest.raises(emcalign.Error, match="appears again"):
        emcalign.fit(twice)

    # compare: a dict against a file, the same numbers as two files
    mc = tmp_path / "mc.h5"
    cli("simulate", "--params", PAPER_LIKE, "--events", "40000", "--seed", "12",
        "--theta-min", "40", "--theta-max", "140", "--no-hits", "-o", mc)
    by_files = emcalign.compare(str(fit_sample), str(mc))
    by_dict = emcalign.compare(ntuple, str(mc))
    assert by_dict["p_value"] == by_files["p_value"] and by_dict["chi2"] == by_files["chi2"]
    assert [d["name"] for d in by_dict["distributions"]][:4] == ["dphi", "dtheta", "profile_phi", "profile_theta"]
    assert 0.0 <= by_dict["p_value"] <= 1.0
    cli_out = tmp_path / "cmp"
    cli("compare", "--data", fit_sample, "--mc", mc, "-o", cli_out)
    assert json.loads((cli_out / "compare.json").read_text())["chi2"] == pytest.approx(by_files["chi2"], rel=1e-12)
    with pytest.raises(emcalign.Error, match="the same files"):
        emcalign.compare(str(fit_sample), str(fit_sample))
    # the same events however given (a dict, a copy of it, the file): refused, not p = 1
    for data, same in ((ntuple, dict(ntuple)), (str(fit_sample), ntuple)):
        with pytest.raises(emcalign.Error, match="the same particles: a comparison of a sample with itself"):
            emcalign.compare(data, same)
    with pytest.raises(emcalign.Error, match="mc: event files .* or a dict of event columns, not NoneType"):
        emcalign.compare(ntuple, None)


def test_compare_refuses_what_the_cli_refuses_and_samples_of_other_energies(tmp_path, fit_sample):
    """Issue 43: compare(depth_offset=inf) and beam_energy=nan are refused as fit refuses them,
    not answered; data and MC of different beam energies are refused, naming both; GeV is named."""
    import numpy as np

    mc900 = tmp_path / "mc900.h5"
    cli("simulate", "--params", PAPER_LIKE, "--events", "4000", "--seed", "13", "--beam-energy", "900",
        "--theta-min", "40", "--theta-max", "140", "--no-hits", "-o", mc900)
    with pytest.raises(emcalign.Error, match="depth offset inf cm is beyond"):
        emcalign.compare(str(fit_sample), str(mc900), depth_offset=math.inf)
    with pytest.raises(emcalign.Error, match="depth offset inf cm is beyond"):
        emcalign.fit(str(fit_sample), depth_offset=math.inf)
    with pytest.raises(emcalign.Error, match="beam_energy nan MeV is not a finite beam energy"):
        emcalign.compare(str(fit_sample), str(mc900), beam_energy=math.nan)
    with pytest.raises(emcalign.Error, match="0.6125 MeV is below .*: GeV"):
        emcalign.compare(str(fit_sample), str(mc900), beam_energy=0.6125)
    # 612.5 MeV data against 900 MeV MC: refused, both energies named, as the CLI does
    with pytest.raises(emcalign.Error) as ours:
        emcalign.compare(str(fit_sample), str(mc900))
    assert "the data (beam energies 612.5 MeV) and the MC (beam energies 900 MeV)" in str(ours.value)
    assert str(ours.value) == cli_error("compare", "--data", fit_sample, "--mc", mc900, "-o", tmp_path / "never")
    assert not (tmp_path / "never").exists()
    # an ntuple in GeV (divided by 1000): the beam energy column names the mistake
    ev = emcalign.read_events(fit_sample, truth=False, hits=False)
    gev = {k: np.asarray(v, dtype=np.float64) for k, v in ev.items()}
    gev["beam_energy_mev"] = gev["beam_energy_mev"] / 1000.0
    gev["energy_mev"] = gev["energy_mev"] / 1000.0
    with pytest.raises(emcalign.Error, match=r"events: row 0 .*column 'beam_energy_mev': 0.6125 MeV .*GeV\?"):
        emcalign.fit(gev)
    # the clusters alone in GeV: no event passes, and the message says why
    clusters = {k: np.asarray(v, dtype=np.float64) for k, v in ev.items()}
    clusters["energy_mev"] = clusters["energy_mev"] / 1000.0
    with pytest.raises(emcalign.Error, match=r"cluster energies are about \d+ times below .*GeV\?"):
        emcalign.fit(clusters)


def test_masked_columns_are_missing_values_never_their_data(fit_sample):
    """Issue 43: numpy masked arrays (what awkward and uproot give for optional fields) are read
    as missing values, not by the data under the mask: a masked cluster field of a charged
    particle is an event without its cluster (not selected), a masked run number is refused."""
    import numpy as np

    ev = emcalign.read_events(fit_sample, truth=False, hits=False)
    plain = {k: np.asarray(v) for k, v in ev.items()}
    charged = np.flatnonzero(plain["charged"] == 1)
    hide = np.zeros(len(plain["run"]), dtype=bool)
    hide[charged[:200]] = True
    masked = dict(plain)
    for key in ("energy_mev", "phi_emc_rad", "theta_emc_rad"):
        masked[key] = np.ma.masked_array(plain[key], mask=hide)
    full, partial = emcalign.select(plain), emcalign.select(masked)
    # the selected particles whose clusters are masked now fail the cluster-energy cut (4), as
    # with no cluster; nothing else changes
    touched = hide & (full == 0)
    assert touched.sum() > 50
    assert (partial[touched] == 4).all()
    assert (partial[hide & (full != 0)] == full[hide & (full != 0)]).all()
    changed = partial != full
    assert (changed <= (touched | np.roll(touched, 1) | np.roll(touched, -1))).all()
    # read by their underlying data, the fit would be unchanged: it is not
    assert emcalign.fit(masked).cut_flow != emcalign.fit(plain).cut_flow
    run = dict(plain, run=np.ma.masked_array(plain["run"], mask=hide))
    with pytest.raises(emcalign.Error, match=r"events: row \d+: run is masked \(missing\)"):
        emcalign.fit(run)

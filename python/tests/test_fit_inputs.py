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


def test_fit_of_a_saved_profile_writes_the_cli_result(tmp_path, fit_sample):
    profile, plain = tmp_path / "p.csv", tmp_path / "rp.json"
    cli("fit", fit_sample, "-o", tmp_path / "r.json", "--profile-out", profile)
    cli("fit", "--profile-in", profile, "-o", plain)
    r = emcalign.fit(profile=profile)
    assert r.json == plain.read_text()
    assert r.cut_flow is None and math.isnan(r.sigma_sys) and r.corrections is None
    # written with corrections: they come again for the depth offset
    weighted, withc = tmp_path / "pc.csv", tmp_path / "rpc.json"
    cli("fit", fit_sample, "-o", tmp_path / "rc.json", "--profile-out", weighted, "--corrections", CORRECTIONS)
    cli("fit", "--profile-in", weighted, "-o", withc, "--corrections", CORRECTIONS)
    assert emcalign.fit(profile=str(weighted), corrections=CORRECTIONS).json == withc.read_text()
    # a grid needs the beam energy, which a profile does not say
    cli("fit", "--profile-in", weighted, "-o", withc, "--corrections", GRID, "--beam-energy", "612.5")
    assert emcalign.fit(profile=str(weighted), corrections=GRID, beam_energy=612.5).json == withc.read_text()


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

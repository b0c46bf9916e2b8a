"""Correcting events: files as emcalign correct writes them (byte for byte), and docs/contract.md §9 on columns."""

import numpy as np
import pytest

import emcalign
from cli_helpers import CORRECTIONS, GRID, PAPER_LIKE, cli, cli_error


def test_correct_writes_the_cli_file(tmp_path, sample):
    h5, text = sample
    ours, theirs = tmp_path / "py.h5", tmp_path / "cli.h5"
    report = emcalign.correct(str(h5), str(ours), alignment=PAPER_LIKE)
    cli("correct", h5, "--alignment", PAPER_LIKE, "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    rows = len(emcalign.read_events(str(h5))["run"])
    assert report["method"] == "hits" and report["rows"] == rows and report["hits"] and report["truth"]
    assert 0 < report["clusters"] <= rows and report["warnings"] == [] and report["alignments"] == 1
    # the cluster method with a corrections file's depth offset, CSV out; and with a grid
    for corrections in (CORRECTIONS, GRID):
        ours, theirs = tmp_path / "py.csv", tmp_path / "cli.csv"
        emcalign.correct([text], ours, alignment=PAPER_LIKE, method="clusters", corrections=corrections)
        cli("correct", text, "--alignment", PAPER_LIKE, "--method", "clusters", "--corrections", corrections,
            "-o", theirs)
        assert ours.read_text() == theirs.read_text(), corrections
    # the correction did something: the test could fail
    assert ours.read_text() != text.read_text()


def test_correct_with_a_conditions_tag_writes_the_cli_file(tmp_path, sample):
    h5, _ = sample
    uri = f"sqlite:{tmp_path / 'c.sqlite'}"
    cli("conditions", "init", uri)
    cli("conditions", "put", uri, "--tag", "t", "--runs", "1-10", PAPER_LIKE)
    ours, theirs = tmp_path / "py.h5", tmp_path / "cli.h5"
    report = emcalign.correct(h5, ours, conditions=uri, tag="t")
    cli("correct", h5, "--conditions", uri, "--tag", "t", "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    assert report["alignments"] == 1
    with pytest.raises(emcalign.Error) as e:
        emcalign.correct(h5, tmp_path / "no.h5", conditions=uri, tag="other")
    assert str(e.value) == cli_error("correct", h5, "--conditions", uri, "--tag", "other", "-o", tmp_path / "no.h5")
    assert not (tmp_path / "no.h5").exists()


def test_correct_directions_is_the_cluster_method(tmp_path, sample, paper_like):
    _, text = sample
    corrected = tmp_path / "c.csv"
    cli("correct", text, "--alignment", PAPER_LIKE, "--method", "clusters", "--depth-offset", "0.5", "-o", corrected)
    before, after = emcalign.read_events(text), emcalign.read_events(corrected)
    phi, theta = emcalign.correct_directions(paper_like, before["phi_emc_rad"], before["theta_emc_rad"],
                                             before["energy_mev"], depth_offset=0.5)
    np.testing.assert_array_equal(phi, after["phi_emc_rad"])  # 17 digits in the CSV: exact, NaN alike
    np.testing.assert_array_equal(theta, after["theta_emc_rad"])
    assert np.nanmax(np.abs(phi - before["phi_emc_rad"])) > 1e-4


def test_refused_corrections(tmp_path, sample):
    h5, _ = sample
    with pytest.raises(emcalign.Error, match="one of them"):
        emcalign.correct(h5, tmp_path / "o.h5")
    with pytest.raises(emcalign.Error, match="go together"):
        emcalign.correct(h5, tmp_path / "o.h5", alignment=PAPER_LIKE, tag="t")
    with pytest.raises(emcalign.Error, match="bring their own"):
        emcalign.correct(h5, tmp_path / "o.h5", alignment=PAPER_LIKE, corrections=CORRECTIONS, depth_offset=0.5)
    with pytest.raises(emcalign.Error, match="method"):
        emcalign.correct(h5, tmp_path / "o.h5", alignment=PAPER_LIKE, method="best")
    before = h5.read_bytes()
    with pytest.raises(emcalign.Error):  # never over its own input
        emcalign.correct(h5, h5, alignment=PAPER_LIKE)
    assert h5.read_bytes() == before
    with pytest.raises(emcalign.Error, match="one length"):
        emcalign.correct_directions(np.zeros(12), np.zeros(3), np.zeros(2), np.zeros(3))

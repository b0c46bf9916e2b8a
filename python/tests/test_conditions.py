"""The conditions database from Python and from the command line: one database, the same answers."""

import json

import numpy as np
import pytest

import emcalign
from cli_helpers import PAPER_LIKE, cli, cli_error


@pytest.fixture()
def database(tmp_path, fit_sample):
    """A database with two IOVs of tag "t": the paper-like parameters and a fit result."""
    uri = f"sqlite:{tmp_path / 'c.sqlite'}"
    db = emcalign.Conditions(uri, create=True)
    result = tmp_path / "fit.json"
    emcalign.fit(fit_sample).write(result)
    first = db.put("t", (1, 10), PAPER_LIKE, description="two IOVs")
    second = db.put("t", (11, 20), result)
    assert first["new_tag"] and not second["new_tag"] and first["payload"] != second["payload"]
    assert first["warnings"] == [] and second["warnings"] == []  # the fit's input found: its digest recorded
    return uri, db, result


def test_get_is_the_cli_get(tmp_path, database, paper_like):
    uri, db, result = database
    for run in (3, 10, 11, 20):
        got = db.get("t", run)
        written = tmp_path / f"{run}.json"
        cli("conditions", "get", uri, "--tag", "t", "--run", run, "-o", written)
        assert got["file"] == written.read_text(), run
        assert (got["first_run"], got["last_run"]) == ((1, 10) if run <= 10 else (11, 20))
    np.testing.assert_allclose(db.get("t", 3)["parameters"], paper_like, rtol=1e-15, atol=1e-18)
    fitted = emcalign.read_alignment(str(result), emcalign.Detector())[0]
    np.testing.assert_allclose(db.get("t", 15)["parameters"], fitted, rtol=1e-15, atol=1e-18)


def test_tags_are_the_cli_list(database):
    uri, db, _ = database
    assert db.tags() == json.loads(cli("conditions", "list", uri, "--json"))
    assert db.tag("t") == json.loads(cli("conditions", "list", uri, "--tag", "t", "--json"))
    assert [i["first_run"] for i in db.tag("t")["iovs"]] == [1, 11]
    assert db.tag("t")["description"] == "two IOVs"


def test_refusals_are_the_cli_messages(tmp_path, database):
    uri, db, result = database
    for tag, run in (("t", 30), ("u", 3)):
        with pytest.raises(emcalign.Error) as ours:
            db.get(tag, run)
        assert str(ours.value) == cli_error("conditions", "get", uri, "--tag", tag, "--run", run, "-o",
                                            tmp_path / "x.json")
    with pytest.raises(emcalign.Error) as ours:
        db.tag("u")
    assert str(ours.value) == cli_error("conditions", "list", uri, "--tag", "u")
    db.lock("t")
    with pytest.raises(emcalign.Error) as ours:
        db.put("t", 21, result)
    assert str(ours.value) == cli_error("conditions", "put", uri, "--tag", "t", "--runs", "21", result)
    with pytest.raises(emcalign.Error, match="first <= last"):
        db.put("v", (5, 4), result)
    with pytest.raises(emcalign.Error):
        emcalign.Conditions(f"sqlite:{tmp_path / 'missing.sqlite'}")


def test_diff_export_and_retire_are_the_cli_ones(tmp_path, database):
    uri, db, result = database
    db.put("u", (1, 20), result, description="one IOV of the fit")
    assert db.diff("t", "u") == json.loads(cli("conditions", "diff", uri, "--tag", "t", "--tag", "u", "--json"))
    pairs = db.diff("t", "u")["pairs"]
    assert [(p["first_run"], p["last_run"]) for p in pairs] == [(1, 10), (11, 20)]
    assert pairs[1]["same_payload"] and pairs[1]["parameters"]["dx"]["difference"] == 0.0
    exported = tmp_path / "t.csv"
    cli("conditions", "export", uri, "--tag", "t", "-o", exported)
    assert db.export("t") == exported.read_text()
    rows = [line for line in db.export("t").splitlines() if not line.startswith("#")]
    assert len(rows) == 3 and rows[0].startswith("first_run,last_run,")  # a header and one row per IOV
    db.retire("u", "stored by mistake")
    listed = db.tag("u")
    assert listed["state"] == "invalid" and listed["reason"] == "stored by mistake"
    with pytest.raises(emcalign.Error, match="invalid") as ours:
        db.get("u", 3)
    assert str(ours.value) == cli_error("conditions", "get", uri, "--tag", "u", "--run", 3, "-o", tmp_path / "x.json")
    assert db.diff("t", "u")["pairs"]  # an invalid tag can still be compared
    db.lock("t")
    with pytest.raises(emcalign.Error) as ours:
        db.retire("t")
    assert str(ours.value) == cli_error("conditions", "retire", uri, "--tag", "t")


def test_states_history_and_promotion_are_the_cli_ones(tmp_path, database):
    uri, db, result = database
    assert db.state("t") == "open"
    assert db.state("t", "running") == "running"
    db.put("s", (15, 30), result)
    assert db.state("s", "testing", reason="a look") == "testing"
    with pytest.raises(emcalign.Error, match="cannot become published"):
        db.state("s", "published")
    db.state("s", "validated")
    with pytest.raises(emcalign.Error, match="not at the first safe run 16"):
        db.promote("s", "t", 16)
    assert db.promote("s", "t", 15, dry_run=True)["time"] is None
    p = db.promote("s", "t", 15)
    assert p["last_iov_fate"] == "cut" and p["appended"] == 1
    history = db.history("t")
    assert history == json.loads(cli("conditions", "history", uri, "--tag", "t", "--json"))
    assert [h["change"] for h in history][-2:] == ["state", "promotion"]

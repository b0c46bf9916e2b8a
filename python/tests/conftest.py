"""Fixtures of the Python tests: the detector, the paper-like alignment and samples the CLI wrote."""

import pytest

import emcalign
from cli_helpers import PAPER_LIKE, cli


@pytest.fixture(scope="session")
def detector():
    return emcalign.Detector()


@pytest.fixture(scope="session")
def paper_like(detector):
    values, warnings = emcalign.read_alignment(PAPER_LIKE, detector)
    assert warnings == []
    return values


@pytest.fixture(scope="session")
def sample(tmp_path_factory):
    """A small simulated sample written by the CLI, as HDF5 with hits and as CSV."""
    d = tmp_path_factory.mktemp("events")
    h5, text = d / "ev.h5", d / "ev.csv"
    for out in (h5, text):
        cli("simulate", "--params", PAPER_LIKE, "--events", "3000", "--seed", "7", "-o", str(out))
    return h5, text


@pytest.fixture(scope="session")
def fit_sample(tmp_path_factory):
    """A sample large enough to fit (12 parameters, 160 bins), written by the CLI."""
    d = tmp_path_factory.mktemp("fit")
    h5 = d / "ee.h5"
    cli("simulate", "--params", PAPER_LIKE, "--events", "40000", "--seed", "11", "--theta-min", "40",
        "--theta-max", "140", "--no-hits", "-o", str(h5))
    return h5

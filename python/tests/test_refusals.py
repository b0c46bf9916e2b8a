"""Bad input refused with emcalign.Error or TypeError and a message, nothing written; Ctrl-C honoured.

From a review that tried to break the module: each case here once crashed, hung, gave a wrong
answer, or raised a bare RuntimeError or an empty message.
"""

import _thread
import os
import pathlib
import shutil
import subprocess
import threading
import time

import numpy as np
import pytest

import emcalign
from cli_helpers import CLI, PAPER_LIKE, cli


def test_a_message_quoting_bytes_of_a_binary_file_is_kept(tmp_path, sample):
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\x89\xfe\xff not a profile\n")
    with pytest.raises(emcalign.Error) as e:
        emcalign.fit(profile=binary)  # bytes of no known kind as a profile (CSV): the message quotes them
    assert str(e.value).startswith(str(binary)) and "\\x89" in str(e.value)
    # A file of a known kind is named instead.
    h5, _ = sample
    with pytest.raises(emcalign.Error, match=r"this is an HDF5 file \(an event file\?\), not a profile CSV"):
        emcalign.fit(profile=h5)


def test_paths_that_are_not_utf8_are_refused(tmp_path, sample):
    h5, _ = sample
    odd = os.path.join(os.fsencode(tmp_path), b"fit\xff.h5")
    shutil.copy(h5, odd)
    with pytest.raises(emcalign.Error, match="not valid UTF-8"):
        emcalign.read_events(odd)
    with pytest.raises(emcalign.Error, match="not valid UTF-8"):
        emcalign.fit(odd)
    done = subprocess.run([os.fsencode(CLI), b"fit", odd, b"-o", os.path.join(os.fsencode(tmp_path), b"r.json")],
                          capture_output=True, check=False)
    assert done.returncode == 2 and b"is not valid UTF-8" in done.stderr


def test_depth_offsets_are_checked(tmp_path, sample, paper_like):
    _, text = sample
    for bad in (float("nan"), float("inf"), 1e9):
        with pytest.raises(emcalign.Error, match="depth offset"):
            emcalign.correct(text, tmp_path / "c.csv", alignment=PAPER_LIKE, method="clusters", depth_offset=bad)
        with pytest.raises(emcalign.Error, match="depth offset"):
            emcalign.correct_directions(paper_like, [1.0], [1.0], [500.0], depth_offset=bad)
    assert not (tmp_path / "c.csv").exists()


def test_select_takes_event_numbers_exactly_and_whole_events(fit_sample):
    ev = emcalign.read_events(fit_sample, truth=False, hits=False)
    cut = emcalign.select(ev)
    big = dict(ev, event=ev["event"] + 10**17)  # beyond 2^53: not a double
    np.testing.assert_array_equal(emcalign.select(big), cut)
    as_float = dict(ev, event=ev["event"].astype(float))
    np.testing.assert_array_equal(emcalign.select(as_float), cut)
    shuffled = {k: v[np.random.default_rng(0).permutation(len(v))] for k, v in ev.items()}
    with pytest.raises(emcalign.Error, match="appears again: each event must appear once, its rows together"):
        emcalign.select(shuffled)
    with pytest.raises(emcalign.Error, match="run"):
        emcalign.select(dict(ev, run=np.where(np.arange(len(cut)) == 5, np.nan, ev["run"])))
    with pytest.raises(emcalign.Error, match="run"):
        emcalign.select(dict(ev, run=ev["run"] + 2**40))  # runs are 32-bit (docs/contract.md §6)
    for kwargs in (dict(beam_energy=-1.0), dict(beam_energy=float("nan")), dict(max_abs_z0=-1.0),
                   dict(min_energy_fraction=1.2)):
        with pytest.raises(emcalign.Error):
            emcalign.select(ev, **kwargs)


def test_arguments_of_the_wrong_type_are_type_errors(tmp_path, fit_sample):
    db = emcalign.Conditions(pathlib.Path(tmp_path / "c.sqlite"), create=True)  # a pathlib.Path too
    assert db.put("t", np.int64(5), PAPER_LIKE)["new_tag"]  # numpy integers are run numbers
    assert db.put("t", (np.int32(6), 9), PAPER_LIKE)["payload"]
    assert [(i["first_run"], i["last_run"]) for i in db.tag("t")["iovs"]] == [(5, 5), (6, 9)]
    for runs in ("1-5", (1, 2, 3), True, 2.5):
        with pytest.raises(TypeError):
            db.put("u", runs, PAPER_LIKE)
    with pytest.raises(emcalign.Error, match="tag"):
        db.tag("")
    for sigma_sys in ([0.3], True, {}):
        with pytest.raises(TypeError):
            emcalign.fit(fit_sample, sigma_sys=sigma_sys)
    with pytest.raises(emcalign.Error, match="sigma_sys"):
        emcalign.fit(fit_sample, sigma_sys=50)  # the CLI's limit: 10 deg
    assert emcalign.fit(fit_sample, sigma_sys=np.float32(0.25)).sigma_sys == pytest.approx(np.radians(0.25))
    with pytest.raises(emcalign.Error, match="empty"):
        emcalign.Detector("")
    with pytest.raises(emcalign.Error, match="r1"):
        emcalign.to_physical(np.zeros(12), -5.0)


def test_nothing_is_written_over_an_input(tmp_path, fit_sample, sample):
    h5, _ = sample
    copy = tmp_path / "ev.h5"
    shutil.copy(fit_sample, copy)
    before = copy.read_bytes()
    r = emcalign.fit(copy)
    for write in (r.write, r.write_profile):
        with pytest.raises(emcalign.Error, match="same file as the input"):
            write(copy)
    assert copy.read_bytes() == before
    uri = f"sqlite:{tmp_path / 'c.sqlite'}"
    cli("conditions", "init", uri)
    cli("conditions", "put", uri, "--tag", "t", "--runs", "1-10", PAPER_LIKE)
    db = (tmp_path / "c.sqlite").read_bytes()
    with pytest.raises(emcalign.Error, match="same file as the input conditions"):
        emcalign.correct(h5, tmp_path / "c.sqlite", conditions=uri, tag="t")
    assert (tmp_path / "c.sqlite").read_bytes() == db


def test_ctrl_c_stops_a_simulation_soon(tmp_path, paper_like):
    for output in (None, tmp_path / "big.h5"):
        timer = threading.Timer(0.3, _thread.interrupt_main)
        start = time.monotonic()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            emcalign.simulate(paper_like, 3_000_000, output=output, threads=2)  # ~20 s to the end
        timer.join()
        assert time.monotonic() - start < 5.0
    assert os.listdir(tmp_path) == []  # no file, no temporary


def test_a_truth_of_the_wrong_type_is_a_type_error():
    with pytest.raises(TypeError, match="truth"):
        emcalign.simulate({"alpha": 3.0}, 10)
    with pytest.raises(emcalign.Error, match="not valid UTF-8"):
        emcalign.simulate(b"p\xff.json", 10)  # a bytes path is a path


def test_sizes_beyond_reason_are_refused(paper_like):
    with pytest.raises(emcalign.Error, match="write them to a file"):
        emcalign.simulate(paper_like, 10**8)
    with pytest.raises(emcalign.Error, match="threads"):
        emcalign.simulate(paper_like, 10, threads=100000)
    with pytest.raises(emcalign.Error, match="events"):
        emcalign.simulate(paper_like, 10**11, output="never.h5")


def test_text_with_nul_is_refused_not_cut(tmp_path):
    """lock('base\\x00x') once locked 'base': the C API cut the name at the NUL."""
    db = emcalign.Conditions(tmp_path / "c.sqlite", create=True)
    db.put("base", (1, 10), PAPER_LIKE)
    for call in (lambda: db.lock("base\x00x"), lambda: db.tag("base\x00x"), lambda: db.get("base\x00x", 5)):
        with pytest.raises(emcalign.Error, match="tag"):
            call()
    assert db.tag("base")["state"] == "open"
    with pytest.raises(emcalign.Error, match="NUL"):
        db.put("other", (1, 10), PAPER_LIKE, description="before\x00after")
    assert [t["tag"] for t in db.tags()] == ["base"]


def test_clusters_out_of_range_are_refused(paper_like):
    good = emcalign.correct_directions(paper_like, [1.0, 2.0], [1.0, 1.5], [500.0, np.nan])
    assert np.isfinite(good[0][0]) and good[0][1] == 2.0  # NaN energy: no cluster, left as it is
    for phi, theta, energy, says in ((1.0, 1.0, 0.0, "energy"), (1.0, 1.0, -100.0, "energy"),
                                     (1.0, 1.0, 1e300, "energy"), (1.0, 1.0, np.inf, "energy"),
                                     (1.0, 100.0, 500.0, "theta"), (1.0, -0.1, 500.0, "theta"),
                                     (7.0, 1.0, 500.0, "phi"), (np.nan, 1.0, 500.0, "phi")):
        with pytest.raises(emcalign.Error, match=f"row 1: {says}"):
            emcalign.correct_directions(paper_like, [1.0, phi], [1.0, theta], [500.0, energy])


def test_a_fifo_is_refused_at_once_not_waited_on(tmp_path):
    fifo = tmp_path / "detector.json"
    os.mkfifo(fifo)
    start = time.monotonic()
    with pytest.raises(emcalign.Error, match="FIFO"):
        emcalign.Detector(fifo)
    with pytest.raises(emcalign.Error, match="character device"):
        emcalign.Detector("/dev/zero")
    assert time.monotonic() - start < 5


def test_an_open_database_is_never_written_over(tmp_path, paper_like, fit_sample):
    """A Conditions object holds its SQLite file open: no output of the module may replace it or
    its journals, while it is open (the command-line tool protects every input the same way)."""
    db_path = tmp_path / "c.db"
    db = emcalign.Conditions(db_path, create=True)
    db.put("t", (1, 10), PAPER_LIKE)
    before = db_path.read_bytes()
    r = emcalign.fit(fit_sample)
    for target in (db_path, tmp_path / "c.db-journal", tmp_path / "c.db-wal"):
        with pytest.raises(emcalign.Error, match="input --conditions"):
            r.write(target)
    with pytest.raises(emcalign.Error, match="input --conditions"):
        emcalign.simulate(paper_like, 10, output=db_path)
    assert db_path.read_bytes() == before
    assert not (tmp_path / "c.db-journal").exists()
    del db
    import gc
    gc.collect()
    r.write(tmp_path / "c.db-journal")  # closed: a file like any other
    assert (tmp_path / "c.db-journal").exists()


def test_a_database_address_with_nul_is_refused(tmp_path):
    with pytest.raises(emcalign.Error, match="NUL"):
        emcalign.Conditions(str(tmp_path / "new") + "\x00.db", create=True)
    assert not (tmp_path / "new").exists()

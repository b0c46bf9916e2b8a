"""docs/examples/demo.py, the demo in Python, runs and gives what scripts/demo's commands give."""

import os
import subprocess
import sys

from cli_helpers import CORRECTIONS, PAPER_LIKE, ROOT, cli


def test_the_python_demo_reproduces_the_cli_demo(tmp_path):
    out = tmp_path / "demo"
    done = subprocess.run([sys.executable, os.path.join(ROOT, "docs", "examples", "demo.py"), str(out)],
                          capture_output=True, text=True, check=False, env={**os.environ, "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stderr
    for name in ("profiles.png", "pulls.png", "residuals.png", "conditions.sqlite", "events-corrected.h5"):
        assert (out / name).stat().st_size > 0, name
    # scripts/demo's commands on the same paths: the same files
    events = out / "events.h5"
    cli("simulate", "--process", "ee", "--events", "50000", "--seed", "1", "--theta-min", "40", "--theta-max", "140",
        "--params", PAPER_LIKE, "-o", tmp_path / "cli-events.h5")
    assert events.read_bytes() == (tmp_path / "cli-events.h5").read_bytes()
    cli("fit", events, "-o", tmp_path / "r.json", "--profile-out", tmp_path / "p.csv")
    assert (out / "result.json").read_text() == (tmp_path / "r.json").read_text()
    assert (out / "profile.csv").read_text() == (tmp_path / "p.csv").read_text()
    cli("fit", events, "-o", tmp_path / "rc.json", "--corrections", CORRECTIONS)
    assert (out / "result-corrected.json").read_text() == (tmp_path / "rc.json").read_text()
    assert "corrected         mean dphi" in done.stdout

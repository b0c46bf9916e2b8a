"""What the Python tests share: the command-line tool to compare with, and the files they use."""

import os
import subprocess

CLI = os.environ.get("EMCALIGN_CLI", "emcalign")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PAPER_LIKE = os.path.join(ROOT, "data", "examples", "paper-like.json")
CORRECTIONS = os.path.join(ROOT, "data", "corrections", "ee-612.5MeV-40-140deg.json")
GRID = os.path.join(ROOT, "data", "corrections", "ee-40-140deg")


def cli(*args, stdin=None):
    """Runs the tool, which must succeed; its standard output."""
    done = subprocess.run([CLI, *map(str, args)], input=stdin, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout


def cli_error(*args):
    """Runs the tool, which must fail with exit code 1; its error message (after "emcalign: error: ")."""
    done = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, check=False)
    assert done.returncode == 1, (done.returncode, done.stderr)
    lines = [l for l in done.stderr.splitlines() if l.startswith("emcalign: error: ")]
    assert len(lines) == 1, done.stderr
    return lines[0][len("emcalign: error: "):]

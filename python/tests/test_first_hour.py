"""A newcomer's first hour (issue 29), through the command line: what it says and writes."""

import json

import pytest

import emcalign
from cli_helpers import PAPER_LIKE, cli


def test_a_default_theta_range_is_said(tmp_path):
    """simulate's default theta (10-170 deg) leaves events without rows: the count and the hint are printed."""
    out = cli("simulate", "--params", PAPER_LIKE, "--events", "3000", "--seed", "3", "--no-hits", "-o",
              tmp_path / "ee.h5")
    note = next(line for line in out.splitlines() if line.startswith("note:"))
    assert "have no reconstructed particle" in note and "--theta-min 40 --theta-max 140" in note
    narrow = cli("simulate", "--params", PAPER_LIKE, "--events", "3000", "--seed", "3", "--no-hits",
                 "--theta-min", "40", "--theta-max", "140", "-o", tmp_path / "ee40.h5")
    assert "--theta-min 40" not in narrow


def test_deflate_files_read_back_the_same(tmp_path):
    """--compression deflate: another filter, the same rows."""
    for compression in ("lz4", "deflate"):
        cli("simulate", "--params", PAPER_LIKE, "--events", "500", "--seed", "5", "--compression", compression,
            "-o", tmp_path / f"{compression}.h5")
    lz4 = emcalign.read_events(str(tmp_path / "lz4.h5"))
    deflate = emcalign.read_events(str(tmp_path / "deflate.h5"))
    for column in ("event", "phi_emc_rad", "energy_mev"):
        assert (lz4[column] == deflate[column]).all()
    assert (tmp_path / "lz4.h5").read_bytes() != (tmp_path / "deflate.h5").read_bytes()
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "deflate.h5", "r") as f:
        assert f["events"]["phi_emc_rad"].compression == "gzip"


def test_a_period_is_corrected_one_file_per_run(tmp_path):
    """correct --conditions -o DIR/: one corrected file per run file, under its own name."""
    period = tmp_path / "period.json"
    period.write_text(json.dumps({
        "format": "emcalign-period/1", "first_run": 7, "runs": 3, "events_per_run": 1500, "seed": 2,
        "theta_range_deg": [40, 140], "beam_energy_mev": [{"from_run": 7, "value": 612.5}],
        "segments": [{"from_run": 7, "parameters": {"alpha": 2.8, "dx": 0.3}}]}))
    cli("simulate", "--period", period, "-o", tmp_path / "runs", "--no-hits")
    db = tmp_path / "c.db"
    cli("campaign", tmp_path / "runs", "--conditions", db, "--tag", "t", "--min-events", "1000")
    runs = sorted(str(p) for p in (tmp_path / "runs").glob("run_*.h5"))
    out = cli("correct", *runs, "--conditions", db, "--tag", "t", "-o", str(tmp_path / "corrected") + "/")
    assert "(3 files, one per input)" in out
    for run in runs:
        corrected = tmp_path / "corrected" / run.rsplit("/", 1)[1]
        before, after = emcalign.read_events(run), emcalign.read_events(str(corrected))
        assert (before["event"] == after["event"]).all() and (before["run"] == after["run"]).all()
        assert (before["phi_emc_rad"] != after["phi_emc_rad"]).any()


# The figure of the paper each number names (README, "The paper's figures"), and words one
# of them stands near wherever the tree cites it.
FIGURES = {
    5: ("profile", "ȳ", "y_phi", "y_theta", "fitted model"),
    6: ("simulation", "mc", "data against"),
    7: ("trend", "time evolution", "against run", "run"),
    8: ("before and after", "before/after", "correct", "residual"),
    9: ("γγ", "gg", "acollinearity"),
    10: ("3π", "3pi", "π+π−π0", "kinematic"),
}


def test_one_numbering_of_the_papers_figures():
    """Every 'Fig. N' in the README, the docs, the sources and the scripts names the figure the README's table gives."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    table = dict(re.findall(r"^\| Fig\. (\d+) \| ([^|]+) \|", (root / "README.md").read_text(), re.M))
    assert sorted(map(int, table)) == sorted(FIGURES)
    files = [root / "README.md", *(root / "docs").glob("*.md"), *(root / "scripts").iterdir()]
    for sub in ("src", "include", "apps", "python"):
        files += [p for p in (root / sub).rglob("*") if p.suffix in (".cpp", ".hpp", ".py", ".gp")]
    wrong = []
    for path in files:
        if not path.is_file():
            continue
        text = path.read_text(errors="replace")
        for m in re.finditer(r"\b[Ff]ig(?:ure|\.) (\d+)\b", text):
            n = int(m.group(1))
            near = text[max(0, m.start() - 300):m.end() + 200].lower()
            if n not in FIGURES or not any(word in near for word in FIGURES[n]):
                wrong.append(f"{path.relative_to(root)}: {text[m.start():m.end() + 40]!r}")
    assert not wrong, "\n".join(wrong)


def test_nothing_cites_a_file_outside_the_repository():
    """The repository carries its own contract (docs/contract.md): no source, script, test or
    page cites the specification it was written from, or a path outside the repository.
    The one exception is the embedded detector's name, part of its digest (docs/contract.md §2)."""
    import re
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    allowed = "SND-like default (SPEC §2)"
    outside = re.compile(r"SPEC|STYLE\.md|\.\./shared|(^|[\s\"'`(=])/work/")
    files = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True).stdout.split()
    if not files:  # not a git checkout (a source tarball): every file under the tree
        files = [str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and ".git" not in p.parts]
    this = str(Path(__file__).resolve().relative_to(root))
    cited = []
    for name in files:
        path = root / name
        if name == this or not path.is_file() or path.suffix in (".h5", ".db", ".png", ".gz", ".pdf"):
            continue
        for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if outside.search(line.replace(allowed, "")):
                cited.append(f"{name}:{n}: {line.strip()[:120]}")
    assert not cited, "\n".join(cited)


def test_the_modules_include_only_downwards():
    """The layer order of docs/style.md and the README: a module includes only the modules
    before it (core → geometry → sim → io → calib → apply → conddb → report → validation → page)."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    order = ["core", "geometry", "sim", "io", "calib", "apply", "conddb", "report", "validation", "page"]
    back = []
    for base in (root / "include" / "emcalign", root / "src"):
        for module in order:
            for path in (base / module).rglob("*.[ch]pp"):
                for n, line in enumerate(path.read_text().splitlines(), 1):
                    m = re.match(r'\s*#\s*include\s+"emcalign/(\w+)/', line)
                    if m and (m.group(1) not in order or order.index(m.group(1)) > order.index(module)):
                        back.append(f"{path.relative_to(root)}:{n}: {module} includes {m.group(1)}")
    assert not back, "\n".join(back)
    readme = (root / "README.md").read_text()
    layout = readme[readme.index("## Layout"):]
    places = []
    for m in order:
        found = re.search(rf"`{m}`\s*\(", layout)
        places.append(found.start() if found else -1)
    assert -1 not in places and places == sorted(places), f"the README's layout lists the modules out of order: {places}"
    style = (root / "docs" / "style.md").read_text()
    rows = [style.find(f"| `{m}/` |") for m in order]
    assert -1 not in rows and rows == sorted(rows), f"docs/style.md lists the modules out of order: {rows}"

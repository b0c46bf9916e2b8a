#!/usr/bin/env python3
"""Issue 45: `emcalign prompt` against docs/contract.md §13, a DAQ directory and faults.

    prompt_test.py EMCALIGN [--postgres]

A season of 24 simulated runs (a step of dx at run 10, a jump beyond max_change at run 16, another
beam energy from run 21) is streamed into a watched directory file by file, and checked:
  season      the decisions (the contract's records, significance = |change|/error, the first group's
              nulls), the IOVs tiling the runs, no-update and veto serving the payload in force,
              the update in the first group after the step, the vetoes alerted with their record
  kills       kill -9 at random moments, in --once and loop mode: the tag and decisions.jsonl
              equal to the uninterrupted season's (run in another directory), every veto alerted
  daq         temporaries, --settle, a truncated file quarantined and alerted, then taken when
              completed; a taken file rewritten; the same run twice; a run older than the decided
              ones; a file vanishing after it was taken; a FIFO; a run without selected events;
              a short group at an energy change
  loops       two loops on one tag (one state directory, then two): the second refuses, naming
              the first; SIGTERM ends a loop between steps with exit 0
  full        a state directory that fills (ulimit -f): exit 1, nothing lost, the next run ends
              the season as the uninterrupted one
  promotion   a validated tag promoted into the running one while the loop appends to it (the
              promotion's transaction held open): the loop waits, the tag tiles the runs
  postgres    (with --postgres: a private server of its own) the server stopped during the loop:
              the loop says so and retries, and when it is back ends the season as the reference
Exit 0 when every check holds; each failure is printed.
"""
import json
import os
import random
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "postgres"))

EMCALIGN = ""
FAILURES = []
MIN_EVENTS = 5000

PERIOD = {
    "format": "emcalign-period/1", "name": "prompt-test", "first_run": 1, "runs": 24, "events_per_run": 3000,
    "seed": 11, "theta_range_deg": [40, 140],
    "beam_energy_mev": [{"from_run": 1, "value": 612.5}, {"from_run": 21, "value": 700}],
    "segments": [{"from_run": 1, "parameters": {"alpha": 3.0, "dx": 0.3}},
                 {"from_run": 10, "parameters": {"alpha": 3.0, "dx": 0.42}},
                 {"from_run": 16, "parameters": {"alpha": 3.0, "dx": 1.2}}],
}
THRESHOLDS = {
    "format": "emcalign-thresholds/1",
    "parameters": {"dx": {"min_change": 0.03, "significance": 3, "max_change": 0.5, "max_error": 0.05},
                   "alpha": {"min_change": 0.05, "significance": 3, "max_change": 0.5, "max_error": 0.1}},
}


def check(condition, what):
    if not condition:
        FAILURES.append(what)
        print(f"FAIL {what}")
    return condition


def run(args, cwd, timeout=120, **kw):
    return subprocess.run([EMCALIGN] + args, cwd=cwd, capture_output=True, text=True, timeout=timeout, **kw)


def prompt_args(watch, db, state, extra=(), tag="t"):
    uri = db if "://" in db else "sqlite:" + db
    settle = [] if "--settle" in extra else ["--settle", "0"]
    events = [] if "--min-events" in extra else ["--min-events", str(MIN_EVENTS)]
    return ["prompt", watch, "--conditions", uri, "--tag", tag, "--thresholds", "thr.json", "-o", state,
            *events, *settle, *extra]


def tag_of(db):
    """The IOVs of tag t: [(first, last, payload)]."""
    with sqlite3.connect(db) as c:
        return c.execute("SELECT first_run, last_run, payload FROM emcalign_iovs WHERE tag = 't' "
                         "ORDER BY first_run").fetchall()


def decisions(state):
    with open(os.path.join(state, "decisions.jsonl")) as f:
        return f.read()


class Season:
    """The event files of the season and the uninterrupted reference, made once."""

    def __init__(self, root):
        self.root = root
        with open(os.path.join(root, "period.json"), "w") as f:
            json.dump(PERIOD, f)
        with open(os.path.join(root, "thr.json"), "w") as f:
            json.dump(THRESHOLDS, f)
        r = run(["simulate", "--period", "period.json", "--no-hits", "-o", "period"], root)
        assert r.returncode == 0, r.stderr
        self.files = sorted(f for f in os.listdir(os.path.join(root, "period")) if f.endswith(".h5"))
        assert len(self.files) == 24, self.files

    def stream(self, name, each=lambda: None):
        """Copies the files one by one into NAME/watch, calling `each` after every file."""
        watch = os.path.join(self.root, name, "watch")
        os.makedirs(watch, exist_ok=True)
        for f in self.files:
            shutil.copy(os.path.join(self.root, "period", f), os.path.join(watch, f + ".part"))
            os.rename(os.path.join(watch, f + ".part"), os.path.join(watch, f))  # as a DAQ writer does
            each()
        return watch


def test_season(season):
    d = os.path.join(season.root, "ref")
    os.makedirs(d)
    alerts = os.path.join(d, "alerts.jsonl")

    def once():
        r = run(prompt_args("ref/watch", "ref/c.db", "ref/state", ["--once", "--on-alert", f"cat >> {alerts}"]),
                season.root)
        check(r.returncode == 0, f"season: --once exit {r.returncode}: {r.stderr}")
    season.stream("ref", once)
    lines = decisions(os.path.join(d, "state")).splitlines()
    records = [json.loads(l) for l in lines]
    check(len(records) >= 6, f"season: {len(records)} groups decided")
    keys = ["group", "runs", "beam_energy_mev", "selected_events", "decision", "reasons", "parameters", "payload"]
    for r in records:
        check(all(k in r for k in keys), f"season: a record without the contract's keys: {r}")
        check(set(r["parameters"]) == {"alpha", "dx"}, f"season: the parameters of {r['group']}")
    check([r["group"] for r in records] == list(range(len(records))), "season: groups numbered 0, 1, ...")
    first = records[0]
    check(first["decision"] == "update" and first["parameters"]["dx"]["in_force"] is None and
          first["parameters"]["dx"]["change"] is None and first["parameters"]["dx"]["significance"] is None,
          f"season: the first group: {first}")
    for r in records[1:]:
        p = r["parameters"]["dx"]
        if p["fitted"] is not None:
            check(abs(p["significance"] - abs(p["change"]) / p["error"]) < 1e-9 * max(1, p["significance"]),
                  f"season: significance of group {r['group']}")
    iovs = tag_of(os.path.join(d, "c.db"))
    check(iovs[0][0] == 1, f"season: the first IOV starts at run 1: {iovs}")
    for a, b in zip(iovs, iovs[1:]):
        check(b[0] == a[1] + 1, f"season: IOVs tile the runs: {a} then {b}")
    by_last = {last: payload for _, last, payload in iovs}
    in_force = None
    for r in records:
        check(by_last.get(r["runs"][1]) == r["payload"], f"season: group {r['group']}'s payload in the tag")
        if r["decision"] != "update":
            check(r["payload"] == in_force, f"season: a {r['decision']} serves the payload in force")
        in_force = r["payload"]
    # The step at run 10 (7 σ of a group's error): updated in the first group after it (dx); the
    # jump at 16 vetoed, and every group after it (in force stays the value before the jump).
    step = next(r for r in records if r["runs"][0] >= 10)
    check(step["decision"] == "update" and any(x.startswith("dx") for x in step["reasons"]),
          f"season: the step at run 10 not updated in the first group after it: {step}")
    after_jump = [r for r in records if r["runs"][0] >= 16]
    check(after_jump and all(r["decision"] == "veto" for r in after_jump),
          f"season: the jump beyond max_change not vetoed: {[r['decision'] for r in after_jump]}")
    energies = {r["beam_energy_mev"] for r in records}
    check(energies == {612.5, 700}, f"season: both energies: {energies}")
    check(not any(r["runs"][0] <= 20 < 21 <= r["runs"][1] for r in records), "season: a group across the energies")
    # Every veto alerted with its record, exactly.
    sent = [json.loads(l) for l in open(alerts)] if os.path.exists(alerts) else []
    vetoes = [r for r in records if r["decision"] == "veto"]
    check(sent == vetoes, f"season: the alerts are the vetoes' records ({len(sent)} sent, {len(vetoes)} vetoes)")
    listed = run(["conditions", "list", "sqlite:ref/c.db", "--tag", "t", "--json"], season.root)
    check(listed.returncode == 0 and json.loads(listed.stdout)["state"] == "running",
          f"season: the tag is running: {listed.stdout[:200]}")
    page = open(os.path.join(d, "state", "status.html")).read()
    check("http://" not in page.replace("http://www.w3.org/2000/svg", "") and "<svg" in page,
          "season: status.html self-contained with its figures")
    check_in_browser(os.path.join(d, "state", "status.html"))
    r = run(["report", "--prompt", "ref/state", "-o", "ref/report.html"], season.root)
    check(r.returncode == 0 and "Prompt calibration" in open(os.path.join(d, "report.html")).read(),
          f"season: report --prompt: {r.stderr}")
    season.reference = (iovs, decisions(os.path.join(d, "state")), vetoes)


def check_in_browser(page):
    """status.html rendered by headless Chromium, offline: its figures drawn (not blank)."""
    binary = shutil.which("chromium")
    if binary is None:
        check(False, "chromium not found (scripts/install-deps installs it)")
        return
    shot = page + ".png"
    r = subprocess.run([binary, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        "--host-resolver-rules=MAP * ~NOTFOUND", "--window-size=1000,3000", f"--screenshot={shot}",
                        "file://" + page], capture_output=True, text=True, timeout=120)
    if not check(os.path.exists(shot), f"status.html: no screenshot: {r.stderr[-300:]}"):
        return
    from PIL import Image
    im = Image.open(shot).convert("RGB")
    colours = im.getcolors(1 << 20) or []
    # The decisions' colours: green (update), red (veto) and the IOVs' blue are drawn.
    drawn = {c for _, c in colours}
    check(len(colours) > 50 and (26, 127, 55) in drawn and (207, 34, 46) in drawn and (9, 105, 218) in drawn,
          f"status.html: the figures are not drawn ({len(colours)} colours)")


def test_kills(season):
    for mode, seed in (("once", 1), ("loop", 2)):
        rng = random.Random(seed)
        name = f"kill-{mode}"
        d = os.path.join(season.root, name)
        os.makedirs(d)
        alerts = os.path.join(d, "alerts.jsonl")
        kills = [0]
        extra = ["--on-alert", f"cat >> {alerts}"] + (["--once"] if mode == "once" else ["--poll", "0.05"])

        def each():
            # Started, killed at a random moment, started again: a few times per file.
            for _ in range(2):
                p = subprocess.Popen([EMCALIGN] + prompt_args(f"{name}/watch", f"{name}/c.db", f"{name}/state", extra),
                                     cwd=season.root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                time.sleep(rng.uniform(0.0, 0.1 if mode == "once" else 0.15))
                if p.poll() is None:
                    p.kill()
                    kills[0] += 1
                p.wait()
        season.stream(name, each)
        r = run(prompt_args(f"{name}/watch", f"{name}/c.db", f"{name}/state", ["--once", "--on-alert",
                                                                             f"cat >> {alerts}"]), season.root)
        check(r.returncode == 0, f"kills ({mode}): the last run: {r.stderr}")
        iovs, text, vetoes = season.reference
        check(kills[0] >= 5, f"kills ({mode}): only {kills[0]} kills")
        check(tag_of(os.path.join(d, "c.db")) == iovs, f"kills ({mode}, {kills[0]} kills): the tag differs")
        check(decisions(os.path.join(d, "state")) == text, f"kills ({mode}): decisions.jsonl differs")
        sent = {json.dumps(json.loads(l), sort_keys=True) for l in open(alerts)} if os.path.exists(alerts) else set()
        check({json.dumps(v, sort_keys=True) for v in vetoes} <= sent,
              f"kills ({mode}): a veto not alerted ({len(sent)} alerts, {len(vetoes)} vetoes)")
        print(f"ok   kills ({mode}): {kills[0]} kill -9s, the same tag and decisions")


def test_daq(season):
    d = os.path.join(season.root, "daq")
    watch = os.path.join(d, "watch")
    os.makedirs(watch)
    alerts = os.path.join(d, "alerts.jsonl")
    src = os.path.join(season.root, "period")

    def once(*extra):
        r = run(prompt_args("daq/watch", "daq/c.db", "daq/state", ["--once", "--on-alert", f"cat >> {alerts}",
                                                                   *extra]), season.root, timeout=60)
        check(r.returncode == 0, f"daq: exit {r.returncode}: {r.stderr}")
        return r.stdout

    def quarantined():
        with open(os.path.join(d, "state", "quarantine.json")) as f:
            return {q["file"]: q["reason"] for q in json.load(f)}

    def taken(name):
        with open(os.path.join(d, "state", "state.json")) as f:
            return json.load(f)["files"].get(name, {}).get("status") == "taken"
    # Temporaries are never taken.
    for t in (".run_000001.h5", "run_000001.h5.tmp", "run_000001.h5.part", "run_000001.h5.tmp-77"):
        shutil.copy(os.path.join(src, "run_000001.h5"), os.path.join(watch, t))
    once()
    check(not any(taken(t) for t in os.listdir(watch)), "daq: a temporary was taken")
    for t in os.listdir(watch):
        os.remove(os.path.join(watch, t))
    # --settle: a file just written waits; once older than --settle it is taken.
    shutil.copy(os.path.join(src, "run_000001.h5"), watch)
    once("--settle", "30")
    check(not taken("run_000001.h5"), "daq: a file younger than --settle was taken")
    old = time.time() - 60
    os.utime(os.path.join(watch, "run_000001.h5"), (old, old))
    once("--settle", "30")
    check(taken("run_000001.h5"), "daq: a settled file was not taken")
    # A truncated file: quarantined, alerted with its record; completed later (it changed): taken.
    with open(os.path.join(src, "run_000002.h5"), "rb") as f:
        whole = f.read()
    with open(os.path.join(watch, "run_000002.h5"), "wb") as f:
        f.write(whole[:4000])
    once()
    q = quarantined()
    check("run_000002.h5" in q, f"daq: a truncated file not quarantined: {q}")
    sent = [json.loads(l) for l in open(alerts)] if os.path.exists(alerts) else []
    check({"file": "run_000002.h5", "reason": q.get("run_000002.h5")} in sent,
          "daq: the quarantine not alerted with its record")
    once()
    sent_again = [json.loads(l) for l in open(alerts)]
    check(len(sent_again) == len(sent), "daq: a quarantined file alerted twice")
    with open(os.path.join(watch, "run_000002.h5"), "wb") as f:
        f.write(whole)
    once()
    check(taken("run_000002.h5") and "run_000002.h5" not in quarantined(), "daq: a completed file not taken")
    # The same content twice, and a FIFO: quarantined, no hang.
    shutil.copy(os.path.join(src, "run_000002.h5"), os.path.join(watch, "copy.h5"))
    os.mkfifo(os.path.join(watch, "fifo.h5"))
    once()
    q = quarantined()
    check("copy.h5" in q and "the same content" in q["copy.h5"], f"daq: a copy: {q.get('copy.h5')}")
    check("fifo.h5" in q and "not a regular file" in q["fifo.h5"], f"daq: a FIFO: {q.get('fifo.h5')}")
    # A run without selected events (e+e- -> gamma gamma) is taken and covered by its group's IOV.
    r = run(["simulate", "--process", "gg", "--events", "2000", "--run", "3", "--no-hits", "--params",
             os.path.join(HERE, "..", "..", "data", "examples", "paper-like.json"), "-o", "daq/gg.h5"], season.root)
    check(r.returncode == 0, f"daq: simulate gg: {r.stderr}")
    shutil.copy(os.path.join(d, "gg.h5"), os.path.join(watch, "run_000003.h5"))
    out = once()
    check(taken("run_000003.h5") and "0 selected events" in out, f"daq: a run without selected events: {out}")
    # Runs 4..6: a group closes (run 4's file vanishes once taken: its fill is kept).
    for k in (4, 5, 6):
        shutil.copy(os.path.join(src, f"run_00000{k}.h5"), watch)
        once()
        if k == 4:
            os.remove(os.path.join(watch, "run_000004.h5"))
    records = [json.loads(l) for l in decisions(os.path.join(d, "state")).splitlines()]
    check(records and records[0]["runs"][0] == 1, f"daq: no group decided over runs 1..: {records}")
    # A taken file rewritten with other content: alerted, the content taken is kept.
    before = tag_of(os.path.join(d, "c.db"))
    shutil.copy(os.path.join(src, "run_000007.h5"), os.path.join(watch, "run_000005.h5"))
    out = once()
    check("rewritten after it was taken" in out, f"daq: a rewritten file not said: {out}")
    check(tag_of(os.path.join(d, "c.db")) == before, "daq: a rewritten file changed the tag")
    # The same run in another file, and a run older than the decided ones: quarantined.
    params = ["--params", os.path.join(HERE, "..", "..", "data", "examples", "paper-like.json")]
    r = run(["simulate", "--events", "2000", "--run", "6", "--seed", "99", "--no-hits", *params, "-o",
             "daq/again6.h5"], season.root)
    check(r.returncode == 0, f"daq: simulate run 6: {r.stderr}")
    shutil.copy(os.path.join(d, "again6.h5"), os.path.join(watch, "again6.h5"))
    r = run(["simulate", "--events", "2000", "--run", "0", "--seed", "98", "--no-hits", *params,
             "-o", "daq/old.h5"], season.root)
    check(r.returncode == 0, f"daq: simulate an old run: {r.stderr}")
    shutil.copy(os.path.join(d, "old.h5"), os.path.join(watch, "old.h5"))
    once()
    q = quarantined()
    check("again6.h5" in q and ("taken already" in q["again6.h5"] or "not after the runs decided" in q["again6.h5"]),
          f"daq: the same run twice: {q.get('again6.h5')}")
    check("old.h5" in q and "not after the runs decided" in q["old.h5"], f"daq: an old run: {q.get('old.h5')}")
    # A short group at an energy change: the open runs up to 8 at 612.5 MeV (below half of
    # --min-events 24000: vetoed for too few events), closed by run 21 at 700 MeV.
    for k in (7, 8):
        shutil.copy(os.path.join(src, f"run_00000{k}.h5"), watch)
    shutil.copy(os.path.join(src, "run_000021.h5"), watch)
    os.remove(os.path.join(watch, "run_000005.h5"))  # the rewritten one: not taken again either way
    once("--min-events", "24000")
    records = [json.loads(l) for l in decisions(os.path.join(d, "state")).splitlines()]
    short = [r for r in records if r["runs"][1] == 8]
    check(short and short[0]["decision"] == "veto" and any("too few events" in x for x in short[0]["reasons"]),
          f"daq: a short group at an energy change: {short}")
    print("ok   daq: temporaries, --settle, truncated, completed, copy, FIFO, no selected events, vanished, "
          "rewritten, the same run twice, an old run, a short group")


def test_loops(season):
    d = os.path.join(season.root, "loops")
    os.makedirs(os.path.join(d, "watch"))
    first = subprocess.Popen([EMCALIGN] + prompt_args("loops/watch", "loops/c.db", "loops/a", ["--poll", "0.1"]),
                             cwd=season.root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 20
        while not os.path.exists(os.path.join(d, "a", "status.html")) and time.time() < deadline:
            time.sleep(0.1)
        same = run(prompt_args("loops/watch", "loops/c.db", "loops/a", ["--once"]), season.root)
        check(same.returncode == 1 and f"pid {first.pid}" in same.stderr,
              f"loops: a second loop on the same state directory: {same.returncode} {same.stderr}")
        other = run(prompt_args("loops/watch", "loops/c.db", "loops/b", ["--once"]), season.root)
        check(other.returncode == 1 and f'"pid":{first.pid}' in other.stderr and "another prompt loop" in other.stderr,
              f"loops: a second loop on the same tag: {other.returncode} {other.stderr}")
    finally:
        first.send_signal(signal.SIGTERM)
        out, err = first.communicate(timeout=30)
    check(first.returncode == 0 and "stopped by a signal" in out, f"loops: SIGTERM: {first.returncode} {out} {err}")
    after = run(prompt_args("loops/watch", "loops/c.db", "loops/b", ["--once"]), season.root)
    check(after.returncode == 0, f"loops: a loop after the first ended: {after.stderr}")
    # A tag in another state is refused, and nothing written into it.
    paper = os.path.join(HERE, "..", "..", "data", "examples", "paper-like.json")
    r = run(["conditions", "put", "sqlite:loops/c.db", paper, "--tag", "offline", "--runs", "1-2"], season.root)
    check(r.returncode == 0, f"loops: conditions put: {r.stderr}")
    refused = run(prompt_args("loops/watch", "loops/c.db", "loops/c", ["--once"], tag="offline"), season.root)
    check(refused.returncode == 1 and "is open, not running" in refused.stderr,
          f"loops: an open tag: {refused.returncode} {refused.stderr}")
    print("ok   loops: one loop per tag, SIGTERM between steps, a tag in another state refused")


def test_review(season):
    """What a hostile review found (issue 45): a state directory against another database, names
    that are not UTF-8, dangling links, a lost fill, an alert command that prints without end or
    hangs, a restart with another model, in_force of an unusable fit."""
    d = os.path.join(season.root, "review")
    watch = os.path.join(d, "watch")
    os.makedirs(watch)
    src = os.path.join(season.root, "period")
    for k in (1, 2, 3):
        shutil.copy(os.path.join(src, f"run_00000{k}.h5"), watch)
    r = run(prompt_args("review/watch", "review/c.db", "review/state", ["--once"]), season.root)
    check(r.returncode == 0, f"review: first run: {r.stderr}")
    n = len(decisions(os.path.join(d, "state")).splitlines())
    check(n >= 1, "review: nothing decided")
    # Another database (a typo, a restored copy): refused, decisions.jsonl untouched.
    other = run(prompt_args("review/watch", "review/typo.db", "review/state", ["--once"]), season.root)
    check(other.returncode == 1 and "decisions are in" in other.stderr, f"review: another database: {other.stderr}")
    check(len(decisions(os.path.join(d, "state")).splitlines()) == n, "review: decisions.jsonl changed")
    shutil.copy(os.path.join(d, "c.db"), os.path.join(d, "c.db.saved"))
    os.remove(os.path.join(d, "c.db"))
    gone = run(prompt_args("review/watch", "review/c.db", "review/state", ["--once"]), season.root)
    check(gone.returncode == 1 and "is gone: restore it" in gone.stderr and not os.path.exists(
          os.path.join(d, "c.db")),
          f"review: the database removed: {gone.returncode} {gone.stderr}")
    check(len(decisions(os.path.join(d, "state")).splitlines()) == n, "review: decisions.jsonl emptied")
    for suffix in ("", "-wal", "-shm"):
        if os.path.exists(os.path.join(d, "c.db" + suffix)):
            os.remove(os.path.join(d, "c.db" + suffix))
    # Another database at the same place (the same count of decisions or more, other ones): refused.
    os.makedirs(os.path.join(d, "other", "watch"))
    for k in (1, 2, 3, 4):
        shutil.copy(os.path.join(src, f"run_00000{k}.h5"), os.path.join(d, "other", "watch"))
    r = run(prompt_args("review/other/watch", "review/other/c.db", "review/other/state", ["--once", "--min-events",
                                                                                         "2000"]), season.root)
    shutil.copy(os.path.join(d, "other", "c.db"), os.path.join(d, "c.db"))
    swapped = run(prompt_args("review/watch", "review/c.db", "review/state", ["--once"]), season.root)
    check(swapped.returncode == 1 and "are not those this state directory saw" in swapped.stderr,
          f"review: another database at the same place: {swapped.returncode} {swapped.stderr}")
    check(len(decisions(os.path.join(d, "state")).splitlines()) == n, "review: decisions.jsonl rewritten")
    shutil.copy(os.path.join(d, "c.db.saved"), os.path.join(d, "c.db"))
    # A name that is not UTF-8 and a dangling link: quarantined, the loop goes on.
    with open(os.path.join(watch.encode(), b"bad\xff.h5"), "wb") as f:
        f.write(b"x")
    os.symlink("nowhere.h5", os.path.join(watch, "dangling.h5"))
    for k in (4, 5):
        shutil.copy(os.path.join(src, f"run_00000{k}.h5"), watch)
    # An alert command that prints without end: its output goes nowhere.
    r = run(prompt_args("review/watch", "review/c.db", "review/state",
                        ["--once", "--on-alert", "cat > /dev/null; yes | head -c 100000000"]), season.root)
    check(r.returncode == 0, f"review: not UTF-8, a dangling link, a loud alert: {r.returncode} {r.stderr}")
    with open(os.path.join(d, "state", "quarantine.json")) as f:
        q = {e["file"]: e["reason"] for e in json.load(f)}
    check(any("not UTF-8" in v for v in q.values()) and "dangling.h5" in q, f"review: quarantine: {q}")
    # A kept fill lost: read again from its file (the same content), never a veto.
    with open(os.path.join(d, "state", "state.json")) as f:
        open_runs = [r["run"] for r in json.load(f)["open"]]
    if open_runs:
        os.remove(os.path.join(d, "state", "runs", f"run-{open_runs[0]:09d}.json"))
    # A restart with another model while runs wait: refused.
    corrections = os.path.join(HERE, "..", "..", "data", "corrections", "ee-612.5MeV-40-140deg.json")
    other_model = run(prompt_args("review/watch", "review/c.db", "review/state", ["--once", "--corrections",
                                                                                 corrections]), season.root)
    check(other_model.returncode == 1 and "not yet decided were read with" in other_model.stderr if open_runs
          else True, f"review: another model: {other_model.stderr}")
    for k in (6, 7, 8, 9):
        shutil.copy(os.path.join(src, f"run_00000{k}.h5"), watch)
    r = run(prompt_args("review/watch", "review/c.db", "review/state", ["--once"]), season.root)
    check(r.returncode == 0, f"review: after a lost fill: {r.stderr}")
    records = [json.loads(l) for l in decisions(os.path.join(d, "state")).splitlines()]
    check(all(not any("lost" in x for x in rec["reasons"]) for rec in records), "review: a lost fill vetoed")
    if open_runs:
        check("read again" in r.stdout, f"review: the lost fill not read again: {r.stdout}")
    # An alert command that hangs (and leaves a child): stopped after its time, the loop goes on.
    t0 = time.time()
    subprocess.run(["bash", "-c", f"cp {src}/run_000010.h5 {watch}/x10.h5; head -c 3000 {src}/run_000011.h5 > "
                    f"{watch}/trunc.h5"])
    hang = run(prompt_args("review/watch", "review/c.db", "review/state",
                           ["--once", "--on-alert", "sleep 1000 & sleep 1000"]), season.root, timeout=120)
    check(hang.returncode == 1 and time.time() - t0 < 60, f"review: a hanging alert: {hang.returncode} "
          f"{time.time() - t0:.0f} s {hang.stderr}")
    left = subprocess.run(["pgrep", "-f", "sleep 1000"], capture_output=True, text=True).stdout.split()
    check(not left, f"review: the alert's children left running: {left}")
    for pid in left:
        os.kill(int(pid), signal.SIGKILL)
    # SIGTERM while an alert command runs: the loop ends within seconds (the alert is sent again later).
    os.mkfifo(os.path.join(watch, "fifo2.h5"))
    loop = subprocess.Popen([EMCALIGN] + prompt_args("review/watch", "review/c.db", "review/state",
                                                     ["--poll", "0.2", "--on-alert", "sleep 100"]),
                            cwd=season.root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(3)
    t0 = time.time()
    loop.send_signal(signal.SIGTERM)
    loop.communicate(timeout=60)
    check(loop.returncode == 0 and time.time() - t0 < 5, f"review: SIGTERM during an alert: exit {loop.returncode} "
          f"after {time.time() - t0:.1f} s")
    print("ok   review: another or a removed database refused, names not UTF-8, dangling links, a lost fill, "
          "a loud and a hanging alert, another model")


def test_promotion(season, uri, name):
    """A validated refit promoted into the running tag while the loop appends to it: the promotion
    holds its transaction open (EMCALIGN_FAULT_HOLD_WRITE) while the loop decides groups; the loop
    waits, then goes on after the promoted runs, and the tag tiles the season without overlap."""
    d = os.path.join(season.root, name)
    watch = os.path.join(d, "watch")
    os.makedirs(watch)
    db = uri if "://" in uri else uri[len("sqlite:"):]
    for f in season.files[:12]:
        shutil.copy(os.path.join(season.root, "period", f), watch)
    r = run(prompt_args(f"{name}/watch", db, f"{name}/state", ["--once"], tag="p"), season.root)
    check(r.returncode == 0, f"{name}: --once on runs 1-12: {r.stderr}")
    paper = os.path.join(HERE, "..", "..", "data", "examples", "paper-like.json")
    for args in (["put", uri, paper, "--tag", "S", "--runs", "13-16"], ["state", uri, "--tag", "S", "--set", "testing"],
                 ["state", uri, "--tag", "S", "--set", "validated"]):
        r = run(["conditions", *args], season.root)
        check(r.returncode == 0, f"{name}: conditions {args[0]}: {r.stderr}")
    before = json.loads(run(["conditions", "list", uri, "--tag", "p", "--json"], season.root).stdout)["iovs"]
    check(before and before[-1]["first_run"] < 13, f"{name}: the tag before: {before}")
    marker = os.path.join(d, "holding")
    env = dict(os.environ, EMCALIGN_FAULT_HOLD_WRITE=marker, EMCALIGN_FAULT_HOLD_SECONDS="4")
    promote = subprocess.Popen([EMCALIGN, "conditions", "promote", uri, "--from", "S", "--to", "p",
                                "--first-safe-run", "13"], cwd=season.root, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    loop = None
    try:
        deadline = time.time() + 30
        while not os.path.exists(marker) and time.time() < deadline:
            time.sleep(0.05)
        check(os.path.exists(marker), f"{name}: the promotion never held its write")
        # The rest of the season arrives while the promotion holds its transaction open.
        loop = subprocess.Popen([EMCALIGN] + prompt_args(f"{name}/watch", db, f"{name}/state", ["--poll", "0.1"],
                                                         tag="p"),
                                cwd=season.root, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        for f in season.files[12:]:
            shutil.copy(os.path.join(season.root, "period", f), watch)
        out, err = promote.communicate(timeout=60)
        check(promote.returncode == 0 and "appended (runs 13-16)" in out,
              f"{name}: the promotion: {promote.returncode} {out} {err}")
        # The season's last group (the reference's) decided: the loop went on to the end.
        end = json.loads(season.reference[1].splitlines()[-1])["runs"][1]
        path = os.path.join(d, "state", "decisions.jsonl")
        deadline = time.time() + 120
        last = lambda: json.loads(decisions(os.path.join(d, "state")).splitlines()[-1])["runs"][1]
        while time.time() < deadline and last() < end:
            time.sleep(0.2)
    finally:
        if promote.poll() is None:
            promote.kill()
        if loop is not None:
            loop.send_signal(signal.SIGTERM)
            said, _ = loop.communicate(timeout=60)
            check(loop.returncode == 0, f"{name}: the loop's exit {loop.returncode}: {said[-2000:]}")
    records = [json.loads(l) for l in open(path)]
    check(records[-1]["runs"][1] == end, f"{name}: the loop stopped at {records[-1]['runs']}: {said[-3000:]}")
    # Runs 13-16 were promoted: each one quarantined as covered, or decided without an IOV.
    for run_ in range(13, 17):
        decided = [r for r in records if r["runs"][0] <= run_ <= r["runs"][1]]
        check(f"run {run_} is not after the runs decided already (up to run 16)" in said or
              (decided and all(r["iov"] is None for r in decided)), f"{name}: promoted run {run_}: {decided}")
    iovs = json.loads(run(["conditions", "list", uri, "--tag", "p", "--json"], season.root).stdout)["iovs"]
    spans = [(i["first_run"], i["last_run"]) for i in iovs]
    check(all(b[0] == a[1] + 1 for a, b in zip(spans, spans[1:])) and spans[0][0] == 1,
          f"{name}: the tag does not tile the runs: {spans}")
    check(spans[-1][1] == end, f"{name}: the tag ends at {spans[-1]}, the season's last group at run {end}")
    s = json.loads(run(["conditions", "list", uri, "--tag", "S", "--json"], season.root).stdout)["iovs"][0]
    check((13, 16) in spans and iovs[spans.index((13, 16))]["payload"] == s["payload"],
          f"{name}: the promoted IOV 13-16 is not in the tag: {spans}")
    check([(i["first_run"], i["payload"]) for i in iovs if i["first_run"] < 13] ==
          [(i["first_run"], i["payload"]) for i in before], f"{name}: the IOVs before run 13 changed")
    for r in records:
        if r["iov"] is not None and r["runs"][0] >= 13:
            check(r["iov"][0] > 16, f"{name}: group {r['group']} wrote {r['iov']} into the promoted runs")
    history = json.loads(run(["conditions", "history", uri, "--tag", "p", "--json"], season.root).stdout)
    changes = [h["change"] for h in history]
    at = changes.index("promotion") if "promotion" in changes else -1
    check(at >= 0 and "prompt" in changes[at + 1:] and "prompt" in changes[:at],
          f"{name}: the history does not hold the loop's appends around the promotion: {changes}")
    check([h["time"] for h in history] == sorted(h["time"] for h in history), f"{name}: history not in time order")
    print(f"ok   {name}: a promotion held open while the loop appends: the loop waits, the tag tiles the runs")


def test_full(season):
    d = os.path.join(season.root, "full")
    os.makedirs(d)
    watch = season.stream("full")
    r = subprocess.run(["bash", "-c", "ulimit -f 8; exec \"$@\"", "bash", EMCALIGN] +
                       prompt_args("full/watch", "full/c.db", "full/state", ["--once"]),
                       cwd=season.root, capture_output=True, text=True, timeout=120)
    check(r.returncode == 1 and "error" in r.stderr, f"full: a full state directory: {r.returncode} {r.stderr}")
    r = run(prompt_args("full/watch", "full/c.db", "full/state", ["--once"]), season.root)
    check(r.returncode == 0, f"full: the run after: {r.stderr}")
    iovs, text, _ = season.reference
    check(tag_of(os.path.join(d, "c.db")) == iovs and decisions(os.path.join(d, "state")) == text,
          "full: the season after a full disk differs from the uninterrupted one")
    del watch
    print("ok   full: exit 1 when the disk is full, nothing lost")


def test_postgres(season):
    import pg_server
    private = os.path.join(season.root, "pg.json")
    pg_server.start(private)
    try:
        with open(private) as f:
            uri = json.load(f)["uri"]
        d = os.path.join(season.root, "pg")
        os.makedirs(os.path.join(d, "watch"))
        loop = subprocess.Popen([EMCALIGN] + prompt_args("pg/watch", uri, "pg/state", ["--poll", "0.1"]),
                                cwd=season.root, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            half = len(season.files) // 2
            for k, f in enumerate(season.files):
                if k == half:
                    time.sleep(2.0)
                    pg_server.pause(private)
                shutil.copy(os.path.join(season.root, "period", f), os.path.join(d, "watch"))
            time.sleep(3.0)
            pg_server.resume(private)
            iovs, text, _ = season.reference
            deadline = time.time() + 90
            path = os.path.join(d, "state", "decisions.jsonl")
            while time.time() < deadline and not (os.path.exists(path) and open(path).read() == text):
                time.sleep(0.2)
        finally:
            loop.send_signal(signal.SIGTERM)
            out, _ = loop.communicate(timeout=60)
        check(open(path).read() == text if os.path.exists(path) else False,
              "postgres: the season with the server stopped for a while differs from the reference")
        check("trying again" in out, f"postgres: the loop did not say it waits: {out[-2000:]}")
        check(loop.returncode == 0, f"postgres: exit {loop.returncode}: {out[-3000:]}")
        print("ok   postgres: the server away for a while, nothing lost")
        test_promotion(season, uri, "pgpromo")
    finally:
        pg_server.stop(private)


def main():
    global EMCALIGN
    EMCALIGN = os.path.abspath(sys.argv[1])
    postgres = "--postgres" in sys.argv[2:]
    root = tempfile.mkdtemp(prefix="emcalign-prompt-")
    try:
        season = Season(root)
        test_season(season)
        print(f"ok   season: {len(season.reference[1].splitlines())} groups as docs/contract.md §13 says")
        for t in (test_kills, test_daq, test_loops, test_review, test_full):
            t(season)
        test_promotion(season, "sqlite:promo/c.db", "promo")
        if postgres:
            test_postgres(season)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    if FAILURES:
        print(f"{len(FAILURES)} checks failed")
        return 1
    print("all checks hold")
    return 0


if __name__ == "__main__":
    sys.exit(main())

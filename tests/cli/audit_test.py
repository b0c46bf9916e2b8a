#!/usr/bin/env python3
"""Issue 46: conditions you can audit, through the command line, against docs/contract.md §13.

    audit_test.py EMCALIGN [--postgres]

On an SQLite file (and, with --postgres, on a private PostgreSQL server of its own):
  states      `conditions state` prints and sets; every refused transition exits 1 and leaves the
              tag byte-identical (list --json and history --json); lock = published, retire =
              invalid; writes refused by state
  promotion   refused promotions (not validated, not running, a gap, another first run, N not
              after the first run of R's last IOV) leave both tags byte-identical; --dry-run
              writes nothing; a promotion cuts R's last IOV at N - 1
  history     oldest first, ISO 8601 UTC to the microsecond, user and host, what changed
  snapshots   list, get, export and diff as they were before the promotion
  correct     the conditions_snapshot a correction records reproduces its bytes after the tag
              changed
  upgrade     (SQLite) the fixture made by schema 1 is upgraded on opening, said once
Exit 0 when every check holds; each failure is printed.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "postgres"))
PARAMS = os.path.join(HERE, "..", "..", "data", "examples", "paper-like.json")
EMCALIGN = ""
FAILURES = []
TIME = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z$")


def check(condition, what):
    if not condition:
        FAILURES.append(what)
        print(f"FAIL {what}")
    return condition


def run(args, cwd):
    return subprocess.run([EMCALIGN] + [str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=300)


def ok(args, cwd):
    r = run(args, cwd)
    check(r.returncode == 0, f"{' '.join(map(str, args))}: exit {r.returncode}: {r.stderr}")
    return r


def fixtures(root):
    """Three fit results (payloads A, B, C) and the events of run 50."""
    for name, seed, run_number in (("a", 1, 1), ("b", 2, 2), ("c", 3, 3), ("ev50", 4, 50)):
        ok(["simulate", "--events", 20000, "--seed", seed, "--run", run_number, "--no-hits", "--params", PARAMS,
            "-o", f"{name}.csv"], root)
    for name in "abc":
        ok(["fit", f"{name}.csv", "-o", f"{name}.json"], root)


def state_of(root, uri, tag):
    """Everything a refusal must leave as it was."""
    listed = run(["conditions", "list", uri, "--tag", tag, "--json"], root)
    history = run(["conditions", "history", uri, "--tag", tag, "--json"], root)
    return listed.stdout + history.stdout


def refused(root, uri, args, tags, text, what):
    before = [state_of(root, uri, t) for t in tags]
    r = run(args, root)
    check(r.returncode == 1, f"{what}: exit {r.returncode} (1 expected): {r.stdout}{r.stderr}")
    check(text in r.stderr, f"{what}: '{text}' not in: {r.stderr}")
    check([state_of(root, uri, t) for t in tags] == before, f"{what}: a tag changed")


def test_states(root, uri):
    ok(["conditions", "put", uri, "--tag", "s", "--runs", "1-10", "a.json"], root)
    check(ok(["conditions", "state", uri, "--tag", "s"], root).stdout == "open\n", "states: state prints open")
    refused(root, uri, ["conditions", "state", uri, "--tag", "s", "--set", "validated"], ["s"],
            "cannot become validated", "open -> validated")
    ok(["conditions", "state", uri, "--tag", "s", "--set", "testing", "--reason", "a look"], root)
    refused(root, uri, ["conditions", "put", uri, "--tag", "s", "--runs", "11-20", "b.json"], ["s"], "is testing",
            "a write to a testing tag")
    refused(root, uri, ["conditions", "state", uri, "--tag", "s", "--set", "published"], ["s"],
            "cannot become published", "testing -> published")
    refused(root, uri, ["conditions", "state", uri, "--tag", "s", "--set", "running"], ["s"],
            "cannot become running", "testing -> running")
    ok(["conditions", "state", uri, "--tag", "s", "--set", "validated"], root)
    ok(["conditions", "lock", uri, "--tag", "s"], root)
    check(ok(["conditions", "state", uri, "--tag", "s"], root).stdout == "published\n", "states: lock publishes")
    for to in ("open", "testing", "validated", "running", "invalid"):
        refused(root, uri, ["conditions", "state", uri, "--tag", "s", "--set", to], ["s"], "published is final",
                f"published -> {to}")
    refused(root, uri, ["conditions", "retire", uri, "--tag", "s"], ["s"], "published is final", "retire published")
    ok(["conditions", "put", uri, "--tag", "m", "--runs", "1-10", "a.json"], root)
    ok(["conditions", "retire", uri, "--tag", "m", "--reason", "a mistake"], root)
    listed = json.loads(ok(["conditions", "list", uri, "--json"], root).stdout)
    states = {t["tag"]: t["state"] for t in listed}
    check(states == {"s": "published", "m": "invalid"}, f"states: list --json {states}")
    m = [t for t in listed if t["tag"] == "m"][0]
    check(m.get("reason") == "a mistake", f"states: the reason listed: {m}")
    for to in ("open", "published", "running"):
        refused(root, uri, ["conditions", "state", uri, "--tag", "m", "--set", to], ["m"], "invalid is final",
                f"invalid -> {to}")
    refused(root, uri, ["conditions", "get", uri, "--tag", "m", "--run", 5, "-o", "m.json"], ["m"], "is invalid",
            "get from an invalid tag")
    check(not os.path.exists(os.path.join(root, "m.json")), "states: an invalid tag served")
    r = run(["conditions", "state", uri, "--tag", "s", "--set", "finished"], root)
    check(r.returncode == 2 and "no tag state" in r.stderr, f"states: an unknown state: {r.returncode} {r.stderr}")


def history_of(root, uri, tag):
    return json.loads(ok(["conditions", "history", uri, "--tag", tag, "--json"], root).stdout)


def test_promotion_history_snapshots(root, uri):
    # R: a running tag with one IOV; S: a validated refit from run 40 (two IOVs).
    ok(["conditions", "put", uri, "--tag", "R", "--runs", "1-100", "a.json"], root)
    ok(["conditions", "state", uri, "--tag", "R", "--set", "running"], root)
    ok(["conditions", "put", uri, "--tag", "S", "--runs", "40-60", "b.json"], root)
    ok(["conditions", "put", uri, "--tag", "S", "--runs", "61-200", "c.json"], root)
    ok(["conditions", "put", uri, "--tag", "G", "--runs", "40-50", "b.json"], root)
    ok(["conditions", "put", uri, "--tag", "G", "--runs", "52-60", "c.json"], root)
    ok(["conditions", "put", uri, "--tag", "early", "--runs", "1-60", "b.json"], root)
    for t in ("G", "early"):
        ok(["conditions", "state", uri, "--tag", t, "--set", "testing"], root)
        ok(["conditions", "state", uri, "--tag", t, "--set", "validated"], root)
    promote = ["conditions", "promote", uri, "--to", "R"]
    refused(root, uri, promote + ["--from", "S", "--first-safe-run", 40], ["R", "S"], "only a validated tag",
            "promotion of an open tag")
    ok(["conditions", "state", uri, "--tag", "S", "--set", "testing"], root)
    ok(["conditions", "state", uri, "--tag", "S", "--set", "validated"], root)
    refused(root, uri, promote + ["--from", "S", "--first-safe-run", 39], ["R", "S"], "not at the first safe run",
            "promotion from another run")
    refused(root, uri, promote + ["--from", "G", "--first-safe-run", 40], ["R", "G"], "leave a gap",
            "promotion of a tag with a gap")
    refused(root, uri, promote + ["--from", "early", "--first-safe-run", 1], ["R", "early"], "starts at or after it",
            "promotion before the first safe run")
    refused(root, uri, ["conditions", "promote", uri, "--to", "S", "--from", "early", "--first-safe-run", 1],
            ["S", "early"], "a promotion goes into a running tag", "promotion into a validated tag")
    before = state_of(root, uri, "R")
    dry = ok(promote + ["--from", "S", "--first-safe-run", 40, "--dry-run"], root)
    check("dry run" in dry.stdout and "cut to 1-39" in dry.stdout, f"promotion: --dry-run says: {dry.stdout}")
    check(state_of(root, uri, "R") == before, "promotion: --dry-run wrote")

    # The correction of run 50 before the promotion, with the time it read.
    ok(["correct", "ev50.csv", "--conditions", uri, "--tag", "R", "-o", "before.csv"], root)
    with open(os.path.join(root, "before.csv")) as f:
        record = json.loads(next(l for l in f if l.startswith("# correction:"))[len("# correction:"):])
    snapshot = record.get("conditions_snapshot", "")
    check(TIME.match(snapshot), f"correct: conditions_snapshot {snapshot!r}")
    t0 = history_of(root, uri, "R")[-1]["time"]
    check(snapshot == t0, f"correct: the snapshot {snapshot} is not the tag's last change {t0}")

    r = ok(promote + ["--from", "S", "--first-safe-run", 40], root)
    check("cut to 1-39" in r.stdout, f"promotion: {r.stdout}")
    iovs = json.loads(ok(["conditions", "list", uri, "--tag", "R", "--json"], root).stdout)["iovs"]
    check([(i["first_run"], i["last_run"]) for i in iovs] == [(1, 39), (40, 60), (61, 200)],
          f"promotion: R's IOVs {[(i['first_run'], i['last_run']) for i in iovs]}")
    check(json.loads(ok(["conditions", "list", uri, "--tag", "S", "--json"], root).stdout)["state"] == "validated",
          "promotion: S keeps its state")

    history = history_of(root, uri, "R")
    check([h["change"] for h in history] == ["created", "iov", "state", "promotion"],
          f"history: {[h['change'] for h in history]}")
    check(all(TIME.match(h["time"]) for h in history), "history: times not ISO 8601 UTC to the microsecond")
    check([h["time"] for h in history] == sorted(h["time"] for h in history), "history: not oldest first")
    check(all(h["user"] and h["host"] for h in history), "history: no user or host")
    p = history[-1]
    check(p.get("from") == "S" and p.get("first_safe_run") == 40 and p.get("appended") == 2,
          f"history: the promotion's entry {p}")
    check(history[2].get("from") == "open" and history[2].get("to") == "running", f"history: {history[2]}")
    text = ok(["conditions", "history", uri, "--tag", "R"], root).stdout
    check("promotion" in text and "open -> running" in text, f"history: the text {text}")

    # Snapshots: the database as it was before the promotion (S validated, R as it was).
    t0 = history_of(root, uri, "S")[-1]["time"]
    then = json.loads(ok(["conditions", "list", uri, "--tag", "R", "--json", "--snapshot", t0], root).stdout)
    check([(i["first_run"], i["last_run"]) for i in then["iovs"]] == [(1, 100)], f"snapshot: list {then['iovs']}")
    got = json.loads(ok(["conditions", "get", uri, "--tag", "R", "--run", 50, "-o", "-", "--snapshot", t0],
                        root).stdout)
    now = json.loads(ok(["conditions", "get", uri, "--tag", "R", "--run", 50, "-o", "-"], root).stdout)
    check(got["input"]["payload"] == iovs[0]["payload"] and now["input"]["payload"] == iovs[1]["payload"],
          "snapshot: get of run 50 then and now")
    ok(["conditions", "export", uri, "--tag", "R", "-o", "then.csv", "--snapshot", t0], root)
    with open(os.path.join(root, "then.csv")) as f:
        rows = [l for l in f if l[:1].isdigit()]
    check(len(rows) == 1 and rows[0].startswith("1,100,"), f"snapshot: export {rows}")
    listed_then = json.loads(ok(["conditions", "list", uri, "--json", "--snapshot", t0], root).stdout)
    check("S" in [t["tag"] for t in listed_then], "snapshot: S existed at t0")
    old = json.loads(ok(["conditions", "list", uri, "--json", "--snapshot", "2000-01-01T00:00:00Z"], root).stdout)
    check(old == [], f"snapshot: tags in 2000: {old}")
    diff = json.loads(ok(["conditions", "diff", uri, "--tag", "R", "--tag", "S", "--json", "--snapshot", t0],
                         root).stdout)
    check([(q["first_run"], q["last_run"]) for q in diff["pairs"]] == [(40, 60), (61, 100)],
          f"snapshot: diff {[(q['first_run'], q['last_run']) for q in diff['pairs']]}")
    r = run(["conditions", "list", uri, "--snapshot", "yesterday"], root)
    check(r.returncode == 2 and "not a UTC time" in r.stderr, f"snapshot: a bad time: {r.returncode} {r.stderr}")

    # The correction again: another now; the same bytes from its recorded snapshot.
    ok(["correct", "ev50.csv", "--conditions", uri, "--tag", "R", "-o", "after.csv"], root)
    ok(["correct", "ev50.csv", "--conditions", uri, "--tag", "R", "--snapshot", snapshot, "-o", "again.csv"], root)
    read = lambda n: open(os.path.join(root, n), "rb").read()
    check(read("after.csv") != read("before.csv"), "correct: the promotion changed nothing of run 50")
    check(read("again.csv") == read("before.csv"), "correct: --snapshot did not reproduce the bytes")


def test_upgrade(root):
    shutil.copy(os.path.join(HERE, "..", "fixtures", "conditions-schema1.db"), os.path.join(root, "old.db"))
    first = ok(["conditions", "list", "old.db", "--json"], root)
    check(first.stderr.count("upgraded from schema 1 to 2") == 1, f"upgrade: said {first.stderr!r}")
    states = {t["tag"]: t["state"] for t in json.loads(first.stdout)}
    check(states == {"locked-tag": "published", "open-tag": "open", "prompt-tag": "running",
                     "retired-tag": "invalid"}, f"upgrade: states {states}")
    second = ok(["conditions", "list", "old.db"], root)
    check("upgraded" not in second.stderr, "upgrade: said twice")


def main():
    global EMCALIGN
    EMCALIGN = os.path.abspath(sys.argv[1])
    with_postgres = "--postgres" in sys.argv[2:]
    root = tempfile.mkdtemp(prefix="emcalign-audit-")
    try:
        fixtures(root)
        uris = [("sqlite", "sqlite:" + os.path.join(root, "c.db"))]
        private = os.path.join(root, "pg.json")
        if with_postgres:
            import pg_server
            pg_server.start(private)
            with open(private) as f:
                uris.append(("postgres", json.load(f)["uri"]))
        try:
            for kind, uri in uris:
                print(f"-- {kind}")
                ok(["conditions", "init", uri], root)
                test_states(root, uri)
                test_promotion_history_snapshots(root, uri)
        finally:
            if with_postgres:
                pg_server.stop(private)
        test_upgrade(root)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"{len(FAILURES)} failures" if FAILURES else "all audit checks hold")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())

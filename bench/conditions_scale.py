#!/usr/bin/env python3
"""Issue 46's scale: `conditions diff`, `list`, `export` and `history` of two tags of 10 000 IOVs
each (every IOV its own payload, tag b shifted so that each IOV overlaps two of the other; each
tag's history holds 10 001 changes), as the command line answers them, now and at a snapshot.

    bench/conditions_scale.py [--iovs N] [--postgres] [--repeat K]

Made by build/bin/emcalign_bench_conditions_db; the timings are the median of K runs (wall
clock, output to /dev/null). The goal (docs/performance.md): under 1 s each on a 2-core machine.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
BUILD = os.environ.get("EMCALIGN_BUILD", os.path.join(HERE, "..", "build"))
EMCALIGN = os.environ.get("EMCALIGN", os.path.join(BUILD, "bin", "emcalign"))
MAKE_DB = os.path.join(BUILD, "bin", "emcalign_bench_conditions_db")


def timed(args, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        r = subprocess.run([EMCALIGN] + args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        times.append(time.perf_counter() - start)
        if r.returncode != 0:
            sys.exit(f"{' '.join(args)}: exit {r.returncode}: {r.stderr}")
    return statistics.median(times)


def bench(uri, kind, n, repeat):
    start = time.perf_counter()
    subprocess.run([MAKE_DB, uri, str(n)], check=True, stdout=subprocess.DEVNULL)
    made = time.perf_counter() - start
    history = json.loads(subprocess.run([EMCALIGN, "conditions", "history", uri, "--tag", "a", "--json"],
                                        check=True, capture_output=True, text=True).stdout)
    snapshot = history[len(history) // 2]["time"]  # half of tag a written, none of b
    rows = [
        ("diff", ["conditions", "diff", uri, "--tag", "a", "--tag", "b"]),
        ("diff --json", ["conditions", "diff", uri, "--tag", "a", "--tag", "b", "--json"]),
        ("list", ["conditions", "list", uri]),
        ("list --json", ["conditions", "list", uri, "--json"]),
        ("list --tag a", ["conditions", "list", uri, "--tag", "a"]),
        ("export --tag a", ["conditions", "export", uri, "--tag", "a", "-o", "/dev/null"]),
        ("history --tag a", ["conditions", "history", uri, "--tag", "a"]),
        ("history --tag a --json", ["conditions", "history", uri, "--tag", "a", "--json"]),
        ("list --tag a --snapshot (half)", ["conditions", "list", uri, "--tag", "a", "--snapshot", snapshot]),
        ("get --run 50000 --snapshot", ["conditions", "get", uri, "--tag", "a", "--run", str(5 * n), "-o", "/dev/null",
                                        "--snapshot", snapshot]),
    ]
    print(f"{kind}: two tags of {n} IOVs ({len(history)} changes in a's history) made in {made:.1f} s")
    for name, args in rows:
        t = timed(args, repeat)
        print(f"  {name:<34} {t:6.2f} s{'   over 1 s' if t > 1.0 else ''}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iovs", type=int, default=10000)
    ap.add_argument("--postgres", action="store_true", help="also on a private PostgreSQL server")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="emcalign-scale-") as d:
        bench("sqlite:" + os.path.join(d, "scale.db"), "SQLite", a.iovs, a.repeat)
        if a.postgres:
            sys.path.insert(0, os.path.join(HERE, "..", "tests", "postgres"))
            import pg_server
            state = os.path.join(d, "pg.json")
            pg_server.start(state)
            try:
                with open(state) as f:
                    bench(json.load(f)["uri"], "PostgreSQL", a.iovs, a.repeat)
            finally:
                pg_server.stop(state)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""A season of 1 000 runs streamed into `emcalign prompt` (issue 45; docs/prompt.md, "Measured").

    bench/prompt_season.py [DIR] [--kills N] [--interval SECONDS]
        DIR         work directory (default /tmp/emcalign-prompt-season; about 6 minutes)
        --kills N   the second season's random kill -9s (default 20)
        --sigma-sys auto|DEG   of the validation and the loop (default auto: errors the data's scatter)
        --false-update-rate R  of prompt-thresholds (default 0.01)

The season (built here, seed fixed): 1 000 runs of 8 000 events at three beam energies (612.5 MeV
to run 400, 750 MeV to 700, 900 MeV after), a dx step of +0.1 cm at run 200, an alpha step of
+0.08 deg at run 550, a dy drift of 0.1 cm over runs 800-900, 20 low-statistics runs (1 000
events, runs 451-470), a dead-counter episode (runs 301-350 simulated with 40 more dead counters)
and one corrupt file (run 123 truncated). The thresholds are proposed by `prompt-thresholds`
from a validation of groups of the prompt's size (alpha, dx, dy, dz listed).

1. Streamed: the loop runs (`--poll 0.2 --settle 1`) while the files arrive one every
   --interval seconds (each written as NAME.part and renamed). Measured: the time from the run
   closing a group having settled (its rename + --settle) to the decision printed (median,
   worst); the loop's CPU time; the spurious updates on stable stretches (a group whose runs
   and those of the group before it saw no change of the truth); for each step, how many groups
   after it its update came; the drift followed (the largest |in force − truth| of dy at the end of
   each group during and after it).
2. All at once: the same files, one `--once` run (the processing of a whole season).
3. Killed: the season streamed again with N kill -9s at random moments of the loop (each
   restarted): the tag and decisions.jsonl compared with the first season's.
"""
import argparse
import json
import os
import random
import shutil
import sqlite3
import statistics
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
E = os.environ.get("EMCALIGN", os.path.join(ROOT, "build", "bin", "emcalign"))
GRID = os.path.join(ROOT, "data", "corrections", "ee-40-140deg")
MIN_EVENTS = 30000
SIGMA_SYS = "auto"  # --sigma-sys of the validation and the loop
FALSE_RATE = 0.01  # prompt-thresholds --false-update-rate


def sh(args, cwd, **kw):
    r = subprocess.run([E] + args, cwd=cwd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed: emcalign {' '.join(args)}\n{r.stderr}")
    return r


def period(first, runs, seed, name):
    return {
        "format": "emcalign-period/1", "name": name, "first_run": first, "runs": runs, "events_per_run": 8000,
        "seed": seed, "theta_range_deg": [40, 140],
        "beam_energy_mev": [{"from_run": 1, "value": 612.5}, {"from_run": 401, "value": 750},
                            {"from_run": 451, "value": 750, "events_per_run": 1000},
                            {"from_run": 471, "value": 750}, {"from_run": 701, "value": 900}],
        "segments": [{"from_run": 1, "parameters": {"alpha": 2.9, "dx": 0.3, "dy": 0.05, "dz": 0.1}},
                     {"from_run": 200, "parameters": {"dx": 0.4}},
                     {"from_run": 550, "parameters": {"alpha": 2.98}}],
        "drift": [{"parameter": "dy", "from_run": 800, "to_run": 900, "per_run": 0.001}],
    }


def make_season(d):
    files = os.path.join(d, "season")
    if os.path.exists(os.path.join(files, "ready")):
        return files
    shutil.rmtree(files, ignore_errors=True)
    with open(os.path.join(d, "season.json"), "w") as f:
        json.dump(period(1, 1000, 45, "prompt-season"), f)
    t0 = time.time()
    sh(["simulate", "--period", "season.json", "--no-hits", "-o", "season"], d)
    # The dead-counter episode: runs 301-350 again with 40 more dead counters.
    episode = period(1, 1000, 45, "prompt-season")
    episode.update({"first_run": 301, "runs": 50, "seed": 46,
                    "beam_energy_mev": [{"from_run": 301, "value": 612.5}],
                    "segments": [{"from_run": 301, "parameters": {"alpha": 2.9, "dx": 0.4, "dy": 0.05, "dz": 0.1}}]})
    episode.pop("drift")
    with open(os.path.join(d, "episode.json"), "w") as f:
        json.dump(episode, f)
    dead = ",".join(str(k) for k in range(200, 1000, 20))
    sh(["simulate", "--period", "episode.json", "--no-hits", "--dead-counters", dead, "-o", "episode"], d)
    for k in range(301, 351):
        shutil.copy(os.path.join(d, "episode", f"run_{k:06d}.h5"), os.path.join(files, f"run_{k:06d}.h5"))
    # One corrupt file.
    bad = os.path.join(files, "run_000123.h5")
    with open(bad, "rb") as f:
        head = f.read(20000)
    with open(bad, "wb") as f:
        f.write(head)
    open(os.path.join(files, "ready"), "w").close()
    print(f"season simulated in {time.time() - t0:.0f} s")
    return files


def make_thresholds(d):
    path = os.path.join(d, f"thresholds-{SIGMA_SYS}-{FALSE_RATE:g}.json")
    if not os.path.exists(path) and not os.path.exists(os.path.join(d, f"validation-{SIGMA_SYS}", "table.json")):
        # Groups of the prompt's size: MIN_EVENTS selected events are about 37 500 simulated.
        sh(["validate", "--samples", "40", "--events", "37500", "--corrections",
            os.path.join(ROOT, "data", "corrections", "ee-612.5MeV-40-140deg.json"), "--theta-min", "40",
            "--theta-max", "140", "--sigma-sys", SIGMA_SYS, "-o", f"validation-{SIGMA_SYS}"], d)
    if not os.path.exists(path):
        sh(["prompt-thresholds", f"validation-{SIGMA_SYS}/table.json", "--parameters", "alpha,dx,dy,dz",
            "--false-update-rate", f"{FALSE_RATE:g}", "-o", path], d)
    with open(path) as f:
        return json.load(f)


def prompt_cmd(watch, db, state, extra):
    return [E, "prompt", watch, "--conditions", "sqlite:" + db, "--tag", "prompt", "--thresholds",
            f"thresholds-{SIGMA_SYS}-{FALSE_RATE:g}.json", "--corrections", GRID, "--sigma-sys", SIGMA_SYS, "--min-events",
            str(MIN_EVENTS), "-o", state, *extra]


def stream(d, files, name, interval, on_file=None):
    """Copies the season into NAME/watch one file every `interval` s; returns {run: time settled-from}."""
    watch = os.path.join(d, name, "watch")
    os.makedirs(watch, exist_ok=True)
    arrived = {}
    for f in sorted(x for x in os.listdir(files) if x.endswith(".h5")):
        shutil.copy(os.path.join(files, f), os.path.join(watch, f + ".part"))
        os.rename(os.path.join(watch, f + ".part"), os.path.join(watch, f))
        arrived[int(f[4:10])] = time.time()
        if on_file:
            on_file()
        time.sleep(interval)
    return arrived


def tag_and_decisions(d, name):
    with sqlite3.connect(os.path.join(d, name, "c.db")) as c:
        iovs = c.execute("SELECT first_run, last_run, payload FROM emcalign_iovs WHERE tag = 'prompt' "
                         "ORDER BY first_run").fetchall()
    with open(os.path.join(d, name, "state", "decisions.jsonl")) as f:
        return iovs, f.read()


def first_season(d, files, interval):
    name = "streamed"
    shutil.rmtree(os.path.join(d, name), ignore_errors=True)
    os.makedirs(os.path.join(d, name, "watch"))
    loop = subprocess.Popen(prompt_cmd(f"{name}/watch", f"{name}/c.db", f"{name}/state", ["--poll", "0.2", "--settle", "1"]),
                            cwd=d, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    decided = {}  # group -> (time, last run)

    def read():
        for line in loop.stdout:
            if line.startswith("group "):
                g = int(line.split()[1])
                runs = line.split("(runs ")[1].split(",")[0]
                decided[g] = (time.time(), int(runs.split("-")[1]))
    reader = threading.Thread(target=read)
    reader.start()
    t0 = time.time()
    arrived = stream(d, files, name, interval)
    # The last group stays open (below --min-events): wait for the decisions to stop coming.
    records_path = os.path.join(d, name, "state", "decisions.jsonl")
    last = -1
    while True:
        time.sleep(3)
        n = sum(1 for _ in open(records_path)) if os.path.exists(records_path) else 0
        if n == last:
            break
        last = n
    loop.terminate()
    loop.wait()
    reader.join()
    wall = time.time() - t0
    latencies = []
    for g, (when, last_run) in decided.items():
        if last_run in arrived:
            latencies.append(when - (arrived[last_run] + 1.0))
    return wall, latencies


def cpu_of_once(d, files):
    name = "once"
    shutil.rmtree(os.path.join(d, name), ignore_errors=True)
    os.makedirs(os.path.join(d, name))
    os.symlink(files, os.path.join(d, name, "watch"))
    t0 = time.time()
    before = os.times()
    r = subprocess.run(prompt_cmd(f"{name}/watch", f"{name}/c.db", f"{name}/state", ["--once", "--settle", "0"]),
                       cwd=d, capture_output=True, text=True)
    after = os.times()
    return time.time() - t0, (after.children_user - before.children_user) + (after.children_system -
                                                                             before.children_system), r.returncode


def killed_season(d, files, kills, interval, seed=7):
    name = "killed"
    shutil.rmtree(os.path.join(d, name), ignore_errors=True)
    os.makedirs(os.path.join(d, name, "watch"))
    rng = random.Random(seed)
    n_files = sum(1 for x in os.listdir(files) if x.endswith(".h5"))
    when = set(rng.sample(range(n_files), kills))
    state = {"loop": None, "k": 0, "killed": 0}

    def start():
        state["loop"] = subprocess.Popen(prompt_cmd(f"{name}/watch", f"{name}/c.db", f"{name}/state",
                                                    ["--poll", "0.05", "--settle", "0"]),
                                         cwd=d, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def each():
        if state["k"] in when:
            time.sleep(rng.uniform(0.0, 0.3))
            state["loop"].kill()
            state["loop"].wait()
            state["killed"] += 1
            start()
        state["k"] += 1
    start()
    stream(d, files, name, interval, each)
    time.sleep(5)
    state["loop"].terminate()
    state["loop"].wait()
    return state["killed"]


def truth_of(d):
    with open(os.path.join(d, "season", "truth.json")) as f:
        return {r["run"]: r["parameters"] for r in json.load(f)["runs"]}


def analyse(d, thresholds):
    truth = truth_of(d)
    _, text = tag_and_decisions(d, "streamed")
    records = [json.loads(l) for l in text.splitlines()]
    listed = list(thresholds["parameters"])

    def changed(a, b):  # the truth changed between runs a and b (inclusive)?
        lo = max(min(truth), a)
        return any(truth[r][p] != truth[lo][p] for r in range(lo, b + 1) if r in truth for p in listed)
    # Stable: the truth has not changed since the runs of the group whose payload is in force (the
    # last update before it) to the end of this one: an update there is spurious.
    stable, made = [], None
    for r in records:
        if made is not None and not changed(made["runs"][0], r["runs"][1]):
            stable.append(r)
        if r["decision"] == "update":
            made = r
    spurious = [r for r in stable if r["decision"] == "update"]
    out = {"groups": len(records), "updates": sum(r["decision"] == "update" for r in records),
           "no_updates": sum(r["decision"] == "no-update" for r in records),
           "vetoes": sum(r["decision"] == "veto" for r in records),
           "stable_groups": len(stable), "spurious_updates": len(spurious)}
    for step, parameter in ((200, "dx"), (550, "alpha")):
        after = [r for r in records if r["runs"][0] >= step]
        k = next((i for i, r in enumerate(after) if r["decision"] == "update" and
                  any(x.startswith(parameter) for x in r["reasons"])), None)
        straddling = [r for r in records if r["runs"][0] < step <= r["runs"][1]]
        out[f"step_{parameter}_run_{step}"] = {
            "updated_in_the_group_holding_it": bool(straddling and straddling[0]["decision"] == "update"),
            "groups_after_it_until_updated": None if k is None else k + 1}
    lags = []
    for r in records:
        if 800 <= r["runs"][1] <= 950 and r["parameters"]["dy"]["fitted"] is not None:
            in_force = r["parameters"]["dy"]["fitted"] if r["decision"] == "update" else r["parameters"]["dy"]["in_force"]
            if in_force is not None:
                lags.append(abs(in_force - truth[r["runs"][1]]["dy"]))
    out["drift_dy_largest_lag_cm"] = max(lags) if lags else None
    out["drift_dy_updates"] = sum(1 for r in records if 800 <= r["runs"][1] <= 950 and r["decision"] == "update")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir", nargs="?", default="/tmp/emcalign-prompt-season")
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--interval", type=float, default=0.1)
    ap.add_argument("--sigma-sys", default="auto", help="of the validation and the loop: auto (default) or DEG")
    ap.add_argument("--false-update-rate", type=float, default=0.01, help="of prompt-thresholds (default 0.01)")
    a = ap.parse_args()
    global SIGMA_SYS, FALSE_RATE
    SIGMA_SYS = a.sigma_sys
    FALSE_RATE = a.false_update_rate
    os.makedirs(a.dir, exist_ok=True)
    files = make_season(a.dir)
    thresholds = make_thresholds(a.dir)
    print("thresholds:", json.dumps(thresholds["parameters"]))
    wall, latencies = first_season(a.dir, files, a.interval)
    latencies.sort()
    print(f"streamed: {len(latencies)} groups decided in {wall:.0f} s; decision after the closing run settled: "
          f"median {statistics.median(latencies):.2f} s, worst {max(latencies):.2f} s")
    once_wall, once_cpu, code = cpu_of_once(a.dir, files)
    print(f"all at once (--once): {once_wall:.0f} s wall, {once_cpu:.0f} s CPU, exit {code}")
    print(json.dumps(analyse(a.dir, thresholds), indent=1))
    killed = killed_season(a.dir, files, a.kills, a.interval)
    same = tag_and_decisions(a.dir, "killed") == tag_and_decisions(a.dir, "streamed")
    print(f"killed: {killed} kill -9s; the tag and decisions.jsonl {'equal' if same else 'DIFFER from'} the "
          f"uninterrupted season's")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())

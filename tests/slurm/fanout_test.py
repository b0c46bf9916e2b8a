#!/usr/bin/env python3
"""The fan-outs of issue 31 on the test suite's own Slurm (slurm_server.py): each heavy command's
plan submitted with `emcalign batch submit --wait`, and its outputs compared with the same command
run in one process.

    fanout_test.py CASE EMCALIGN SLURM_STATE [POSTGRES_STATE]

CASE: validate, cancel (a running task cancelled with scancel and the plan completed with
--missing), twice (one task run twice at once), campaign (into PostgreSQL: the same payload
hashes), derive (a two-energy corrections grid: each point's samples, first stage and
response blocks as tasks), systematics (with the reverse study).
Exit 0 when every check holds; the first that fails is printed.
"""
import filecmp
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

PERIOD = {"format": "emcalign-period/1", "first_run": 1, "runs": 12, "events_per_run": [2500, 3500], "seed": 5,
          "theta_range_deg": [40, 140],
          "beam_energy_mev": [{"from_run": 1, "value": 612.5}, {"from_run": 7, "value": 700}],
          "segments": [{"from_run": 1, "parameters": {"alpha": 2.8, "dx": 0.3, "dp1": 0.5}},
                       {"from_run": 5, "parameters": {"dx": 0.8}}]}


class Failed(Exception):
    pass


def check(condition, message):
    if not condition:
        raise Failed(message)


class Case:
    def __init__(self, binary, slurm_state, pg_state, top):
        self.binary = binary
        self.top = top
        with open(slurm_state) as f:
            self.env = {**os.environ, "SLURM_CONF": json.load(f)["conf"]}
        self.pg_state = pg_state

    def run(self, *args, cwd=None, ok=True):
        r = subprocess.run([self.binary, *args], cwd=cwd or self.top, capture_output=True, text=True, env=self.env,
                           timeout=900)
        if ok:
            check(r.returncode == 0, f"emcalign {' '.join(args)}: exit {r.returncode}\n{r.stderr}{r.stdout}")
        return r

    def slurm(self, *args):
        return subprocess.run(list(args), capture_output=True, text=True, env=self.env, timeout=120)

    def submit(self, plan, *extra):
        t0 = time.time()
        r = self.run("batch", "submit", plan, "--wait", "--json", *extra, ok=False)
        check(r.returncode == 0, f"batch submit {plan} --wait: exit {r.returncode}\n{r.stderr}\n"
                                 + self.logs(plan))
        ids = json.loads(r.stdout.strip().splitlines()[0])
        check(isinstance(ids["array_job"], int) and isinstance(ids["finish_job"], int), f"job ids: {r.stdout}")
        print(f"{plan}: array {ids['array_job']}, merge {ids['finish_job']}: {time.time() - t0:.1f} s")
        return ids

    def logs(self, plan):
        work = os.path.join(self.top, os.path.splitext(plan)[0] + ".tasks")
        out = ""
        for log in sorted(glob.glob(os.path.join(work, "*.log"))):
            out += f"--- {log}\n" + open(log).read()[-1500:]
        return out

    def status(self, plan):
        r = self.run("batch", "status", plan, "--json", ok=False)
        j = json.loads(r.stdout)
        check(r.returncode == (0 if not j["missing"] else 1), f"batch status exit {r.returncode} for {j}")
        return j

    def same_files(self, a, b, names):
        for n in names:
            pa, pb = os.path.join(self.top, a, n), os.path.join(self.top, b, n)
            check(os.path.exists(pa), f"{pa}: not written by the fan-out")
            check(filecmp.cmp(pa, pb, shallow=False), f"{pa} differs from the one-process {pb}")

    def no_temporaries(self, directory):
        left = [p for p in glob.glob(os.path.join(self.top, directory, "**", "*"), recursive=True)
                if ".tmp" in os.path.basename(p) or os.path.basename(p).startswith(".emcalign")]
        check(not left, f"temporaries left: {left}")


def case_validate(c):
    args = ["validate", "--samples", "4", "--events", "20000", "--seed", "7"]
    c.run(*args, "-o", "fan", "--plan", "plan.json")
    plan = json.load(open(os.path.join(c.top, "plan.json")))
    check(plan["format"] == "emcalign-plan/1" and plan["command"] == "validate" and len(plan["tasks"]) == 4,
          f"the plan: {plan['format']}, {plan['command']}, {len(plan['tasks'])} tasks")
    c.submit("plan.json")
    j = c.status("plan.json")
    check(j == {**j, "tasks": 4, "done": [0, 1, 2, 3], "missing": []}, f"status after the merge: {j}")
    log = open(os.path.join(c.top, "plan.tasks", "task-2.log")).read()
    for said in ("task 2 of", "sample 2", "writes", "done in", "peak memory"):
        check(said in log, f"task 2's log does not say '{said}':\n{log}")
    c.run(*args, "--threads", "2", "-o", "one")
    c.same_files("fan", "one", ["table.json", "table.md", "plots/pulls.png"] +
                 [f"samples/sample_{i:04d}.json" for i in range(4)])
    # A retried task and a second merge change nothing.
    r = c.run("task", "plan.json", "1")
    check("done already" in r.stdout, f"a retried task: {r.stdout}")


def case_cancel(c):
    args = ["validate", "--samples", "3", "--events", "300000", "--seed", "11"]
    c.run(*args, "-o", "fan", "--plan", "plan.json")
    r = c.run("batch", "submit", "plan.json", "--json")
    ids = json.loads(r.stdout)
    array = ids["array_job"]
    # Cancel task 1 while it runs, and task 2 before it starts (the node runs two at once).
    deadline = time.time() + 120
    while time.time() < deadline:
        q = c.slurm("squeue", "-h", "-j", str(array), "-r", "-o", "%i %T").stdout.split("\n")
        if f"{array}_1 RUNNING" in q:
            break
        time.sleep(0.2)
    else:
        raise Failed(f"task 1 never ran: {q}")
    time.sleep(1.0)  # into its simulation
    c.slurm("scancel", f"{array}_1")
    c.slurm("scancel", f"{array}_2")
    deadline = time.time() + 300
    while c.slurm("squeue", "-h").stdout.strip() and time.time() < deadline:
        time.sleep(0.5)
    check(not c.slurm("squeue", "-h").stdout.strip(), "the queue did not drain (the merge job left waiting?)")
    j = c.status("plan.json")
    check(j["missing"] == [1, 2] and j["done"] == [0], f"status after the cancel: {j}")
    check("1" in j["logs_of_missing"] and "CANCELLED" in j["logs_of_missing"]["1"]["last_line"],
          f"the cancelled task's log: {j['logs_of_missing']}")
    check(not os.path.exists(os.path.join(c.top, "fan", "table.json")), "the merge ran with tasks missing")
    check(not os.path.exists(os.path.join(c.top, "fan", "samples", "sample_0001.json")),
          "the cancelled task left its sample")
    c.no_temporaries("fan")
    r = c.run("finish", "plan.json", ok=False)
    check(r.returncode == 1 and "1-2" in r.stderr, f"finish with tasks missing: exit {r.returncode}: {r.stderr}")
    c.submit("plan.json", "--missing")
    check(c.status("plan.json")["missing"] == [], "tasks still missing after --missing")
    c.run(*args, "--threads", "2", "-o", "one")
    c.same_files("fan", "one", ["table.json", "table.md"] + [f"samples/sample_{i:04d}.json" for i in range(3)])


def case_twice(c):
    args = ["validate", "--samples", "2", "--events", "200000", "--seed", "3"]
    c.run(*args, "-o", "fan", "--plan", "plan.json")
    p = [subprocess.Popen([c.binary, "task", "plan.json", "0"], cwd=c.top, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, env=c.env) for _ in range(2)]
    out = [x.communicate(timeout=600) for x in p]
    check(all(x.returncode == 0 for x in p), f"two copies of task 0: {[x.returncode for x in p]} {out}")
    said = " ".join(o[0] for o in out)
    check(said.count("done in") == 1 and ("meanwhile by another copy" in said or "done already" in said),
          f"two copies of task 0 said: {said}")
    c.run("task", "plan.json", "1")
    c.run("finish", "plan.json")
    c.run(*args, "-o", "one")
    c.same_files("fan", "one", ["table.json", "samples/sample_0000.json", "samples/sample_0001.json"])
    c.no_temporaries("fan")


def case_campaign(c):
    with open(os.path.join(c.top, "s.json"), "w") as f:
        json.dump(PERIOD, f)
    c.run("simulate", "--period", "s.json", "-o", "period", "--no-hits")
    with open(c.pg_state) as f:
        server = json.load(f)["uri"]
    name = f"fanout_{os.getpid()}"
    r = subprocess.run(["psql", server, "-q", "-c", f"CREATE DATABASE {name}"], capture_output=True, text=True)
    check(r.returncode == 0, f"psql: {r.stderr}")
    pg = server.rsplit("/", 1)[0] + "/" + name
    # A password in the address is refused: a plan never holds one.
    with_password = pg.replace("postgres@", "postgres:s3cret@")
    r = c.run("campaign", "period", "--conditions", with_password, "--tag", "fan", "--min-events", "4000", "--plan",
              "bad.json", ok=False)
    check(r.returncode == 1 and "never holds a password" in r.stderr and "s3cret" not in r.stderr
          and not os.path.exists(os.path.join(c.top, "bad.json")), f"a password given to --plan: {r.stderr}")
    c.run("campaign", "period", "--conditions", pg, "--tag", "fan", "--min-events", "4000", "--plan", "plan.json")
    plan = json.load(open(os.path.join(c.top, "plan.json")))
    n = len(plan["tasks"])
    check(n >= 4, f"{n} groups")
    c.submit("plan.json")
    merge = c.run("finish", "plan.json")  # again: the same, nothing to do
    one_process = c.run("campaign", "period", "--conditions", "sqlite:one.db", "--tag", "fan", "--min-events", "4000")
    # The one-process warnings of the groups (a poor fit, a fit outside the validated ranges) come
    # with the merge too, each group's from its task's record (this period's small groups fit
    # outside the validated ranges).
    check("outside the ranges" in one_process.stderr, f"no warning to compare: {one_process.stderr}")
    for text in ("poor fit", "outside the ranges"):
        check((text in one_process.stderr) == (text in merge.stderr),
              f"'{text}': one process\n{one_process.stderr}\nthe merge\n{merge.stderr}")

    def same_payloads():
        fan = json.loads(c.run("conditions", "list", pg, "--tag", "fan", "--json").stdout)
        one = json.loads(c.run("conditions", "list", "sqlite:one.db", "--tag", "fan", "--json").stdout)
        check(len(fan["iovs"]) == n and len(one["iovs"]) == n, f"IOVs: {len(fan['iovs'])}, {len(one['iovs'])}, {n}")
        for a, b in zip(fan["iovs"], one["iovs"]):
            check((a["first_run"], a["last_run"], a["payload"]) == (b["first_run"], b["last_run"], b["payload"]),
                  f"IOV {a['first_run']}-{a['last_run']}: payload {a['payload']} against {b['payload']} in one process")
        return fan

    fan = same_payloads()
    # An IOV removed from the database after the merge: the merge finds it gone, its task counts as
    # missing again, and --missing stores it again.
    gone = fan["iovs"][1]
    r = subprocess.run(["psql", pg, "-q", "-c",
                        f"DELETE FROM emcalign_iovs WHERE tag = 'fan' AND first_run = {gone['first_run']}"],
                       capture_output=True, text=True)
    check(r.returncode == 0, f"psql: {r.stderr}")
    r = c.run("finish", "plan.json", ok=False)
    check(r.returncode == 1 and "task 1 counts as missing again" in r.stderr, f"finish of a removed IOV: {r.stderr}")
    check(c.status("plan.json")["missing"] == [1], "the removed IOV's task is not missing")
    c.submit("plan.json", "--missing")
    same_payloads()


def case_derive(c):
    args = ["derive-corrections", "--ideal", "--events", "20000", "--response-samples", "50",
            "--response-events", "5000", "--beam-energy", "500,700"]
    c.run(*args, "--samples-per-task", "25", "-o", "fan", "--plan", "plan.json")
    plan = json.load(open(os.path.join(c.top, "plan.json")))
    check(len(plan["tasks"]) == 2 * (3 + 1 + 2), f"{len(plan['tasks'])} tasks")
    c.submit("plan.json")
    c.run(*args, "-o", "one")
    c.same_files("fan", "one", ["ee-500MeV.json", "ee-700MeV.json"])


def case_systematics(c):
    c.run("derive-corrections", "--events", "30000", "--response-samples", "0", "-o", "c.json")
    args = ["systematics", "--samples", "2", "--events", "5000", "--variations", "tmax-up",
            "--corrections", "c.json", "--reverse", "--reverse-events", "20000", "--reverse-response-samples", "0"]
    c.run(*args, "-o", "fan", "--plan", "plan.json")
    plan = json.load(open(os.path.join(c.top, "plan.json")))
    check(len(plan["tasks"]) == 2 + 2 * 2 + 2 * 2, f"{len(plan['tasks'])} tasks")
    c.submit("plan.json")
    c.run(*args, "-o", "one")
    c.same_files("fan", "one", ["systematics.json", "systematics.md", "plots/systematics.png",
                                "reverse/corrections/nominal.json", "reverse/corrections/tmax-up.json",
                                "nominal/table.json", "reverse/tmax-up/table.json"])


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    name, binary, slurm_state = sys.argv[1], os.path.abspath(sys.argv[2]), sys.argv[3]
    pg_state = sys.argv[4] if len(sys.argv) > 4 else None
    cases = {"validate": case_validate, "cancel": case_cancel, "twice": case_twice, "campaign": case_campaign,
             "derive": case_derive, "systematics": case_systematics}
    top = tempfile.mkdtemp(prefix=f"emcalign-fanout-{name}-")
    # The validation runs in a directory whose name a shell or sbatch would read as something
    # else (issue 44): on the real Slurm too, nothing but the tasks runs.
    work = os.path.join(top, "it's a $(touch PWNED) `touch PWNED` #dir") if name == "validate" else top
    os.makedirs(work, exist_ok=True)
    try:
        cases[name](Case(binary, slurm_state, pg_state, work))
        pwned = [os.path.join(d, f) for d, _, files in os.walk(top) for f in files if f == "PWNED"]
        check(not pwned, f"a command hidden in a directory's name ran: {pwned}")
    except Failed as e:
        print(f"FAILED ({top} kept): {e}")
        return 1
    shutil.rmtree(top, ignore_errors=True)
    print(f"{name}: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())

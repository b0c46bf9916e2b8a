#!/usr/bin/env python3
"""Issue 44: nothing but a plan's tasks runs from its job-array script, whatever its paths hold.

    script_names_test.py EMCALIGN

A small validation plan is made in directories whose names hold what a shell or sbatch would
read as something else — `$(…)`, backticks, quotes, spaces, '#', ';', '&&', '*', '%' — and
submitted with `emcalign batch submit` to a stub `sbatch` that reads the script's #SBATCH lines
as Slurm's sbatch does (src/sbatch/opt.c: words split at white space, '"' and "'" as quotes,
'\\' as an escape, an unescaped '#' a comment, the block ending at the first line that is no
comment; "hetjob"/"packjob" starting another job component) and runs the job array and then the
merge in the directory and with the output file their options give. Checked: every directive is
the plan's own, each task's log is where the script says, the merge's outputs are the
one-process command's, and no command hidden in a name ran (no file PWNED anywhere). The
comments' suggested merge command is run too. A newline or "hetjob" in a name is refused, where
the plan is written and where a copy of it is read.
Exit 0 when every check holds; the first that fails is printed.
"""
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

STUB = r'''#!/usr/bin/env python3
# A stub sbatch: Slurm's #SBATCH parsing, the job run at once (an array task by task).
import json, os, subprocess, sys, tempfile

def get_argument(line):
    """One word of an #SBATCH line, as sbatch's _get_argument reads it: (word, characters used)."""
    i = 0
    while i < len(line) and line[i].isspace():
        i += 1
    if i == len(line):
        return None, i
    word, quoted, q, escape = [], False, "", False
    while i < len(line) and (quoted or not line[i].isspace()) and line[i] != "\n":
        c = line[i]
        if escape:
            escape = False
        elif c == "\\":
            escape = True
            i += 1
            continue
        elif quoted:
            if c == q:
                quoted = False
                i += 1
                continue
        elif c in "\"'":
            quoted, q = True, c
            i += 1
            continue
        elif c == "#":
            break
        word.append(c)
        i += 1
    if quoted:
        sys.exit(f"sbatch: error: unmatched {q} in [{line}]")
    return "".join(word), i

def directives(script):
    components, options = [], []
    for line in script.split("\n"):
        if line.startswith("#SBATCH"):
            rest = line[len("#SBATCH"):]
            lower = rest.lower()
            if "hetjob" in lower or "packjob" in lower:
                components.append(options)
                options = []
                for word in ("hetjob", "packjob"):
                    at = lower.find(word)
                    if at >= 0:
                        rest = rest[:at] + " " * len(word) + rest[at + len(word):]
                        lower = rest.lower()
            while True:
                word, used = get_argument(rest)
                if word is None:
                    break
                if word:
                    options.append(word)
                rest = rest[used:]
                if not rest or rest.lstrip().startswith("#"):
                    break
        elif line.strip() == "" or line.lstrip().startswith("#"):
            continue
        else:
            break
    components.append(options)
    return components

def value(options, name):
    found = None
    for o in options:
        if o.startswith(name + "="):
            found = o[len(name) + 1:]
    return found

def main():
    log = os.environ["STUB_LOG"]
    args = [a for a in sys.argv[1:] if a != "--parsable"]
    script = sys.stdin.read()
    wrap = value(args, "--wrap")
    if wrap is not None:
        script = "#!/bin/sh\n" + wrap + "\n"
    components = directives(script)
    if len(components) != 1:
        sys.exit(f"sbatch: a heterogeneous job of {len(components)} components")
    options = components[0] + args  # the command line wins
    with open(log, "a") as f:
        f.write(json.dumps({"options": options, "script": script}) + "\n")
    chdir = value(options, "--chdir") or os.getcwd()
    output = value(options, "--output") or "slurm-%j.out"
    array = value(options, "--array")
    indices = []
    if array is not None:
        for part in array.split(","):
            a, _, b = part.partition("-")
            indices += list(range(int(a), int(b or a) + 1))
    with tempfile.NamedTemporaryFile("w", suffix=".sh", delete=False) as f:
        f.write(script)
        path = f.name
    for k in indices or [None]:
        env = dict(os.environ)
        out = output.replace("%%", "\0")
        if k is not None:
            env["SLURM_ARRAY_TASK_ID"] = str(k)
            out = out.replace("%a", str(k))
        out = out.replace("\0", "%")
        with open(os.path.join(chdir, out), "a") as o:
            r = subprocess.run(["/bin/bash", path], cwd=chdir, env=env, stdout=o, stderr=subprocess.STDOUT)
        if r.returncode != 0:
            sys.exit(f"sbatch stub: the job ended with {r.returncode} (its log: {out})")
    os.unlink(path)
    print(len(open(log).readlines()))

main()
'''

NAMES = ["with space", "$(touch PWNED)", "`touch PWNED`", "it's", 'a"b', "#hash", "a;touch PWNED", "x&&touch PWNED",
         "star*", "per%acent", "back\\slash", "tab\there"]
REFUSED = {'a"b': "a double quote", "back\\slash": "a backslash", "tab\there": "a control character"}


class Failed(Exception):
    pass


def check(condition, message):
    if not condition:
        raise Failed(message)


def run(binary, args, cwd, env=None):
    return subprocess.run([binary, *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=600)


def pwned(top):
    return [os.path.join(d, f) for d, _, files in os.walk(top) for f in files if f == "PWNED"]


def one_name(binary, top, name, stubs):
    d = os.path.join(top, name, "deeper " + name)
    os.makedirs(d)
    plan = os.path.join(d, "plan.json")
    r = run(binary, ["validate", "--samples", "2", "--events", "1500", "--seed", "3", "-o", "out", "--plan",
                     "plan.json"], d)
    if name in REFUSED:
        check(r.returncode == 1 and REFUSED[name] in r.stderr, f"{name!r}: the plan is not refused\n{r.stderr}")
        check(not os.path.exists(plan), f"{name!r}: a refused plan was written")
        return
    check(r.returncode == 0, f"{name!r}: validate --plan: exit {r.returncode}\n{r.stderr}")
    real = os.path.realpath(d)
    # The script as a user submits it: its directives are the plan's own.
    r = run(binary, ["batch", "script", "plan.json", "-o", "job.sh"], d)
    check(r.returncode == 0, f"{name!r}: batch script: exit {r.returncode}\n{r.stderr}")
    script = open(os.path.join(d, "job.sh")).read()
    log = os.path.join(top, f"stub-{len(os.listdir(top))}.jsonl")
    env = {**os.environ, "PATH": stubs + ":" + os.environ["PATH"], "STUB_LOG": log}
    r = subprocess.run(["sbatch", "--parsable"], input=script, cwd=top, env=env, capture_output=True, text=True)
    check(r.returncode == 0, f"{name!r}: the script, submitted: {r.stderr}{r.stdout}")
    options = json.loads(open(log).readline())["options"]
    expected = ["--job-name=emcalign-validate", "--array=0-1", f"--output={real}/plan.tasks/task-%a.log".replace(
        "%acent", "%%acent"), "--open-mode=append", f"--chdir={real}", "--cpus-per-task=1"]
    check(options == expected, f"{name!r}: the script's directives, as sbatch reads them:\n{options}\nnot\n{expected}")
    for k in (0, 1):
        task_log = os.path.join(real, "plan.tasks", f"task-{k}.log")
        check(os.path.isfile(task_log) and "sample" in open(task_log).read(), f"{name!r}: no log of task {k}")
    # The merge as the script's comment gives it.
    line = next(li for li in script.splitlines() if "--dependency=afterok:J" in li)
    words = shlex.split(line.lstrip("# ").replace("afterok:J", "afterok:1"))
    r = subprocess.run(words, cwd=top, env=env, capture_output=True, text=True)
    check(r.returncode == 0, f"{name!r}: the merge of the script's comment: {r.stderr}{r.stdout}")
    check(os.path.isfile(os.path.join(real, "out", "table.json")), f"{name!r}: the merge wrote no table.json")
    check(not pwned(top), f"{name!r}: a command hidden in a name ran: {pwned(top)}")
    # The same plan submitted by emcalign itself (the merge as a second job).
    r = run(binary, ["batch", "submit", "plan.json"], d, env)
    check(r.returncode == 0, f"{name!r}: batch submit: {r.stderr}")
    check(not pwned(top), f"{name!r}: a command hidden in a name ran: {pwned(top)}")


def refused_where_read(binary, top):
    """A copy of a good plan in a directory whose name holds a newline (or hetjob) is refused."""
    good = os.path.join(top, "good")
    os.makedirs(good)
    r = run(binary, ["validate", "--samples", "2", "--events", "1500", "-o", "out", "--plan", "plan.json"], good)
    check(r.returncode == 0, r.stderr)
    for name, what in (("evil\ntouch PWNED\n", "a control character"), ("my-HetJob", "another job's start")):
        d = os.path.join(top, name)
        os.makedirs(d)
        shutil.copy(os.path.join(good, "plan.json"), d)
        for args in (["batch", "script", "plan.json", "-o", "-"], ["batch", "submit", "plan.json"],
                     ["task", "plan.json", "0"]):
            r = run(binary, args, d)
            check(r.returncode == 1 and what in r.stderr and "#SBATCH" not in r.stdout,
                  f"{name!r}: {' '.join(args)} of a copied plan: exit {r.returncode}\n{r.stderr}{r.stdout}")
        r = run(binary, ["validate", "--samples", "2", "--events", "1500", "-o", "out", "--plan", "p2.json"], d)
        check(r.returncode == 1 and what in r.stderr, f"{name!r}: validate --plan is not refused\n{r.stderr}")
    # An edited plan's directory goes into the script as it is read.
    plan = json.load(open(os.path.join(good, "plan.json")))
    plan["directory"] = "/tmp\ntouch PWNED"
    with open(os.path.join(good, "edited.json"), "w") as f:
        json.dump(plan, f)
    r = run(binary, ["batch", "script", "edited.json", "-o", "-"], good)
    check(r.returncode == 1 and "directory" in r.stderr, f"an edited plan's directory: {r.stderr}{r.stdout}")
    check(not pwned(top), f"a command hidden in a name ran: {pwned(top)}")


def main():
    binary = os.path.abspath(sys.argv[1])
    top = tempfile.mkdtemp(prefix="emcalign_script_names_")
    try:
        stubs = os.path.join(top, "stubs")
        os.makedirs(stubs)
        with open(os.path.join(stubs, "sbatch"), "w") as f:
            f.write(STUB)
        os.chmod(os.path.join(stubs, "sbatch"), 0o755)
        work = os.path.join(top, "names")
        os.makedirs(work)
        for name in NAMES:
            one_name(binary, work, name, stubs)
        refused_where_read(binary, work)
        print(f"script names: {len(NAMES)} names, each run through the stub sbatch: only the tasks ran")
        return 0
    except Failed as e:
        print(f"FAILED: {e}", file=sys.stderr)
        return 1
    finally:
        shutil.rmtree(top, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())

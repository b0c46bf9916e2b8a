#!/usr/bin/env python3
"""A private single-node Slurm for the test suite (issue 31: the fan-outs tested on a real Slurm).

    slurm_server.py start STATE   start munged (as the `munge` user, its own socket), slurmctld
                                  and slurmd (a private slurm.conf, free non-default ports, this
                                  machine as the one node) and write STATE (JSON: the directory,
                                  SLURM_CONF, the pids)
    slurm_server.py stop STATE    cancel what is still queued, stop the three daemons by pid and
                                  remove the directory and STATE
    slurm_server.py smoke STATE   submit a job array of 4 tasks and a job that depends on it,
                                  wait for both, and check what each wrote

Slurm's daemons run as root (CI runs as root, as the brief says); the clients find this Slurm
through SLURM_CONF (the state's `env`). Nothing is written outside the directory.
"""
import json
import os
import pwd
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time


def fail(message):
    sys.exit(f"slurm_server: {message}")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def memory_mb():
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) // 1024
    return 1024


def wait_for(what, test, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if test():
            return
        time.sleep(0.25)
    fail(f"{what} within {seconds} s")


def alive(pid):
    try:
        os.kill(pid, 0)
        return True
    except OSError:
        return False


def clients_env(state):
    return {**os.environ, "SLURM_CONF": state["conf"]}


def start(state_path):
    if os.geteuid() != 0:
        fail("Slurm's daemons need root (the tests start them as CI does, as root)")
    for tool in ("munged", "slurmctld", "slurmd", "sbatch"):
        if shutil.which(tool) is None:
            fail(f"no {tool}: install slurm-wlm and munge (scripts/install-deps)")
    top = tempfile.mkdtemp(prefix="emcalign-slurm-")
    os.chmod(top, 0o755)  # munged checks that its socket's directories are reachable
    munge_dir = os.path.join(top, "munge")
    os.makedirs(munge_dir)
    for d in ("state", "spool", "log"):
        os.makedirs(os.path.join(top, d))
    user = pwd.getpwnam("munge")
    os.chown(munge_dir, user.pw_uid, user.pw_gid)
    os.chmod(munge_dir, 0o755)
    socket_path = os.path.join(munge_dir, "munge.socket")
    state = {"dir": top, "conf": os.path.join(top, "slurm.conf"), "pids": {}}
    with open(state_path, "w") as f:  # written first: a failed start is stopped by `stop`
        json.dump(state, f)
    r = subprocess.run(["runuser", "-u", "munge", "--", "munged", f"--socket={socket_path}",
                        f"--pid-file={munge_dir}/munged.pid", f"--log-file={munge_dir}/munged.log",
                        f"--seed-file={munge_dir}/seed", "--key-file=/etc/munge/munge.key"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"munged: {r.stderr.strip()}")
    wait_for("munged's pid file", lambda: os.path.exists(f"{munge_dir}/munged.pid"), 10)
    state["pids"]["munged"] = int(open(f"{munge_dir}/munged.pid").read().split()[0])
    host = socket.gethostname().split(".")[0]
    # EMCALIGN_SLURM_CPUS: a node of fewer CPUs than the machine (bench/cluster_fanout.sh).
    cpus = int(os.environ.get("EMCALIGN_SLURM_CPUS", "0")) or os.cpu_count() or 1
    conf = f"""# A private single-node Slurm of the emcalign tests (tests/slurm/slurm_server.py)
ClusterName=emcalign-test
SlurmctldHost={host}
SlurmctldPort={free_port()}
SlurmdPort={free_port()}
SlurmUser=root
AuthType=auth/munge
AuthInfo=socket={socket_path}
CredType=cred/munge
StateSaveLocation={top}/state
SlurmdSpoolDir={top}/spool
SlurmctldPidFile={top}/slurmctld.pid
SlurmdPidFile={top}/slurmd.pid
SlurmctldLogFile={top}/log/slurmctld.log
SlurmdLogFile={top}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
SchedulerType=sched/backfill
MinJobAge=600
DefMemPerCPU=1024
NodeName={host} CPUs={cpus} RealMemory={max(512, memory_mb() - 1024)} State=UNKNOWN
PartitionName=test Nodes={host} Default=YES MaxTime=INFINITE State=UP
"""
    with open(state["conf"], "w") as f:
        f.write(conf)
    env = clients_env(state)
    for daemon in ("slurmctld", "slurmd"):
        log = open(os.path.join(top, "log", f"{daemon}.out"), "w")
        p = subprocess.Popen([daemon, "-D", "-f", state["conf"]], stdout=log, stderr=subprocess.STDOUT, env=env,
                             start_new_session=True)
        state["pids"][daemon] = p.pid
        with open(state_path, "w") as f:
            json.dump(state, f)
        time.sleep(0.5)
        if p.poll() is not None:
            fail(f"{daemon} ended at once:\n" + open(log.name).read()[-2000:])

    def idle():
        r = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, env=env)
        return r.returncode == 0 and r.stdout.strip() == "idle"

    wait_for("the node idle (sinfo)", idle, 30)
    print(f"slurm_server: single-node Slurm up (SLURM_CONF={state['conf']})")


def stop(state_path):
    try:
        with open(state_path) as f:
            state = json.load(f)
    except (OSError, ValueError):
        return
    env = clients_env(state)
    if os.path.exists(state["conf"]):
        subprocess.run(["scancel", "--full", "--user=root"], capture_output=True, env=env)
    for name in ("slurmd", "slurmctld", "munged"):
        pid = state.get("pids", {}).get(name)
        if pid and alive(pid):
            os.kill(pid, signal.SIGTERM)
            deadline = time.time() + 10
            while alive(pid) and time.time() < deadline:
                try:
                    os.waitpid(pid, os.WNOHANG)
                except ChildProcessError:
                    pass
                time.sleep(0.1)
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
    shutil.rmtree(state["dir"], ignore_errors=True)
    os.unlink(state_path)


def smoke(state_path):
    """A job array and a job that depends on it, as `batch submit` will make them."""
    with open(state_path) as f:
        state = json.load(f)
    env = clients_env(state)
    out = os.path.join(state["dir"], "smoke")
    os.makedirs(out, exist_ok=True)
    array = subprocess.run(["sbatch", "--parsable", "--array=0-3", "-o", f"{out}/task-%a.log",
                            "--wrap", f"echo $SLURM_ARRAY_TASK_ID > {out}/done-$SLURM_ARRAY_TASK_ID"],
                           capture_output=True, text=True, env=env)
    if array.returncode != 0:
        fail(f"sbatch of the array: {array.stderr.strip()}")
    array_id = array.stdout.strip().split(";")[0]
    finish = subprocess.run(["sbatch", "--parsable", f"--dependency=afterok:{array_id}", "-o", f"{out}/finish.log",
                             "--wrap", f"cat {out}/done-* | sort | tr '\\n' ' ' > {out}/merged"],
                            capture_output=True, text=True, env=env)
    if finish.returncode != 0:
        fail(f"sbatch of the dependent job: {finish.stderr.strip()}")
    finish_id = finish.stdout.strip().split(";")[0]

    def finished():
        r = subprocess.run(["squeue", "-h", "-j", f"{array_id},{finish_id}"], capture_output=True, text=True, env=env)
        return r.returncode == 0 and r.stdout.strip() == ""

    wait_for("the array and its dependent job to finish", finished, 120)
    merged = open(f"{out}/merged").read().split() if os.path.exists(f"{out}/merged") else []
    if merged != ["0", "1", "2", "3"]:
        fail(f"the dependent job saw {merged}, not the 4 tasks' outputs")
    print(f"slurm_server: array {array_id} (4 tasks) and job {finish_id} after it: done")


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("start", "stop", "smoke"):
        sys.exit(__doc__)
    {"start": start, "stop": stop, "smoke": smoke}[sys.argv[1]](sys.argv[2])

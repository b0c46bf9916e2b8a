#!/usr/bin/env python3
"""A private PostgreSQL 15 server for the test suite.

    pg_server.py start STATE   initdb on a new temporary directory, start the server on a
                               free local port, and write STATE (JSON: uri, data directory)
    pg_server.py stop STATE    stop it and remove its directory and STATE

The server belongs to whoever runs the tests; as root (CI) it runs as the `postgres` system
user, started with runuser, since PostgreSQL refuses to run as root. It listens on 127.0.0.1
only, trusts local connections, and keeps its socket in its own directory.
"""
import json
import os
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import time

BIN = "/usr/lib/postgresql/15/bin"


def as_server_user(cmd):
    if os.geteuid() == 0:
        return ["runuser", "-u", "postgres", "--"] + cmd
    return cmd


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(cmd, **kw):
    r = subprocess.run(as_server_user(cmd), capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"pg_server: {' '.join(cmd)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    return r


def stop(state_path):
    try:
        with open(state_path) as f:
            state = json.load(f)
    except (OSError, ValueError):
        return
    data = state.get("data", "")
    if data and os.path.isdir(data):
        subprocess.run(as_server_user([f"{BIN}/pg_ctl", "-D", data, "-m", "immediate", "-w", "stop"]),
                       capture_output=True)
        shutil.rmtree(os.path.dirname(data), ignore_errors=True)
    os.unlink(state_path)


def start(state_path):
    if not os.path.exists(f"{BIN}/initdb"):
        sys.exit(f"pg_server: no {BIN}/initdb: install postgresql-15 (scripts/install-deps)")
    stop(state_path)  # a server left by an interrupted run
    root = tempfile.mkdtemp(prefix="emcalign-pg-")
    os.chmod(root, 0o755)
    data = os.path.join(root, "data")
    if os.geteuid() == 0:
        pw = pwd.getpwnam("postgres")
        os.chown(root, pw.pw_uid, pw.pw_gid)
    user = "postgres" if os.geteuid() == 0 else pwd.getpwuid(os.geteuid()).pw_name
    run([f"{BIN}/initdb", "-D", data, "-U", user, "--auth=trust", "-E", "UTF8", "--locale=C", "--no-sync"])
    for attempt in range(5):
        port = free_port()
        options = (f"-c listen_addresses=127.0.0.1 -c port={port} -c unix_socket_directories={root} "
                   "-c fsync=off -c max_connections=100 -c log_min_messages=fatal")
        r = subprocess.run(as_server_user([f"{BIN}/pg_ctl", "-D", data, "-o", options, "-l",
                                           os.path.join(root, "log"), "-w", "-t", "60", "start"]),
                           capture_output=True, text=True)
        if r.returncode == 0:
            break
        time.sleep(0.2)
    else:
        log = open(os.path.join(root, "log")).read() if os.path.exists(os.path.join(root, "log")) else ""
        shutil.rmtree(root, ignore_errors=True)
        sys.exit(f"pg_server: the server did not start:\n{r.stdout}{r.stderr}{log}")
    state = {"uri": f"postgresql://{user}@127.0.0.1:{port}/postgres", "data": data, "port": port, "user": user,
             "options": options}
    tmp = state_path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(state, f)
    os.replace(tmp, state_path)
    print(state["uri"])


def pause(state_path):
    """Stops the server, keeping its data: a database that goes away (resume() brings it back)."""
    with open(state_path) as f:
        state = json.load(f)
    run([f"{BIN}/pg_ctl", "-D", state["data"], "-m", "fast", "-w", "stop"])


def resume(state_path):
    """Starts a paused server again on its port."""
    with open(state_path) as f:
        state = json.load(f)
    root = os.path.dirname(state["data"])
    run([f"{BIN}/pg_ctl", "-D", state["data"], "-o", state["options"], "-l", os.path.join(root, "log"), "-w", "-t",
         "60", "start"])


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("start", "stop"):
        sys.exit("usage: pg_server.py start|stop STATE")
    (start if sys.argv[1] == "start" else stop)(os.path.abspath(sys.argv[2]))

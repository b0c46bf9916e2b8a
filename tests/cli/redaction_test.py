#!/usr/bin/env python3
"""Issue 44: a password never leaves the process, wherever it stands on the command line.

    redaction_test.py EMCALIGN [--one-address]

Every command and subcommand (read from the --help pages, so a new one is walked too) is run
with a database address holding a password in every position: as the value of each of its
options (--opt URI, --opt=URI, --opt @URI), as a positional argument, after the others, and
as the command itself. The addresses: a URI with a plain password, one percent-encoded, one
with an unencoded '@', one with password= among its parameters, a libpq keyword string. Checked
for each run: no form of the password in what it prints (standard output and error), in the
name or the content of any file it leaves; usage errors included. The server named is
127.0.0.1:9, which refuses at once.
Exit 0 when every check holds; the first that fails is printed with its command line.
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

SECRETS = {
    "postgresql://calib:Sekr3tPw@127.0.0.1:9/snd": ["Sekr3tPw"],
    "postgres://calib:Pa%24%24w0rd@127.0.0.1:9/snd": ["Pa%24%24w0rd", "Pa$$w0rd"],
    "postgresql://calib:Unenc@ded@127.0.0.1:9/snd": ["Unenc@ded"],
    "postgresql://calib@127.0.0.1:9/snd?password=Qu3ryPw&sslmode=disable": ["Qu3ryPw"],
    "host=127.0.0.1 port=9 password=K3ywordPw": ["K3ywordPw"],
    # Cut short by a message (a value shown to 32 characters): no beginning of it either.
    "postgresql://calib:Xq7LongPasswordCutShortByMessages@127.0.0.1:9/snd": ["Xq7Lo"],
    "postgresql://me@127.0.0.1:9/d?pass%77ord=EncodedNamePw": ["EncodedNamePw"],
    "postgresql://me@127.0.0.1:9/d?password%3DEncodedEqPw": ["EncodedEqPw"],
    "host=127.0.0.1 password = SpacedPw9": ["SpacedPw9"],
}


class Failed(Exception):
    pass


def commands(binary):
    """(path, options) of every command that runs something, from the --help pages."""
    out = []

    def walk(path):
        text = subprocess.run([binary, *path, "--help"], capture_output=True, text=True).stdout
        subs = re.findall(r"^  ([a-z][a-z-]*)\s{2,}", text.split("Subcommands:")[1], re.M) if "Subcommands:" in text \
            else []
        options = sorted(set(re.findall(r"^\s+(?:-[a-zA-Z],)?(--[a-z][a-z0-9-]*)", text, re.M)) - {"--help", "--version"})
        if subs:
            for s in subs:
                walk(path + [s])
        else:
            out.append((path, options))

    walk([])
    return out


def check_run(binary, top, args, secrets, counter):
    work = os.path.join(top, f"run-{counter}")
    os.makedirs(work)
    shutil.copy(os.path.join(top, "ev.csv"), work)
    try:
        r = subprocess.run([binary, *args], cwd=work, capture_output=True, text=True, timeout=60,
                           stdin=subprocess.DEVNULL)
        printed = r.stdout + r.stderr
    except subprocess.TimeoutExpired as e:
        printed = (e.stdout or b"").decode(errors="replace") + (e.stderr or b"").decode(errors="replace")
    for s in secrets:
        if s in printed:
            raise Failed(f"emcalign {' '.join(args)}: printed the password {s!r}:\n{printed}")
    for d, dirs, files in os.walk(work):
        for name in dirs + files:
            p = os.path.join(d, name)
            for s in secrets:
                if s in p:
                    raise Failed(f"emcalign {' '.join(args)}: left a file named with the password: {p}")
            if os.path.isfile(p) and not os.path.islink(p):
                data = open(p, "rb").read()
                for s in secrets:
                    if s.encode() in data:
                        raise Failed(f"emcalign {' '.join(args)}: wrote the password {s!r} into {p}")
    shutil.rmtree(work)


def main():
    binary = os.path.abspath(sys.argv[1])
    # Under the sanitizers (slow to start): every position with one address only.
    addresses = dict(list(SECRETS.items())[:1]) if "--one-address" in sys.argv else SECRETS
    top = tempfile.mkdtemp(prefix="emcalign_redaction_")
    try:
        shutil.copy(os.path.join(os.path.dirname(__file__), "..", "..", "data", "examples", "spec-example.json"),
                    os.path.join(top, "p.json"))
        r = subprocess.run([binary, "simulate", "--events", "200", "--seed", "1", "--params", "p.json", "-o",
                            "ev.csv"], cwd=top, capture_output=True, text=True)
        if r.returncode != 0:
            raise Failed(f"the fixture: {r.stderr}")
        runs = 0
        walked = commands(binary)
        for first, (uri, secrets) in enumerate(addresses.items()):
            lines = [[uri], [uri, "list"]]
            for path, options in walked:
                lines += [path + [uri], path + ["ev.csv", uri], path + [uri, "0"]]
                for o in options:
                    lines += [path + [o, uri]]
                    if first == 0:  # every position with one address; the other forms as an option's value
                        lines += [path + [f"{o}={uri}"], path + [o, "@" + uri], path + ["ev.csv", o, uri]]
            for args in lines:
                check_run(binary, top, args, secrets, runs)
                runs += 1
        print(f"redaction: {len(walked)} commands, {runs} command lines with a password: none shown or written")
        return 0
    except Failed as e:
        print(f"FAILED: {e}", file=sys.stderr)
        return 1
    finally:
        shutil.rmtree(top, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())

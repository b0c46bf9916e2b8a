#!/usr/bin/env bash
# The fan-out on Slurm against one process (docs/cluster.md, "Measured on this machine"): four
# studies, each run in one process with 1 and 2 threads, and as a plan on a private single-node
# Slurm with 1 and with 2 CPUs (tests/slurm/slurm_server.py, EMCALIGN_SLURM_CPUS); the outputs
# of every run are compared with the one-process ones, and each task's duration and peak memory
# are read from its record. Prints a Markdown table.
#
#   bench/cluster_fanout.sh [WORKDIR] [STUDY...]   (about 35 minutes on 2 cores; run as root, as the tests)
# STUDY: validate, derive, systematics, campaign (default: all four). The campaign stores into the
# suite's own PostgreSQL server (tests/postgres/pg_server.py), as a plan must.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
bin="$here/build/bin/emcalign"
work="${1:-/tmp/emcalign-cluster-fanout}"
shift || true
rm -rf "$work"
mkdir -p "$work"
cd "$work"

now() { date +%s.%N; }
elapsed() { python3 -c "print(f'{$(now) - $1:.1f}')"; }

# The studies: a name, its command line (without -o and --plan), its output.
"$bin" derive-corrections --events 100000 --response-samples 0 -o c.json >/dev/null 2>&1
cat > period.json <<'EOF'
{"format": "emcalign-period/1", "first_run": 1, "runs": 40, "events_per_run": [15000, 25000], "seed": 3,
 "theta_range_deg": [40, 140], "beam_energy_mev": [{"from_run": 1, "value": 612.5}], "segments": [{"from_run": 1, "parameters": {"alpha": 2.8, "dx": 0.3, "dp1": 0.5}},
 {"from_run": 21, "parameters": {"dx": 0.45}}]}
EOF
"$bin" simulate --period period.json -o period --no-hits >/dev/null 2>&1
declare -A study
study[validate]="validate --samples 50 --events 50000"
study[derive]="derive-corrections --beam-energy 500,700,900 --events 200000 --response-samples 100 --response-events 20000 --samples-per-task 10"
study[systematics]="systematics --samples 10 --events 50000 --variations gains-2pc,tmax-up,dead-double --corrections c.json --reverse --reverse-events 200000 --reverse-response-samples 0"
study[campaign]="campaign period --min-events 50000"
order=(validate derive systematics campaign)
if [ $# -gt 0 ]; then order=("$@"); fi
pg=""
if [[ " ${order[*]} " == *" campaign "* ]]; then
  /usr/bin/python3 "$here/tests/postgres/pg_server.py" start "$work/pg.json" >/dev/null
  trap '/usr/bin/python3 "$here/tests/postgres/pg_server.py" stop "$work/pg.json"' EXIT
  pg="$(python3 -c "import json; print(json.load(open('$work/pg.json'))['uri'])")"
fi

output() { # the output option of a study's run NAME into DIR
  case "$1" in
    campaign) psql -q "$pg" -c "CREATE DATABASE \"${2//-/_}\"" >/dev/null
              echo "--conditions ${pg%/*}/${2//-/_} --tag t" ;;
    *) echo "-o $2" ;;
  esac
}
uri() { echo "${pg%/*}/${1//-/_}"; }

same() { # the outputs of run A and run B of a study are the same
  case "$1" in
    validate) cmp -s "$2/table.json" "$3/table.json" ;;
    derive) cmp -s "$2/ee-500MeV.json" "$3/ee-500MeV.json" && cmp -s "$2/ee-900MeV.json" "$3/ee-900MeV.json" ;;
    systematics) cmp -s "$2/systematics.json" "$3/systematics.json" ;;
    campaign) diff <("$bin" conditions list "$(uri "$2")" --tag t --json | python3 -c \
                 "import json,sys; print([i['payload'] for i in json.load(sys.stdin)['iovs']])") \
                   <("$bin" conditions list "$(uri "$3")" --tag t --json | python3 -c \
                 "import json,sys; print([i['payload'] for i in json.load(sys.stdin)['iovs']])") >/dev/null ;;
  esac
}

declare -A t1 t2 s1 s2 tasks mean longest memory
for name in "${order[@]}"; do
  for threads in 1 2; do
    start=$(now)
    "$bin" ${study[$name]} $(output "$name" "$name-t$threads") --threads $threads >"$name-t$threads.log" 2>&1 ||
      { echo "$name with $threads threads failed: $work/$name-t$threads.log" >&2; exit 1; }
    if [ "$threads" = 1 ]; then t1[$name]=$(elapsed "$start"); else t2[$name]=$(elapsed "$start"); fi
  done
  same "$name" "$name-t1" "$name-t2" || { echo "$name: 1 and 2 threads differ" >&2; exit 1; }
done

for cpus in 1 2; do
  EMCALIGN_SLURM_CPUS=$cpus /usr/bin/python3 "$here/tests/slurm/slurm_server.py" start "$work/slurm.json" >/dev/null
  export SLURM_CONF="$(python3 -c "import json; print(json.load(open('$work/slurm.json'))['conf'])")"
  for name in "${order[@]}"; do
    out="$name-slurm$cpus"
    "$bin" ${study[$name]} $(output "$name" "$out") --plan "$out.json" >/dev/null 2>&1
    start=$(now)
    "$bin" batch submit "$out.json" --wait >/dev/null 2>&1 || { echo "$out: the fan-out failed" >&2; exit 1; }
    if [ "$cpus" = 1 ]; then s1[$name]=$(elapsed "$start"); else s2[$name]=$(elapsed "$start"); fi
    same "$name" "$name-t1" "$out" || { echo "$out: differs from one process" >&2; exit 1; }
    read -r n m l mem < <(python3 - "$out.tasks" <<'EOF'
import glob, json, sys
r = [json.load(open(f)) for f in glob.glob(sys.argv[1] + "/task-*.json")]
s = [x["seconds"] for x in r]
print(len(r), f"{sum(s) / len(s):.2f}", f"{max(s):.1f}", f"{max(x['peak_memory_mb'] for x in r):.0f}")
EOF
)
    tasks[$name]=$n; mean[$name]=$m; longest[$name]=$l; memory[$name]=$mem
  done
  /usr/bin/python3 "$here/tests/slurm/slurm_server.py" stop "$work/slurm.json"
done

echo "| study | tasks | task mean / longest (s) | task peak memory (MB) | one process, 1 thread | 2 threads | Slurm, 1 CPU | Slurm, 2 CPUs |"
echo "|---|---|---|---|---|---|---|---|"
for name in "${order[@]}"; do
  echo "| $name | ${tasks[$name]} | ${mean[$name]} / ${longest[$name]} | ${memory[$name]} | ${t1[$name]} s | ${t2[$name]} s | ${s1[$name]} s | ${s2[$name]} s |"
done
echo
echo "every fan-out's outputs equal the one-process command's (compared file by file; the campaign's payload hashes)"

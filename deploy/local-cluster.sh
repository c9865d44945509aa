#!/usr/bin/env bash
# Local irfarm cluster on 127.0.0.1: one irfarm-coordinator (in-memory job store, or its own
# redis-server with --redis) and N irfarm-worker processes.
#
#   local-cluster.sh start [--workers N] [--threads T] [--redis] [--port P] [--metrics M]
#                          [--http H]
#       starts the cluster, waits until the coordinator answers and every worker has registered,
#       and records pids, address and logs in the state dir; prints the coordinator address.
#       --metrics M: Prometheus metrics of the coordinator on 127.0.0.1:M and of worker i on
#       127.0.0.1:M+i; --http H: the coordinator's dashboard on http://127.0.0.1:H/.
#   local-cluster.sh stop
#       SIGTERM to every process of the cluster, SIGKILL after IRFARM_STOP_TIMEOUT seconds (10).
#   local-cluster.sh status
#       the cluster's processes and `irfarm status`.
#   local-cluster.sh run SCENE.xml -o OUT.exr [--stats OUT.json] [--workers N] [--threads T]
#                        [--redis] [--port P] [other `irfarm submit` options, e.g. -D resx=64]
#       starts a private cluster, submits the scene with `irfarm submit --wait`, writes the image
#       (and a stats JSON of the job: per-worker and total records computed / received / used,
#       tiles, wall seconds), and stops the cluster, also on failure or Ctrl-C.
#
# Credentials: `start` writes a random worker token and a client token ($IRFARM_TOKEN if set,
# else random) to STATE/worker.token and STATE/client.token (mode 600); the coordinator refuses
# calls without them. Talk to a started cluster with
#   irfarm status --token-file STATE/client.token      (or export IRFARM_TOKEN=<that token>)
#
# Binaries: $IRFARM_BIN, else <repo>/build (the repo that holds this script).
# State dir: $IRFARM_CLUSTER_DIR, else ${XDG_RUNTIME_DIR:-/tmp}/irfarm-cluster (`run` uses a
# private temporary one, so it never disturbs a cluster started with `start`).
# Threads: by default each worker gets nproc / N threads (at least 1), so the workers share the
# machine's cores instead of oversubscribing them.
set -euo pipefail

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${IRFARM_BIN:-$REPO/build}
STATE=${IRFARM_CLUSTER_DIR:-${XDG_RUNTIME_DIR:-/tmp}/irfarm-cluster}
STOP_TIMEOUT=${IRFARM_STOP_TIMEOUT:-10}
READY_TIMEOUT=${IRFARM_READY_TIMEOUT:-30}

die() { echo "local-cluster: $*" >&2; exit 1; }
say() { echo "local-cluster: $*" >&2; }

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//' >&2; exit 2; }

need_bin() {
  for b in irfarm irfarm-coordinator irfarm-worker; do
    [[ -x $BIN/$b ]] || die "$BIN/$b not found: build first (cmake -S . -B build -G Ninja && ninja -C build) or set IRFARM_BIN"
  done
}

# A free TCP port on 127.0.0.1 (the kernel picks it; a race with another process is unlikely).
free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

port_in_use() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

# A random 192-bit token (hex) from the kernel's CSPRNG.
new_token() { od -An -N24 -tx1 /dev/urandom | tr -d ' \n'; }

# irfarm_cli ARGS...: the `irfarm` command with this cluster's client token.
irfarm_cli() { "$BIN/irfarm" "$@" --token-file "$STATE/client.token"; }

# alive PID NAME: the pid runs and is the program we started (not a reused pid).
alive() {
  [[ -n $1 ]] && kill -0 "$1" 2>/dev/null && tr '\0' ' ' <"/proc/$1/cmdline" 2>/dev/null | grep -q -- "$2"
}

# Pid files: STATE/<name>.pid holds "pid program".
running_pids() {
  local f pid prog
  for f in "$STATE"/*.pid; do
    [[ -e $f ]] || continue
    read -r pid prog <"$f" || continue
    alive "$pid" "$prog" && echo "$pid $prog $(basename "$f" .pid)"
  done
  return 0
}

# launch NAME PROGRAM ARGS...: starts it detached from the terminal's hangup, logs to STATE.
launch() {
  local name=$1; shift
  nohup "$@" </dev/null >"$STATE/$name.log" 2>&1 &
  echo "$! $(basename "$1")" >"$STATE/$name.pid"
}

cmd_start() {
  local workers=2 threads=0 redis=0 port="" metrics="" http=""
  while (($#)); do
    case $1 in
      --workers) workers=${2:?}; shift 2 ;;
      --metrics) metrics=${2:?}; shift 2 ;;
      --http) http=${2:?}; shift 2 ;;
      --threads) threads=${2:?}; shift 2 ;;
      --redis) redis=1; shift ;;
      --port) port=${2:?}; shift 2 ;;
      *) die "start: unknown option '$1'" ;;
    esac
  done
  [[ $workers =~ ^[0-9]+$ ]] && ((workers >= 1)) || die "--workers expects a number >= 1"
  need_bin
  mkdir -p "$STATE"
  [[ -z $(running_pids) ]] || die "a cluster is already running (state in $STATE); stop it first"
  rm -f "$STATE"/*.pid "$STATE"/*.log "$STATE/address" "$STATE"/*.token
  if [[ -z $port ]]; then
    port=50051
    port_in_use "$port" && port=$(free_port)
  fi
  port_in_use "$port" && die "port $port on 127.0.0.1 is in use"
  ((threads > 0)) || threads=$(($(nproc) / workers))
  ((threads > 0)) || threads=1
  local addr=127.0.0.1:$port coord_args=(--listen "127.0.0.1:$port")
  # Tokens readable by this user only (the token file format is "NAME TOKEN" or "TOKEN").
  (
    umask 077
    echo "local ${IRFARM_TOKEN:-$(new_token)}" >"$STATE/client.token"
    new_token >"$STATE/worker.token"
  )
  coord_args+=(--client-token-file "$STATE/client.token" --worker-token-file "$STATE/worker.token")
  [[ -z $metrics ]] || coord_args+=(--metrics "127.0.0.1:$metrics")
  [[ -z $http ]] || coord_args+=(--http "127.0.0.1:$http")

  if ((redis)); then
    command -v redis-server >/dev/null || die "redis-server not installed (deploy/setup.sh installs it)"
    local rport; rport=$(free_port)
    mkdir -p "$STATE/redis"
    launch redis redis-server --port "$rport" --bind 127.0.0.1 --dir "$STATE/redis" \
      --save "" --appendonly yes --appendfsync everysec
    local ok=0
    for _ in $(seq $((READY_TIMEOUT * 10))); do
      if redis-cli -p "$rport" ping 2>/dev/null | grep -q PONG; then ok=1; break; fi
      sleep 0.1
    done
    ((ok)) || { cmd_stop; die "redis-server did not come up on 127.0.0.1:$rport"; }
    coord_args+=(--redis "127.0.0.1:$rport")
    say "redis-server on 127.0.0.1:$rport (data in $STATE/redis)"
  fi

  launch coordinator "$BIN/irfarm-coordinator" "${coord_args[@]}"
  local ok=0
  for _ in $(seq $((READY_TIMEOUT * 10))); do
    if irfarm_cli status --coordinator "$addr" >/dev/null 2>&1; then ok=1; break; fi
    sleep 0.1
  done
  ((ok)) || { tail -5 "$STATE/coordinator.log" >&2; cmd_stop; die "coordinator did not come up on $addr"; }

  for i in $(seq "$workers"); do
    local worker_metrics=()
    [[ -z $metrics ]] || worker_metrics=(--metrics "127.0.0.1:$((metrics + i))")
    launch "worker-$i" "$BIN/irfarm-worker" --coordinator "$addr" --threads "$threads" \
      --name "worker-$i" --token-file "$STATE/worker.token" "${worker_metrics[@]}"
  done
  # A worker is ready once it has registered (its log says so).
  for i in $(seq "$workers"); do
    ok=0
    for _ in $(seq $((READY_TIMEOUT * 10))); do
      if grep -q "registered with" "$STATE/worker-$i.log" 2>/dev/null; then ok=1; break; fi
      sleep 0.1
    done
    ((ok)) || { tail -5 "$STATE/worker-$i.log" >&2; cmd_stop; die "worker-$i did not register"; }
  done
  echo "$addr" >"$STATE/address"
  say "coordinator on $addr with $workers worker(s) x $threads thread(s); state in $STATE"
  say "client token: $STATE/client.token (irfarm ... --token-file $STATE/client.token)"
  echo "$addr"
}

cmd_stop() {
  local procs pid prog name
  procs=$(running_pids)
  if [[ -z $procs ]]; then
    rm -f "$STATE"/*.pid "$STATE/address"
    return 0
  fi
  # Workers first (they finish their tile), then the coordinator, then Redis.
  for pattern in irfarm-worker irfarm-coordinator redis-server; do
    local pids=()
    while read -r pid prog name; do
      [[ $prog == "$pattern" ]] && pids+=("$pid")
    done <<<"$procs"
    ((${#pids[@]})) || continue
    kill -TERM "${pids[@]}" 2>/dev/null || true
    local end=$((SECONDS + STOP_TIMEOUT)) left
    while :; do
      left=()
      for pid in "${pids[@]}"; do alive "$pid" "$pattern" && left+=("$pid"); done
      ((${#left[@]})) || break
      if ((SECONDS >= end)); then
        say "$pattern ${left[*]} still running after ${STOP_TIMEOUT}s: SIGKILL"
        kill -KILL "${left[@]}" 2>/dev/null || true
        break
      fi
      sleep 0.1
    done
  done
  rm -f "$STATE"/*.pid "$STATE/address"
  say "stopped"
}

cmd_status() {
  local procs
  procs=$(running_pids)
  [[ -n $procs ]] || { echo "no cluster running (state dir $STATE)"; return 1; }
  echo "$procs" | while read -r pid prog name; do echo "$name: pid $pid ($prog)"; done
  [[ -f $STATE/address ]] && irfarm_cli status --coordinator "$(cat "$STATE/address")"
}

# job_stats_json JOB_JSON SCENE: the stats JSON of a finished job (from `irfarm status --json`).
job_stats_json() {
  python3 - "$1" "$2" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
num = lambda w, k: int(w.get(k, 0))
workers = []
for w in j.get("workers", []):
    workers.append({
        "worker_id": w.get("workerId", 0), "name": w.get("workerName", ""),
        "tiles": num(w, "tiles"),
        "records": {"computed": num(w, "recordsComputed"), "received": num(w, "recordsReceived"),
                    "used": num(w, "recordsUsed"), "used_remote": num(w, "remoteRecordsUsed"),
                    "sent": num(w, "recordsSent")},
        "bytes": {"sent": num(w, "bytesSent"), "received": num(w, "bytesReceived")},
        "cache": {"lookups": num(w, "lookups"), "hits": num(w, "lookupHits")},
        "render_seconds": float(w.get("renderSeconds", 0)),
    })
total = {
    "tiles": sum(w["tiles"] for w in workers),
    "records": {k: sum(w["records"][k] for w in workers)
                for k in ("computed", "received", "used", "used_remote", "sent")},
    "bytes": {k: sum(w["bytes"][k] for w in workers) for k in ("sent", "received")},
    "render_seconds": sum(w["render_seconds"] for w in workers),
    "wall_seconds": float(j.get("elapsedSeconds", 0)),
}
out = {
    "job": j["id"], "scene": sys.argv[2], "state": j["state"].replace("JOB_STATE_", ""),
    "width": j.get("width", 0), "height": j.get("height", 0),
    "tiles_total": j.get("tilesTotal", 0), "tiles_done": j.get("tilesDone", 0),
    "records_merged": int(j.get("recordsMerged", 0)),
    "records_rejected": int(j.get("recordsRejected", 0)),
    "records_imported": int(j.get("recordsImported", 0)),
    "records_seeded": int(j.get("recordsSeeded", 0)),
    "wall_seconds": total["wall_seconds"], "workers": workers, "total": total,
}
print(json.dumps(out, indent=2))
PY
}

cmd_run() {
  local scene="" out="" stats="" start_args=() submit_args=()
  while (($#)); do
    case $1 in
      -o|--output) out=${2:?}; shift 2 ;;
      --stats) stats=${2:?}; shift 2 ;;
      --workers|--threads|--port) start_args+=("$1" "${2:?}"); shift 2 ;;
      --redis) start_args+=("$1"); shift ;;
      --coordinator|--wait) die "run: $1 is set by the script" ;;
      -D) submit_args+=("$1" "${2:?}"); shift 2 ;;
      -*) # other `irfarm submit` options; those taking a value get it too
        case $1 in
          --priority|--cache-in|--integrator|--spp|--accuracy|--record-rays|--tile-size|--seed|--target-error|--time-limit)
            submit_args+=("$1" "${2:?}"); shift 2 ;;
          *) submit_args+=("$1"); shift ;;
        esac ;;
      *) [[ -z $scene ]] || die "run: one scene at a time (got '$scene' and '$1')"; scene=$1; shift ;;
    esac
  done
  [[ -n $scene ]] || die "run: no scene given"
  [[ -f $scene ]] || die "run: $scene: no such file"
  [[ -n $out ]] || die "run: -o OUT.exr is required"
  need_bin
  STATE=$(mktemp -d "${TMPDIR:-/tmp}/irfarm-run.XXXXXX")
  local status=0
  SUBMIT_PID=""
  trap 'cmd_stop; rm -rf "$STATE"' EXIT
  # The submit runs in the background and is waited for, so that a signal is handled at once
  # (bash runs traps only between foreground commands); the handler stops it too.
  trap 'say "interrupted"; [[ -z $SUBMIT_PID ]] || kill -TERM "$SUBMIT_PID" 2>/dev/null; exit 130' \
    INT TERM HUP
  local addr
  addr=$(cmd_start "${start_args[@]}")
  say "submitting $scene"
  local job
  irfarm_cli submit --coordinator "$addr" "$scene" --wait -o "$out" "${submit_args[@]}" \
    >"$STATE/submit.out" &
  SUBMIT_PID=$!
  wait "$SUBMIT_PID" || status=$?
  SUBMIT_PID=""
  job=$(head -1 "$STATE/submit.out")
  if [[ -n $job ]] && irfarm_cli status --coordinator "$addr" "$job" --json >"$STATE/job.json"; then
    job_stats_json "$STATE/job.json" "$scene" >"$STATE/stats.json"
    python3 - "$STATE/stats.json" <<'PY' >&2
import json, sys
s = json.load(open(sys.argv[1]))
for w in s["workers"]:
    r = w["records"]
    print("local-cluster: %-9s tiles %3d  records computed %6d received %6d used %9d (remote %d)"
          % (w["name"], w["tiles"], r["computed"], r["received"], r["used"], r["used_remote"]))
t = s["total"]
print("local-cluster: job %s %s in %.2f s wall, %d records computed" %
      (s["job"], s["state"], s["wall_seconds"], t["records"]["computed"]))
PY
    if [[ -n $stats ]]; then
      cp "$STATE/stats.json" "$stats.tmp.$$" && mv "$stats.tmp.$$" "$stats"
    fi
  fi
  if ((status != 0)); then
    for f in "$STATE"/*.log; do echo "--- $(basename "$f")"; tail -n 15 "$f"; done >&2
    die "job failed (exit $status)"
  fi
  say "wrote $out${stats:+ and $stats}"
}

case ${1:-} in
  start) shift; cmd_start "$@" ;;
  stop) shift; cmd_stop ;;
  status) shift; cmd_status ;;
  run) shift; cmd_run "$@" ;;
  -h|--help|help|"") usage ;;
  *) die "unknown command '$1' (start, stop, status, run)" ;;
esac

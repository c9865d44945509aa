# Helpers for the multi-process service tests: free loopback ports, starting and stopping a real
# irfarm-coordinator and irfarm-worker processes, waiting on jobs, reading numbers from JSON.
# Every process started here is recorded and killed (by pid) when the test script exits.
set -euo pipefail

BIN=${BIN:?set BIN to the build directory}
DATA=${DATA:?set DATA to tests/data}
WORK=$(mktemp -d /tmp/irfarm-svc-test.XXXXXX)
# The processes' own temporary folders (scene bundles, results) go under WORK too: a process the
# test kills with SIGKILL leaves its folder, and WORK goes at the end.
export TMPDIR=$WORK/tmp
mkdir -p "$TMPDIR"
PIDS=()

cleanup() {
  for pid in "${PIDS[@]}"; do kill -9 "$pid" 2>/dev/null || true; done
  for pid in "${PIDS[@]}"; do wait "$pid" 2>/dev/null || true; done
  rm -rf "$WORK"
}
trap cleanup EXIT

fail() { echo "FAIL: $*" >&2; for f in "$WORK"/*.log; do echo "--- $f"; tail -20 "$f"; done >&2; exit 1; }

# free_port: a loopback port nothing listens on now, drawn at random below the kernel's ephemeral
# range (/proc/sys/net/ipv4/ip_local_port_range, 32768 and up here): a port from bind(0) is one
# that outgoing connections (gRPC clients, redis-cli) and other tests' bind(0) draw from too, and
# one of them could take it before the server binds it.
free_port() {
  python3 -c '
import random, socket
try:
    low = int(open("/proc/sys/net/ipv4/ip_local_port_range").read().split()[0])
except (OSError, ValueError, IndexError):
    low = 0
for _ in range(200):
    # Where the ephemeral range leaves no room below it, the kernel picks (bind to port 0).
    port = random.randrange(10000, low) if low >= 12000 else 0
    s = socket.socket()
    try:
        s.bind(("127.0.0.1", port))
        port = s.getsockname()[1]
    except OSError:
        continue
    finally:
        s.close()
    print(port)
    break
else:
    raise SystemExit("no free port")'
}

# alive PID WHAT LOG: fails (with LOG's tail) when PID has exited: a server that could not bind
# its port exits, and another test's server on that port would answer in its place.
alive() {
  kill -0 "$1" 2>/dev/null || fail "$2 exited: $(tail -5 "$3" 2>/dev/null)"
}

# start_redis: a real redis-server on a free loopback port, no persistence, in $WORK/redis; sets
# RPORT and REDIS_PID and waits until it answers.
start_redis() {
  command -v redis-server >/dev/null || fail "redis-server not installed (deploy/setup.sh installs it)"
  RPORT=$(free_port)
  mkdir -p "$WORK/redis"
  redis-server --port "$RPORT" --bind 127.0.0.1 --dir "$WORK/redis" --save "" --appendonly no \
    >"$WORK/redis.log" 2>&1 &
  REDIS_PID=$!
  PIDS+=("$REDIS_PID")
  # Ready when its own log says so (a redis-server of another test on the port would answer the
  # ping too) and it answers.
  for _ in $(seq 50); do
    alive "$REDIS_PID" redis-server "$WORK/redis.log"
    grep -q "Ready to accept connections" "$WORK/redis.log" 2>/dev/null &&
      redis-cli -p "$RPORT" ping >/dev/null 2>&1 && return 0
    sleep 0.1
  done
  fail "redis-server did not answer on port $RPORT"
}

# start_coordinator ADDR [args...]: starts it and waits until it answers.
start_coordinator() {
  local addr=$1; shift
  local log=$WORK/coordinator.log before
  before=$(grep -c "listening on $addr " "$log" 2>/dev/null || true)
  "$BIN/irfarm-coordinator" --listen "$addr" "$@" >>"$log" 2>&1 &
  COORD_PID=$!
  PIDS+=("$COORD_PID")
  # Up when this one has logged that it listens (another test's coordinator on the port would
  # answer `status` too) and it answers.
  for _ in $(seq 100); do
    alive "$COORD_PID" "coordinator on $addr" "$log"
    (($(grep -c "listening on $addr " "$log" 2>/dev/null || true) > ${before:-0})) &&
      "$BIN/irfarm" status --coordinator "$addr" >/dev/null 2>&1 && return 0
    sleep 0.1
  done
  fail "coordinator did not come up on $addr"
}

# start_worker ADDR NAME: sets LAST_WORKER_PID.
start_worker() {
  "$BIN/irfarm-worker" --coordinator "$1" --threads 1 --name "$2" >>"$WORK/$2.log" 2>&1 &
  LAST_WORKER_PID=$!
  PIDS+=("$LAST_WORKER_PID")
}

# start_cluster [--redis] WORKERS [COORDINATOR_ARGS...]: a local cluster. With --redis, first a
# redis-server (start_redis) that the coordinator uses; then a coordinator on a free loopback port
# (ADDR, COORD_PID; waits until it answers) and one worker per name in the space-separated list
# WORKERS (WORKER_PIDS in that order; LAST_WORKER_PID is the last one's).
start_cluster() {
  local redis_args=()
  if [[ $1 == --redis ]]; then
    shift
    start_redis
    redis_args=(--redis "127.0.0.1:$RPORT")
  fi
  local names=$1 name; shift
  ADDR=127.0.0.1:$(free_port)
  start_coordinator "$ADDR" "${redis_args[@]}" "$@"
  WORKER_PIDS=()
  for name in $names; do
    start_worker "$ADDR" "$name"
    WORKER_PIDS+=("$LAST_WORKER_PID")
  done
  wait_workers "$ADDR" "${#WORKER_PIDS[@]}"
}

# wait_workers ADDR N: until the coordinator lists at least N connected workers (30 s). A job
# submitted before then can be rendered by the first worker alone (a 64x64 job takes under a
# second), which the scripts that check both workers' counters cannot tell from a broken exchange.
wait_workers() {
  local n
  for _ in $(seq 300); do
    n=$("$BIN/irfarm" status --coordinator "$1" --workers --json 2>/dev/null |
      python3 -c 'import json,sys; print(len(json.load(sys.stdin).get("workers", [])))' 2>/dev/null) || n=0
    ((n >= $2)) && return 0
    sleep 0.1
  done
  fail "only $n of $2 workers connected to $1 in 30 s"
}

# render_job OUT SUBMIT_ARGS...: `irfarm submit SUBMIT_ARGS` to $ADDR; waits for the job (120 s),
# checks that it succeeded and fetches its image to OUT. Sets JOB.
render_job() {
  local out=$1; shift
  JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$@" -q)
  check "job $JOB succeeded" "'$(wait_job "$ADDR" "$JOB" 120)' == 'JOB_STATE_SUCCEEDED'"
  "$BIN/irfarm" fetch --coordinator "$ADDR" "$JOB" -o "$out"
}

# job_field ADDR JOB PYEXPR: evaluates PYEXPR with j = the job's JSON (irfarm status --json).
job_field() {
  "$BIN/irfarm" status --coordinator "$1" "$2" --json | python3 -c "import json,sys; j=json.load(sys.stdin); print($3)"
}

# wait_job ADDR JOB TIMEOUT_S: waits for a final state; prints it.
wait_job() {
  local end=$((SECONDS + $3)) state
  while ((SECONDS < end)); do
    state=$(job_field "$1" "$2" "j['state']")
    case $state in *SUCCEEDED|*FAILED|*CANCELLED) echo "$state"; return 0 ;; esac
    sleep 0.2
  done
  fail "job $2 did not finish in $3 s"
}

# wait_tiles ADDR JOB N: until at least N tiles are done.
wait_tiles() {
  for _ in $(seq 600); do
    (($(job_field "$1" "$2" "j['tilesDone']") >= $3)) && return 0
    sleep 0.05
  done
  fail "job $2 never reached $3 tiles"
}

# mitsuba_x4_error SCENE "WxH Nspp": the largest relMSE against SCENE's reference-x4.exr (64x64)
# of 8 Mitsuba 3 renders (different seeds) at WxH and N spp, box-filtered to 64x64, from
# $DATA/scenes/SCENE/mitsuba-x4-noise.json (made by make_x4_noise.py there). The tolerance of a
# service image compared with reference-x4.exr: an error bound that does not come from irfarm.
mitsuba_x4_error() {
  python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["renders"][sys.argv[2]]["relmse_vs_ref_max"])' \
    "$DATA/scenes/$1/mitsuba-x4-noise.json" "$2" || fail "no Mitsuba error for $1 at '$2'"
}

# within_tolerance LABEL EXR [FACTOR]: EXR, box-filtered FACTORxFACTOR first when FACTOR is given,
# against the script's $REF: prints its relMSE and checks that it is at most the script's $TOL.
within_tolerance() {
  local img=$2
  if (($# > 2)); then
    img=${2%.exr}-down$3.exr
    "$BIN/irfarm" downsample "$2" "$img" --factor "$3"
  fi
  local err
  err=$(relmse "$img" "$REF")
  echo "MEASURED $1 relMSE vs reference: $err (tolerance $TOL)"
  check "$1 within the tolerance" "$err <= $TOL"
}

relmse() { "$BIN/irfarm" compare "$1" "$2" | python3 -c 'import json,sys; print(json.load(sys.stdin)["relmse"])'; }
computed() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["records"]["computed"])' "$1"; }
# check "description" PYTHON_BOOL_EXPR
check() { python3 -c "import sys; sys.exit(0 if ($2) else 1)" || fail "$1: $2"; echo "ok: $1 ($2)"; }

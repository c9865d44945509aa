#!/usr/bin/env bash
# deploy/local-cluster.sh end to end with real processes on 127.0.0.1:
#  1. `run` renders the Cornell box at 64x64 through a coordinator and two workers: the EXR exists
#     and the stats JSON has the job's two workers, each with tiles and records computed, and the
#     total matches the sum of the workers;
#  2. `run` stopped with SIGTERM mid-job leaves no coordinator or worker behind;
#  3. `start --redis` then `stop`: the coordinator answers on the chosen port (with the cluster's
#     client token; without it, or with the worker token, UNAUTHENTICATED), its redis-server
#     runs, and after `stop` none of the cluster's processes is left.
source "$(dirname "$0")/lib.sh"
SCRIPT=$(cd "$(dirname "$0")/../.." && pwd)/deploy/local-cluster.sh
SCENE=$DATA/scenes/cornell-box/scene.xml
export IRFARM_BIN=$BIN
# The clusters' client token (local-cluster.sh uses $IRFARM_TOKEN when set); `irfarm` reads it too.
export IRFARM_TOKEN=local-cluster-test-token-$$-$RANDOM

# --- 1. run ---
"$SCRIPT" run "$SCENE" -o "$WORK/out.exr" --stats "$WORK/out.json" -D resx=64 -D resy=64 \
  --tile-size 16 --port "$(free_port)" 2>"$WORK/run.log" || { cat "$WORK/run.log" >&2; fail "local-cluster.sh run failed"; }
cat "$WORK/run.log"
[[ -s $WORK/out.exr ]] || fail "no EXR written"
"$BIN/irfarm" compare "$WORK/out.exr" "$WORK/out.exr" >/dev/null || fail "EXR does not read back"
python3 - "$WORK/out.json" <<'PY' || fail "stats JSON"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["state"] == "SUCCEEDED", s["state"]
assert (s["width"], s["height"]) == (64, 64), (s["width"], s["height"])
ws = s["workers"]
assert len(ws) == 2, "expected 2 workers, got %d" % len(ws)
assert sorted(w["name"] for w in ws) == ["worker-1", "worker-2"], [w["name"] for w in ws]
for w in ws:
    assert w["tiles"] > 0 and w["records"]["computed"] > 0 and w["records"]["used"] > 0, w
assert sum(w["tiles"] for w in ws) == s["tiles_total"] == 16
assert s["total"]["records"]["computed"] == sum(w["records"]["computed"] for w in ws)
assert s["wall_seconds"] > 0
print("ok: stats JSON: %s" % ", ".join("%s %d tiles %d computed %d received" % (
    w["name"], w["tiles"], w["records"]["computed"], w["records"]["received"]) for w in ws))
PY

# --- 2. SIGTERM mid-job: nothing left behind ---
PORT=$(free_port)
"$SCRIPT" run "$SCENE" -o "$WORK/big.exr" -D resx=256 -D resy=256 --port "$PORT" \
  --threads 1 >"$WORK/run2.log" 2>&1 &
RUN_PID=$!
PIDS+=("$RUN_PID")
for _ in $(seq 200); do
  "$BIN/irfarm" status --coordinator "127.0.0.1:$PORT" 2>/dev/null | grep -q RUNNING && break
  sleep 0.05
done
kill -TERM "$RUN_PID"
wait "$RUN_PID" && fail "interrupted run exited 0"
sleep 0.2
if pgrep -f "127.0.0.1:$PORT" >/dev/null; then
  pgrep -af "127.0.0.1:$PORT" >&2; fail "processes left after an interrupted run"
fi
[[ ! -e $WORK/big.exr ]] || fail "an interrupted run wrote an image"
echo "ok: interrupted run cleaned up ($(grep -c . "$WORK/run2.log") log lines)"

# --- 3. start --redis / stop ---
export IRFARM_CLUSTER_DIR=$WORK/cluster
PORT=$(free_port)
ADDR=$("$SCRIPT" start --redis --workers 2 --port "$PORT" 2>"$WORK/start.log") ||
  { cat "$WORK/start.log" >&2; fail "start failed"; }
for f in "$IRFARM_CLUSTER_DIR"/*.pid; do read -r pid _ <"$f"; PIDS+=("$pid"); done
[[ $ADDR == "127.0.0.1:$PORT" ]] || fail "start printed '$ADDR'"
"$BIN/irfarm" status --coordinator "$ADDR" >/dev/null || fail "coordinator does not answer"
# Without the token (or with the worker token) the coordinator refuses.
OUT=$(IRFARM_TOKEN= "$BIN/irfarm" status --coordinator "$ADDR" 2>&1) && fail "no token: accepted"
[[ $OUT == *UNAUTHENTICATED* ]] || fail "no token: $OUT"
OUT=$("$BIN/irfarm" status --coordinator "$ADDR" --token-file "$IRFARM_CLUSTER_DIR/worker.token" \
  2>&1) && fail "worker token on the job API: accepted"
[[ $OUT == *UNAUTHENTICATED* ]] || fail "worker token on the job API: $OUT"
[[ $(stat -c %a "$IRFARM_CLUSTER_DIR/client.token") == 600 ]] || fail "client.token is not mode 600"
echo "ok: the cluster refuses calls without its client token"
"$SCRIPT" status >/dev/null || fail "status says no cluster"
"$SCRIPT" start --port "$(free_port)" 2>/dev/null && fail "a second start was accepted"
"$SCRIPT" stop 2>/dev/null
sleep 0.2
if pgrep -f "127.0.0.1:$PORT" >/dev/null || pgrep -f "$IRFARM_CLUSTER_DIR/redis" >/dev/null; then
  fail "processes left after stop"
fi
"$SCRIPT" status >/dev/null && fail "status still sees a cluster"
echo "ok: start --redis / stop"
echo PASS

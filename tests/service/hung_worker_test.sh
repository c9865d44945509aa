#!/usr/bin/env bash
# A hung worker (SIGSTOP) holding a lease, with real processes on 127.0.0.1: Cornell box 64x64,
# 16 tiles of 16 px, two workers, heartbeat period 1 s. The coordinator must take the stopped
# worker's lease once it has been silent for 3 heartbeat periods (it logs how long; at most 3
# periods plus its 0.25 s expiry tick, 3.5 s allowed), the other worker renders the tile, and the
# job finishes in under 15 s from submission (with the old 120 s lease it took over 120 s). The
# worker is continued afterwards: its stale result is refused without failing anything.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
start_cluster "healthy victim" --heartbeat-seconds 1
VICTIM=$LAST_WORKER_PID

# victim_leased: true when the worker named victim holds a lease now.
victim_leased() {
  "$BIN/irfarm" status --coordinator "$ADDR" --workers --json | python3 -c '
import json, sys
c = json.load(sys.stdin)
sys.exit(0 if any(w["name"] == "victim" and w["hasLease"] for w in c["workers"]) else 1)'
}

T0=$(date +%s.%N)
JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" -Dresx=64 -Dresy=64 --tile-size 16 -q)
STOPPED=0
for _ in $(seq 300); do
  if victim_leased; then
    kill -STOP "$VICTIM"
    # Still holding it once stopped (it may have finished the tile in between): else go on.
    if victim_leased; then STOPPED=1; break; fi
    kill -CONT "$VICTIM"
  fi
  sleep 0.01
done
((STOPPED)) || fail "never caught the victim holding a lease"
echo "stopped the victim at $(job_field "$ADDR" "$JOB" "j['tilesDone']")/16 tiles"
STATE=$(wait_job "$ADDR" "$JOB" 60)
T1=$(date +%s.%N)
ELAPSED=$(python3 -c "print(round($T1 - $T0, 2))")
SILENT=$(python3 -c '
import re, sys
m = re.search(r"\(victim\) silent for ([0-9.]+) s", open(sys.argv[1]).read())
print(m.group(1) if m else "")' "$WORK/coordinator.log")
[[ -n $SILENT ]] || fail "the coordinator never declared the stopped worker silent"
echo "MEASURED stopped worker's lease taken after ${SILENT} s of silence; job finished ${ELAPSED} s after submission"
check "job succeeded" "'$STATE' == 'JOB_STATE_SUCCEEDED'"
check "every tile done" "$(job_field "$ADDR" "$JOB" "j['tilesDone']") == 16"
check "lease taken within 3 heartbeat periods (+ expiry tick)" "3.0 <= $SILENT <= 3.5"
check "job finished in under 15 s" "$ELAPSED < 15"
kill -CONT "$VICTIM"
sleep 1.5
kill -0 "$VICTIM" || fail "the continued worker died"
echo PASS

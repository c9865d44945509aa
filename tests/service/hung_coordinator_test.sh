#!/usr/bin/env bash
# A hung coordinator, with real processes on 127.0.0.1: a worker given two coordinators (A,B)
# registers with A; B starts; A is frozen with SIGSTOP (a hung process: its socket stays open, it
# answers nothing, as behind a partition without a reset). The coordinator sends nothing to an
# idle worker, so only the worker's HTTP/2 keepalive pings (--keepalive-seconds 2: a ping every
# 2 s, answered within 2 s) can tell: the worker must leave A and register with B within 10 s of
# the freeze (before keepalive it waited on A forever), and render a job B is given. A is
# continued at the end.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
A=127.0.0.1:$(free_port)
B=127.0.0.1:$(free_port)
start_coordinator "$A"
A_PID=$COORD_PID
"$BIN/irfarm-worker" --coordinator "$A,$B" --threads 1 --name pinger --keepalive-seconds 2 \
  >>"$WORK/pinger.log" 2>&1 &
PIDS+=($!)
wait_workers "$A" 1
start_coordinator "$B"
grep -q "registered with $B" "$WORK/pinger.log" && fail "the worker registered with B before A froze"
kill -STOP "$A_PID"
T0=$(date +%s.%N)
MOVED=0
for _ in $(seq 150); do
  if grep -q "registered with $B" "$WORK/pinger.log"; then MOVED=1; break; fi
  sleep 0.1
done
T1=$(date +%s.%N)
kill -CONT "$A_PID"
((MOVED)) || fail "the worker did not leave the frozen coordinator in 15 s"
ELAPSED=$(python3 -c "print(round($T1 - $T0, 2))")
echo "MEASURED the worker registered with B ${ELAPSED} s after A froze"
check "moved within 10 s" "$ELAPSED <= 10"
ADDR=$B
render_job "$WORK/b.exr" "$SCENE" -Dresx=32 -Dresy=32
echo PASS

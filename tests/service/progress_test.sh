#!/usr/bin/env bash
# `irfarm status` rate and ETA, `irfarm watch`, `irfarm delete` (issue 11, parts 6-7), against a
# real coordinator and one real worker on 127.0.0.1 rendering the Cornell box at 128x128
# (64 tiles of 16 px):
#  - `irfarm watch JOB` (not a terminal: a line at most once a second) follows the job to
#    "SUCCEEDED ... 100% 64/64 tiles" and exits 0; its lines' percentages never go down;
#  - `irfarm status JOB` while the job runs shows a rate and an ETA; the ETA shown once a quarter
#    of the tiles is done is within 4x of the time the job then actually took (tiles differ in
#    cost, and the machine is shared: a loose, independent bound);
#  - `irfarm delete` refuses a running job (FAILED_PRECONDITION), removes a finished one (status
#    then NOT_FOUND), and a second delete is NOT_FOUND; `irfarm watch` of a cancelled job exits 1.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
start_cluster w1
JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" -Dresx=128 -Dresy=128 --tile-size 16 -q)
"$BIN/irfarm" watch --coordinator "$ADDR" "$JOB" >"$WORK/watch.txt" 2>&1 &
WATCH_PID=$!
PIDS+=("$WATCH_PID")

if "$BIN/irfarm" delete --coordinator "$ADDR" "$JOB" 2>"$WORK/del-running.txt"; then
  fail "a running job was deleted"
fi
grep -q FAILED_PRECONDITION "$WORK/del-running.txt" || fail "unclear refusal: $(cat "$WORK/del-running.txt")"
echo "ok: delete of a running job refused: $(cat "$WORK/del-running.txt")"

ETA_LINE=""
end=$((SECONDS + 180))
while ((SECONDS < end)); do
  line=$("$BIN/irfarm" status --coordinator "$ADDR" "$JOB")
  case $line in *SUCCEEDED*|*FAILED*|*CANCELLED*) break ;; esac
  done_tiles=$(sed -n 's/.* \([0-9]*\)\/64 tiles.*/\1/p' <<<"$line")
  if [[ -z $ETA_LINE && -n $done_tiles && $done_tiles -ge 16 ]]; then
    ETA_LINE=$line
    ETA_AT=$(python3 -c 'import time; print(time.time())')
  fi
  sleep 0.2
done
END_AT=$(python3 -c 'import time; print(time.time())')
wait "$WATCH_PID" || fail "irfarm watch exited $? for a job that succeeded: $(cat "$WORK/watch.txt")"
echo "status at >= 25%: $ETA_LINE"
[[ -n $ETA_LINE ]] || fail "no status line seen between 25% and the end"
python3 - "$ETA_LINE" "$ETA_AT" "$END_AT" <<'PY' || fail "ETA"
import re, sys
line, at, end = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
m = re.search(r"([0-9.]+) tiles/s  ETA (?:(\d+)h)?(?:(\d+)m)?(?:(\d+)s)?", line)
assert m, "no rate/ETA in: " + line
eta = int(m.group(2) or 0) * 3600 + int(m.group(3) or 0) * 60 + int(m.group(4) or 0)
actual = end - at
print("MEASURED ETA %d s at >= 25%% done, actual remaining %.1f s (rate %s tiles/s)" % (eta, actual, m.group(1)))
# The ETA is rounded to whole seconds: allow 1 s either way on top of the 4x.
assert actual / 4 - 1 <= eta <= 4 * actual + 1, "ETA %d s vs %.1f s actual" % (eta, actual)
print("ok: ETA within 4x of the actual remaining time")
PY
cat "$WORK/watch.txt"
tail -1 "$WORK/watch.txt" | grep -q "SUCCEEDED.*100%  64/64 tiles" || fail "watch did not end at 100%"
python3 - "$WORK/watch.txt" <<'PY' || fail "watch percentages"
import re, sys
p = [int(m.group(1)) for m in re.finditer(r"\] +(\d+)%", open(sys.argv[1]).read())]
assert len(p) >= 2 and p == sorted(p) and p[-1] == 100, p
print("ok: watch printed %d lines, percentages %s" % (len(p), p))
PY

"$BIN/irfarm" delete --coordinator "$ADDR" "$JOB" || fail "delete of a finished job"
if "$BIN/irfarm" status --coordinator "$ADDR" "$JOB" 2>"$WORK/gone.txt"; then fail "deleted job still listed"; fi
grep -q NOT_FOUND "$WORK/gone.txt" || fail "status of a deleted job: $(cat "$WORK/gone.txt")"
if "$BIN/irfarm" delete --coordinator "$ADDR" "$JOB" 2>"$WORK/again.txt"; then fail "deleted twice"; fi
grep -q NOT_FOUND "$WORK/again.txt" || fail "second delete: $(cat "$WORK/again.txt")"
echo "ok: delete of a finished job; then status and delete are NOT_FOUND"

# A job cancelled while watched: watch exits 1 and says so.
kill -STOP "$LAST_WORKER_PID"  # keep the next job from finishing
J2=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" -Dresx=128 -Dresy=128 --tile-size 16 -q)
"$BIN/irfarm" watch --coordinator "$ADDR" "$J2" >"$WORK/watch2.txt" 2>&1 &
W2=$!
PIDS+=("$W2")
sleep 0.5
"$BIN/irfarm" cancel --coordinator "$ADDR" "$J2" >/dev/null
if wait "$W2"; then fail "watch of a cancelled job exited 0"; fi
grep -q CANCELLED "$WORK/watch2.txt" || fail "watch output: $(cat "$WORK/watch2.txt")"
kill -CONT "$LAST_WORKER_PID"
echo "ok: watch of a cancelled job exits 1: $(tail -1 "$WORK/watch2.txt")"
echo PASS

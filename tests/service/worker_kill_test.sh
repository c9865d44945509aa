#!/usr/bin/env bash
# Failure tests with real processes on 127.0.0.1, Cornell box at 128x128 (64 tiles of 16 px):
#  1. a worker killed with SIGKILL mid-job: the job still completes with every tile and its image
#     (box-filtered to 64x64) is within noise of the reference (3x a single-process render's
#     relMSE at the same settings);
#  2. on a real redis-server: the coordinator killed with SIGKILL mid-job and restarted on the
#     same Redis: every tile finished and every record merged before the kill is still there,
#     and the job completes.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
REF=$DATA/scenes/cornell-box/reference-x4.exr
OPTS=(-Dresx=128 -Dresy=128)

"$BIN/irfarm" render "$SCENE" "${OPTS[@]}" --threads 2 -q -o "$WORK/local.exr"
"$BIN/irfarm" downsample "$WORK/local.exr" "$WORK/local64.exr" --factor 2
TOL=$(python3 -c "print(3 * $(relmse "$WORK/local64.exr" "$REF"))")


# --- 1. worker SIGKILL ---
ADDR=127.0.0.1:$(free_port)
start_coordinator "$ADDR"
start_worker "$ADDR" k1
start_worker "$ADDR" k2
VICTIM=$LAST_WORKER_PID
JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" "${OPTS[@]}" --tile-size 16 -q)
wait_tiles "$ADDR" "$JOB" 12
kill -9 "$VICTIM"
echo "killed worker k2 at $(job_field "$ADDR" "$JOB" "j['tilesDone']")/64 tiles"
STATE=$(wait_job "$ADDR" "$JOB" 180)
check "job survived the worker kill" "'$STATE' == 'JOB_STATE_SUCCEEDED'"
check "every tile done" "$(job_field "$ADDR" "$JOB" "j['tilesDone']") == 64"
"$BIN/irfarm" fetch --coordinator "$ADDR" "$JOB" -o "$WORK/killed.exr"
"$BIN/irfarm" downsample "$WORK/killed.exr" "$WORK/killed64.exr" --factor 2
K=$(relmse "$WORK/killed64.exr" "$REF")
echo "MEASURED worker-kill image relMSE vs reference: $K (tolerance $TOL)"
check "image within noise after worker kill" "$K <= $TOL"
kill -9 "$COORD_PID"

# --- 2. coordinator SIGKILL on Redis ---
start_redis
ADDR=127.0.0.1:$(free_port)
start_coordinator "$ADDR" --redis "127.0.0.1:$RPORT"
start_worker "$ADDR" r1
start_worker "$ADDR" r2
JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" "${OPTS[@]}" --tile-size 16 -q)
wait_tiles "$ADDR" "$JOB" 16
# What the coordinator has reported finished and merged; it can only grow until the kill.
TILES_BEFORE=$(job_field "$ADDR" "$JOB" "j['tilesDone']")
RECORDS_BEFORE=$(job_field "$ADDR" "$JOB" "j['recordsMerged']")
kill -9 "$COORD_PID"
echo "MEASURED killed coordinator after $TILES_BEFORE tiles / $RECORDS_BEFORE records merged"
start_coordinator "$ADDR" --redis "127.0.0.1:$RPORT"
AFTER_TILES=$(job_field "$ADDR" "$JOB" "j['tilesDone']")
AFTER_RECORDS=$(job_field "$ADDR" "$JOB" "j['recordsMerged']")
check "tiles finished before the kill are still done" "$AFTER_TILES >= $TILES_BEFORE"
echo "MEASURED after restart: $AFTER_TILES tiles, $AFTER_RECORDS records"
check "records merged before the kill are still there" "$AFTER_RECORDS >= $RECORDS_BEFORE > 0"
STATE=$(wait_job "$ADDR" "$JOB" 180)
check "job completed after the coordinator restart" "'$STATE' == 'JOB_STATE_SUCCEEDED'"
check "every tile done" "$(job_field "$ADDR" "$JOB" "j['tilesDone']") == 64"
"$BIN/irfarm" fetch --coordinator "$ADDR" "$JOB" -o "$WORK/restarted.exr"
"$BIN/irfarm" downsample "$WORK/restarted.exr" "$WORK/restarted64.exr" --factor 2
R=$(relmse "$WORK/restarted64.exr" "$REF")
echo "MEASURED coordinator-restart image relMSE vs reference: $R (tolerance $TOL)"
check "image within noise after coordinator restart" "$R <= $TOL"
echo PASS

#!/usr/bin/env bash
# Failure tests with real processes on 127.0.0.1, Cornell box at 128x128 (64 tiles of 16 px):
#  1. a worker killed with SIGKILL mid-job, holding a lease: the job still completes with every
#     tile (the killed worker's included; a worker started after the kill removes the scene folder
#     the killed one left) and its image,
#     box-filtered to 64x64, has a relMSE against the 64x64 reference (reference-x4.exr) within
#     Mitsuba's own at the job's 128x128 and 64 spp, box-filtered the same way (the largest of 8
#     seeds, 1.27e-3, tests/data/scenes/cornell-box/mitsuba-x4-noise.json: a bound that does not
#     come from irfarm). This test is about losing nothing: one tile blacked out puts the image at
#     1.8e-3 (a dark corner) to 9.0e-3 (the centre). Its images measure 1.8-3.5e-4 (30 runs,
#     2026-12-05), against Mitsuba's 3.1e-4 mean at 256 spp: the bound of 256 spp failed about
#     one run in 30, on the tail. The quality claim against Mitsuba at 256 spp is
#     two_workers_test.sh's and batch_test.sh's (64x64, with room to spare);
#  2. on a real redis-server: the coordinator killed with SIGKILL mid-job and restarted on the
#     same Redis: every tile finished and every record merged before the kill is still there,
#     and the job completes with its image within the same bound.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
REF=$DATA/scenes/cornell-box/reference-x4.exr
OPTS=(-Dresx=128 -Dresy=128)
TOL=$(mitsuba_x4_error cornell-box "128x128 64spp")

# job_completes WHAT NAME: $JOB succeeds (180 s) with all 64 tiles; its image ($WORK/NAME.exr),
# box-filtered to 64x64, is within the tolerance.
job_completes() {
  check "job completed $1" "'$(wait_job "$ADDR" "$JOB" 180)' == 'JOB_STATE_SUCCEEDED'"
  check "every tile done" "$(job_field "$ADDR" "$JOB" "j['tilesDone']") == 64"
  "$BIN/irfarm" fetch --coordinator "$ADDR" "$JOB" -o "$WORK/$2.exr"
  within_tolerance "image $1 (64x64)" "$WORK/$2.exr" 2
}

# --- 1. worker SIGKILL ---
CM=127.0.0.1:$(free_port)
start_cluster "k1 k2" --metrics "$CM"
VICTIM=$LAST_WORKER_PID
JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" "${OPTS[@]}" --tile-size 16 -q)
# Killed while it holds a lease, early in the job (stopped first, then checked, so that it cannot
# finish the tile in between): the job's 64 tiles then include one the coordinator had to take
# back from it.
k2_leased() {
  "$BIN/irfarm" status --coordinator "$ADDR" --workers --json | python3 -c '
import json, sys
c = json.load(sys.stdin)
sys.exit(0 if any(w["name"] == "k2" and w["hasLease"] for w in c["workers"]) else 1)'
}
HELD=0
for _ in $(seq 300); do
  kill -STOP "$VICTIM"
  if k2_leased; then HELD=1; break; fi
  kill -CONT "$VICTIM"
  sleep 0.02
done
kill -9 "$VICTIM"
wait "$VICTIM" 2>/dev/null || true  # reaped: a zombie still answers kill(pid, 0)
check "k2 held a lease when killed" "$HELD == 1"
echo "killed worker k2 at $(job_field "$ADDR" "$JOB" "j['tilesDone']")/64 tiles"
# The killed worker's copy of the scene stays behind (nothing ran its clean-up); a worker started
# on the same machine afterwards removes it (its pid is gone), and helps finish the job.
k2_folders() { ls -d "$TMPDIR/irfarm-worker-$VICTIM-"* 2>/dev/null | wc -l; }
check "the killed worker's scene folder is left" "$(k2_folders) == 1"
start_worker "$ADDR" k3
for _ in $(seq 100); do [[ $(k2_folders) == 0 ]] && break; sleep 0.05; done
check "a worker started later removed it" "$(k2_folders) == 0"
job_completes "after the worker kill" killed
# The coordinator took a lease back from the disconnected worker (its tile was rendered again).
LOST=$(curl -sf "http://$CM/metrics" | awk '/^irfarm_lease_expiries_total\{reason="disconnected"\}/ {print $2}')
check "a lease taken back from the killed worker" "${LOST:-0} >= 1"
kill -9 "$COORD_PID"

# --- 2. coordinator SIGKILL on Redis ---
start_cluster --redis "r1 r2"
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
job_completes "after the coordinator restart" restarted
echo PASS

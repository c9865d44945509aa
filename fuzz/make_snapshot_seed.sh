#!/usr/bin/env bash
# Makes the snapshot_fuzz seed: a real cache snapshot exported by the service (a coordinator and
# one worker on 127.0.0.1 render the Cornell box at 16x16 in one tile, then `irfarm snapshot`
# exports the job's records). Kept small (109 records, 4836 bytes when made) so the fuzzer mutates
# real records rather than spending its time on a large file.
#   BIN=build fuzz/make_snapshot_seed.sh tests/data/fuzz/snapshot_fuzz/cornell-16x16.snap
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: BIN=build $0 OUT.snap}
BIN=${BIN:-build} DATA=$PWD/tests/data
export BIN DATA
source tests/service/lib.sh
ADDR=127.0.0.1:$(free_port)
start_coordinator "$ADDR"
start_worker "$ADDR" seed
JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$DATA/scenes/cornell-box/scene.xml" \
  -Dresx=16 -Dresy=16 --tile-size 16 -q)
STATE=$(wait_job "$ADDR" "$JOB" 120)
[[ $STATE == JOB_STATE_SUCCEEDED ]] || fail "job $JOB: $STATE"
"$BIN/irfarm" snapshot --coordinator "$ADDR" "$JOB" -o "$out"
echo "$out: $(stat -c %s "$out") bytes, $(( ($(stat -c %s "$out") - 40) / 56 )) records"

#!/usr/bin/env bash
# Two-process integration test: a real coordinator and two real workers on 127.0.0.1 render the
# Cornell box at 64x64 (16 tiles of 16 px). Checks, also against a single-process `irfarm render`:
#  - the image's relMSE against the 64x64 reference (reference-x4.exr) is within Mitsuba's own at
#    256 spp on that grid (the largest of 8 seeds, 1.28e-3, tests/data/scenes/cornell-box/
#    mitsuba-x4-noise.json: a bound that does not come from irfarm; irrcache at its defaults is
#    claimed to beat Mitsuba at 256 spp);
#  - each worker received the other's records, and they were used in lookups;
#  - each of the 16 tiles rendered once (the workers' tile counts sum to 16). Records computed by both workers against the
#    single-process render's (its mean over seeds 0-2) is printed, not asserted: the job's count
#    moves with the timing of the exchange (over 80 runs on 2026-12-07 the ratio was 1.07-1.20,
#    mean 1.12) and no source outside irfarm says what it should be; the bound of 1.2 it had
#    failed about once in 60 runs. At 64x64 the job without sharing below makes only 2-5% more
#    records than with it, so sharing itself is checked by the received and used counts;
#  - with sharing off, prints how many more records are computed;
#  - snapshot export then import: the warm job computes <= 5% of the first job's records (its
#    tiles wait for their regions' records, RegionReady; before they did, the snapshot's records
#    reached a tile with its region's backlog while it rendered, and the job made 61-89 new
#    records of about 830, where a local `render --cache-in` makes 4-16; with the wait, 4-26 in
#    13 runs), its image is within the same bound, and a snapshot of another scene is refused
#    (submit and local render).
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
REF=$DATA/scenes/cornell-box/reference-x4.exr
OPTS=(-Dresx=64 -Dresy=64)
TOL=$(mitsuba_x4_error cornell-box "64x64 256spp")

"$BIN/irfarm" render "$SCENE" "${OPTS[@]}" --threads 2 -q -o "$WORK/local0.exr" --stats "$WORK/local0.json"
L0=$(relmse "$WORK/local0.exr" "$REF")
LOCAL_REC=$(computed "$WORK/local0.json")
echo "single-process relMSE vs reference: $L0; records $LOCAL_REC; tolerance (Mitsuba 256 spp) $TOL"
LOCAL_SUM=$LOCAL_REC
for seed in 1 2; do
  "$BIN/irfarm" render "$SCENE" "${OPTS[@]}" --seed $seed --threads 2 -q -o "$WORK/local$seed.exr" --stats "$WORK/local$seed.json"
  LOCAL_SUM=$((LOCAL_SUM + $(computed "$WORK/local$seed.json")))
done
LOCAL_MEAN=$(python3 -c "print($LOCAL_SUM / 3)")

start_cluster "w1 w2"

# Shared records.
render_job "$WORK/dist.exr" "$SCENE" "${OPTS[@]}" --tile-size 16
within_tolerance "two-worker image" "$WORK/dist.exr"
"$BIN/irfarm" status --coordinator "$ADDR" "$JOB" --json > "$WORK/job.json"
python3 - "$WORK/job.json" "$LOCAL_MEAN" <<'PY' || fail "worker stats"
import json, sys
j = json.load(open(sys.argv[1])); local = float(sys.argv[2])
ws = j["workers"]
assert len(ws) == 2, ws
total = sum(int(w["recordsComputed"]) for w in ws)
for w in ws:
    print("worker %s: tiles %d computed %s received %s remote-used %s sent %s B recv %s B" % (
        w["workerName"], w["tiles"], w["recordsComputed"], w["recordsReceived"],
        w["remoteRecordsUsed"], w["bytesSent"], w["bytesReceived"]))
    assert int(w["recordsReceived"]) > 0, "worker received no records"
# Received records were used in lookups. Not necessarily by both: a worker that started late and
# rendered 3 of the 16 tiles left the other nothing near its own tiles in time (1 run in about 60).
assert sum(int(w["remoteRecordsUsed"]) for w in ws) > 0, "no worker used a received record"
print("MEASURED records computed: two workers %d, single process %.1f (seeds 0-2), ratio %.3f" % (total, local, total / local))
tiles = sum(int(w["tiles"]) for w in ws)
assert tiles == 16 == int(j["tilesTotal"]), "tiles rendered %d of %s" % (tiles, j["tilesTotal"])
print("ok: worker stats")
PY
SHARED_TOTAL=$(job_field "$ADDR" "$JOB" "sum(int(w['recordsComputed']) for w in j['workers'])")

# Sharing off: how many more records.
JOB2=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" "${OPTS[@]}" --tile-size 16 --no-share -q)
wait_job "$ADDR" "$JOB2" 120 >/dev/null
NOSHARE_TOTAL=$(job_field "$ADDR" "$JOB2" "sum(int(w['recordsComputed']) for w in j['workers'])")
echo "MEASURED records computed without sharing: $NOSHARE_TOTAL vs $SHARED_TOTAL shared ($(python3 -c "print('%.2fx' % ($NOSHARE_TOTAL / $SHARED_TOTAL))"))"

# Snapshot export -> import warm start.
"$BIN/irfarm" snapshot --coordinator "$ADDR" "$JOB" -o "$WORK/cache.snap"
JOB3=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" "${OPTS[@]}" --tile-size 16 --cache-in "$WORK/cache.snap" -q)
wait_job "$ADDR" "$JOB3" 120 >/dev/null
WARM_TOTAL=$(job_field "$ADDR" "$JOB3" "sum(int(w['recordsComputed']) for w in j['workers'])")
echo "MEASURED warm-start records computed: $WARM_TOTAL vs $SHARED_TOTAL cold ($(python3 -c "print('%.3f' % ($WARM_TOTAL / $SHARED_TOTAL))"))"
check "warm start computes <= 5%" "$WARM_TOTAL <= 0.05 * $SHARED_TOTAL"
"$BIN/irfarm" fetch --coordinator "$ADDR" "$JOB3" -o "$WORK/warm.exr"
within_tolerance "warm-start image" "$WORK/warm.exr"
"$BIN/irfarm" render "$SCENE" "${OPTS[@]}" --threads 2 -q --cache-in "$WORK/cache.snap" -o "$WORK/local-warm.exr" --stats "$WORK/local-warm.json"
check "local render --cache-in computes <= 5%" "$(computed "$WORK/local-warm.json") <= 0.05 * $LOCAL_REC"
OTHER=$DATA/scenes/specular/scene.xml
if "$BIN/irfarm" submit --coordinator "$ADDR" "$OTHER" --cache-in "$WORK/cache.snap" -q 2>"$WORK/refused.txt"; then
  fail "snapshot of another scene accepted"
fi
grep -q "another scene" "$WORK/refused.txt" || fail "unclear refusal: $(cat "$WORK/refused.txt")"
if "$BIN/irfarm" render "$OTHER" -Dresx=16 -Dresy=16 -q --cache-in "$WORK/cache.snap" -o "$WORK/x.exr" 2>"$WORK/refused2.txt"; then
  fail "local render accepted a snapshot of another scene"
fi
grep -q "another scene" "$WORK/refused2.txt" || fail "unclear refusal: $(cat "$WORK/refused2.txt")"
echo "ok: snapshot of another scene refused: $(cat "$WORK/refused.txt")"
echo PASS

#!/usr/bin/env bash
# Metrics (issue 11, part 1): a real coordinator on a real redis-server and two real workers on
# 127.0.0.1, each with --metrics, render the Cornell box at 320x320 (400 tiles: at 128x128 the
# job once ended before three scrapes, after the renders got faster; at 192x192, on 2026-12-04, it
# ran for exactly 3 scrapes when idle and failed once in a full ctest run). Both endpoints
# are scraped every 0.2 s during the job and once after it; every scrape must parse with the
# Prometheus project's own parser (prometheus_client.parser.text_string_to_metric_families), and:
#  - the coordinator's irfarm_job_tiles_done{job} and irfarm_job_records_merged{job} and each
#    worker's tiles and records-sent counters take several increasing values while the job runs;
#  - at the end, counted by independent processes: the coordinator's tiles_completed_total and the
#    job's tiles_done equal the job's tile count (from `irfarm status`), the sum of the workers'
#    tiles equals it too, the coordinator's records received equal the workers' records sent, and
#    its fan-out (records sent) equals what the workers received;
#  - latency histograms (tile_result handling, Redis put_tile) counted every tile; rays, cache hit
#    ratio and resident memory are present and positive.
# Skipped (77) when no python3 has prometheus_client (Debian: python3-prometheus-client).
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
PY=""
for p in python3 /usr/bin/python3; do
  if "$p" -c 'import prometheus_client' 2>/dev/null; then PY=$p; break; fi
done
[[ -n $PY ]] || { echo "SKIP: prometheus_client not installed (apt-get install python3-prometheus-client)"; exit 77; }
start_redis

ADDR=127.0.0.1:$(free_port)
CM=127.0.0.1:$(free_port)
start_coordinator "$ADDR" --redis "127.0.0.1:$RPORT" --metrics "$CM"
WM=()
for w in w1 w2; do
  m=127.0.0.1:$(free_port)
  "$BIN/irfarm-worker" --coordinator "$ADDR" --threads 1 --name "$w" --metrics "$m" \
    >>"$WORK/$w.log" 2>&1 &
  PIDS+=("$!")
  WM+=("$m")
done
for m in "$CM" "${WM[@]}"; do
  for _ in $(seq 50); do curl -sf "http://$m/metrics" >/dev/null && break; sleep 0.1; done
  curl -sf "http://$m/metrics" >/dev/null || fail "no metrics on $m"
done

# A request body past 64 KiB is refused (413) before any route reads it: 100 MB of zeros posted to
# the unauthenticated metrics port used to be read into the coordinator's memory whole.
code=$(head -c 100000000 /dev/zero | curl -s -o /dev/null -w '%{http_code}' -X POST \
  -H 'Content-Type: application/octet-stream' --data-binary @- "http://$CM/metrics" || true)
check "a 100 MB request body is refused" "'$code' == '413'"

JOB=$("$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" -Dresx=320 -Dresy=320 --tile-size 16 -q)
mkdir -p "$WORK/scrapes"
n=0
end=$((SECONDS + 180))
while ((SECONDS < end)); do
  n=$((n + 1))
  state=$(job_field "$ADDR" "$JOB" "j['state']")
  curl -sf "http://$CM/metrics" >"$WORK/scrapes/$n.c" || fail "coordinator scrape $n"
  curl -sf "http://${WM[0]}/metrics" >"$WORK/scrapes/$n.w1" || fail "worker 1 scrape $n"
  curl -sf "http://${WM[1]}/metrics" >"$WORK/scrapes/$n.w2" || fail "worker 2 scrape $n"
  echo "$state" >"$WORK/scrapes/$n.state"
  case $state in *SUCCEEDED|*FAILED|*CANCELLED) break ;; esac
  sleep 0.2
done
check "job succeeded" "'$state' == 'JOB_STATE_SUCCEEDED'"
sleep 0.5  # the last record batches and counters settle
n=$((n + 1))
for s in c:"$CM" w1:"${WM[0]}" w2:"${WM[1]}"; do
  curl -sf "http://${s#*:}/metrics" >"$WORK/scrapes/$n.${s%%:*}" || fail "final scrape"
done
echo done >"$WORK/scrapes/$n.state"
TILES=$(job_field "$ADDR" "$JOB" "j['tilesTotal']")
"$PY" - "$WORK/scrapes" "$n" "$JOB" "$TILES" <<'PY' || fail "metrics checks"
import sys
from prometheus_client.parser import text_string_to_metric_families
d, n, job, tiles = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])

def parse(path):
    """{(sample name, frozenset(labels)): value}; raises on invalid text format."""
    out = {}
    for fam in text_string_to_metric_families(open(path).read()):
        for s in fam.samples:
            out[(s.name, frozenset(s.labels.items()))] = s.value
    return out

def get(m, name, **labels):
    return m.get((name, frozenset(labels.items())))

scrapes = [{k: parse("%s/%d.%s" % (d, i, k)) for k in ("c", "w1", "w2")} for i in range(1, n + 1)]
states = [open("%s/%d.state" % (d, i)).read().strip() for i in range(1, n + 1)]
print("scrapes parsed: %d x 3 endpoints" % n)
failures = []
def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what)
    if not ok:
        failures.append(what)

def moving(values, what):
    distinct = sorted(set(v for v in values if v is not None))
    mono = all(a <= b for a, b in zip(values, values[1:]) if a is not None and b is not None)
    check(len(distinct) >= 3 and mono, "%s moves: %d distinct values, monotonic %s (%s)" % (
        what, len(distinct), mono, distinct[:6] + (["..."] if len(distinct) > 6 else [])))

running = [s for s, st in zip(scrapes, states) if st == "JOB_STATE_RUNNING"]
check(len(running) >= 3, "%d scrapes while the job ran" % len(running))
moving([get(s["c"], "irfarm_job_tiles_done", job=job) for s in running],
       "coordinator irfarm_job_tiles_done{job=%s}" % job)
moving([get(s["c"], "irfarm_job_records_merged", job=job) for s in running],
       "coordinator irfarm_job_records_merged{job=%s}" % job)
for w in ("w1", "w2"):
    moving([get(s[w], "irfarm_worker_tiles_completed_total") for s in scrapes],
           "%s irfarm_worker_tiles_completed_total" % w)
    moving([get(s[w], "irfarm_worker_records_sent_total") for s in scrapes],
           "%s irfarm_worker_records_sent_total" % w)

c, w1, w2 = scrapes[-1]["c"], scrapes[-1]["w1"], scrapes[-1]["w2"]
ws = (w1, w2)
check(get(c, "irfarm_job_tiles_done", job=job) == tiles,
      "job tiles_done %s == %d tiles" % (get(c, "irfarm_job_tiles_done", job=job), tiles))
check(get(c, "irfarm_tiles_completed_total") == tiles,
      "coordinator tiles_completed_total %s == %d" % (get(c, "irfarm_tiles_completed_total"), tiles))
wt = sum(get(w, "irfarm_worker_tiles_completed_total") for w in ws)
check(wt == tiles, "workers' tiles %s == %d" % (wt, tiles))
sent = sum(get(w, "irfarm_worker_records_sent_total") for w in ws)
recv = get(c, "irfarm_records_received_total")
check(sent > 0 and recv == sent, "coordinator records received %s == workers' records sent %s" % (recv, sent))
merged = get(c, "irfarm_records_merged_total")
rejected = get(c, "irfarm_records_rejected_total")
check(merged + rejected == recv and merged == get(c, "irfarm_job_records_merged", job=job),
      "merged %s + rejected %s == received, merged == the job's records" % (merged, rejected))
fan = get(c, "irfarm_records_sent_total")
wrecv = sum(get(w, "irfarm_worker_records_received_total") for w in ws)
check(fan > 0 and fan == wrecv, "coordinator fan-out %s == workers' records received %s" % (fan, wrecv))
check(get(c, "irfarm_record_bytes_received_total") == sum(get(w, "irfarm_worker_record_bytes_sent_total") for w in ws),
      "record bytes: coordinator received == workers sent")
check(get(c, "irfarm_rpc_duration_seconds_count", method="Session/tile_result") == tiles,
      "tile_result latency histogram counted %s results" % get(c, "irfarm_rpc_duration_seconds_count", method="Session/tile_result"))
check(get(c, "irfarm_store_duration_seconds_count", op="put_tile") == tiles,
      "Redis put_tile latency histogram counted %s tiles" % get(c, "irfarm_store_duration_seconds_count", op="put_tile"))
check(get(c, "irfarm_jobs", state="succeeded") == 1, "irfarm_jobs{state=succeeded} == 1")
for w, m in (("w1", w1), ("w2", w2)):
    rays = sum(get(m, "irfarm_worker_rays_total", kind=k) for k in ("camera", "bounce", "shadow", "record"))
    hr = get(m, "irfarm_worker_cache_hit_ratio")
    check(rays > 0 and 0 < hr <= 1, "%s rays %d, cache hit ratio %.3f" % (w, rays, hr))
    check(get(m, "irfarm_worker_tile_duration_seconds_count") == get(m, "irfarm_worker_tiles_completed_total"),
          "%s tile duration histogram counts its tiles" % w)
check(0 < get(c, "irfarm_cache_hit_ratio") <= 1, "coordinator cache hit ratio %.3f" % get(c, "irfarm_cache_hit_ratio"))
for k, m in (("coordinator", c), ("w1", w1)):
    check(get(m, "process_resident_memory_bytes") > 1e6,
          "%s resident memory %.1f MB" % (k, get(m, "process_resident_memory_bytes") / 1e6))
print("MEASURED coordinator: %d tiles, %d records received, %d merged, %d fanned out; RSS %.1f MB" % (
    tiles, recv, merged, fan, get(c, "process_resident_memory_bytes") / 1e6))
sys.exit(1 if failures else 0)
PY
echo PASS

#!/usr/bin/env bash
# The coordinator's web dashboard (issue 11, part 2), against a real coordinator (--http, client
# tokens for alice and bob) and one real worker on 127.0.0.1 rendering the Cornell box.
#   dashboard_test.sh api      HTTP checks with curl (always run): the page, /api/jobs and
#                              /api/workers JSON, /api/image.png a PNG of the film's size (up to 1024 px) while
#                              the job runs and after; 401 without a token, bob sees neither
#                              alice's job nor its image, a POST without X-Irfarm-Request is 403,
#                              cancel and priority over HTTP change the job as `irfarm status`
#                              sees it.
#                              /api/record_map.png: the film's size, black but for pixels in
#                              w1's colour (worker 1: record_map.cc's first colour), at most
#                              one per record w1 computed; bob gets 404.
#   dashboard_test.sh browser  a second worker w2 too; headless Chromium driven by Selenium (dashboard_browser_test.py):
#                              exit 77 (skipped) when chromium, chromedriver or python3-selenium
#                              are not installed (Debian: chromium chromium-driver
#                              python3-selenium). SCREENSHOT=path keeps the mid-job screenshot.
source "$(dirname "$0")/lib.sh"
MODE=${1:-api}
SCENE=$DATA/scenes/cornell-box/scene.xml
if [[ $MODE == browser ]]; then
  PY=""
  for p in python3 /usr/bin/python3; do
    if "$p" -c 'import selenium' 2>/dev/null; then PY=$p; break; fi
  done
  CHROME=$(command -v chromium || command -v chromium-browser || true)
  DRIVER=$(command -v chromedriver || true)
  if [[ -z $PY || -z $CHROME || -z $DRIVER ]]; then
    echo "SKIP: needs chromium, chromedriver and python3 selenium (apt-get install chromium chromium-driver python3-selenium)"
    exit 77
  fi
fi
ALICE=$(openssl rand -hex 24)
BOB=$(openssl rand -hex 24)
printf 'alice %s\nbob %s\n' "$ALICE" "$BOB" >"$WORK/client-tokens"
ADDR=127.0.0.1:$(free_port)
HTTP=127.0.0.1:$(free_port)
# start_coordinator polls `irfarm status`, which needs a client token now.
export IRFARM_TOKEN=$ALICE
start_coordinator "$ADDR" --client-token-file "$WORK/client-tokens" --http "$HTTP"
start_worker "$ADDR" w1
WORKER=$LAST_WORKER_PID
if [[ $MODE == browser ]]; then
  start_worker "$ADDR" w2  # the record map shows two workers' colours
  WORKER=$WORKER,$LAST_WORKER_PID
fi
# The dashboard starts listening just after the gRPC port.
for _ in $(seq 50); do curl -sf "http://$HTTP/" >/dev/null && break; sleep 0.1; done
submit() { "$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" --tile-size 16 -q "$@"; }

if [[ $MODE == browser ]]; then
  "$PY" "$(dirname "$0")/dashboard_browser_test.py" "http://$HTTP/" "$ALICE" "$BIN" "$ADDR" \
    "$SCENE" "$WORKER" "$CHROME" "$DRIVER" "${SCREENSHOT:-$WORK/dashboard.png}" ||
    fail "browser test"
  echo PASS
  exit 0
fi

a() { curl -s -H "Authorization: Bearer $ALICE" "$@"; }
b() { curl -s -H "Authorization: Bearer $BOB" "$@"; }
code() { curl -s -o /dev/null -w '%{http_code}' "$@"; }
curl -sf "http://$HTTP/" >"$WORK/page.html" || fail "page not served"
grep -q "<title>irfarm dashboard</title>" "$WORK/page.html" || fail "page not served"
echo "ok: GET / serves the page"
check "no token: 401" "$(code "http://$HTTP/api/jobs") == 401"
check "wrong token: 401" "$(code -H 'Authorization: Bearer 0123456789abcdef0123' "http://$HTTP/api/jobs") == 401"

JOB=$(submit -Dresx=160 -Dresy=96)
sleep 1
# While it runs: a PNG of the film's size (160x96, from its IHDR chunk).
a "http://$HTTP/api/image.png?job=$JOB" >"$WORK/mid.png"
python3 - "$WORK/mid.png" <<'PY' || fail "mid-job PNG"
import struct, sys
d = open(sys.argv[1], "rb").read()
assert d[:8] == b"\x89PNG\r\n\x1a\n", d[:60]
w, h = struct.unpack(">II", d[16:24])
assert (w, h) == (160, 96), (w, h)
print("ok: mid-job image is a %dx%d PNG (%d bytes)" % (w, h, len(d)))
PY
a "http://$HTTP/api/jobs" | python3 -c "
import json, sys
jobs = json.load(sys.stdin)['jobs']
assert [j['id'] for j in jobs] == ['$JOB'], jobs
assert jobs[0]['owner'] == 'alice' and jobs[0]['tilesTotal'] == 60, jobs[0]
print('ok: alice sees her job in /api/jobs: %s %s %d/%d tiles' % (jobs[0]['id'], jobs[0]['state'], jobs[0]['tilesDone'], jobs[0]['tilesTotal']))
" || fail "/api/jobs"
b "http://$HTTP/api/jobs" | python3 -c "import json,sys; j=json.load(sys.stdin).get('jobs', []); assert j == [], j" ||
  fail "bob sees alice's job"
check "bob gets 404 for alice's image" "$(code -H "Authorization: Bearer $BOB" "http://$HTTP/api/image.png?job=$JOB") == 404"
a "http://$HTTP/api/workers" | python3 -c "
import json, sys
ws = json.load(sys.stdin)['workers']
assert [w['name'] for w in ws] == ['w1'], ws
print('ok: /api/workers lists w1')" || fail "/api/workers"
wait_job "$ADDR" "$JOB" 120 >/dev/null
COMPUTED=$(job_field "$ADDR" "$JOB" "sum(int(w['recordsComputed']) for w in j['workers'])")
a "http://$HTTP/api/workers" | python3 -c "
import json, sys
w = json.load(sys.stdin)['workers'][0]
assert w['threads'] == 1 and int(w['recordsComputed']) == $COMPUTED > 0, w
print('ok: /api/workers: w1 has 1 thread and computed %s records (the job says $COMPUTED)' % w['recordsComputed'])" ||
  fail "worker threads / records"
a "http://$HTTP/api/image.png?job=$JOB" >"$WORK/final.png"
# The record map: black, and w1's records in its colour (worker id 1, the palette's first).
a "http://$HTTP/api/workers" | python3 -c "
import json, sys; assert json.load(sys.stdin)['workers'][0]['id'] == 1" || fail "w1 is not worker 1"
a "http://$HTTP/api/record_map.png?job=$JOB" >"$WORK/map.png"
python3 "$(dirname "$0")/png_colours.py" "$WORK/map.png" | python3 -c "
import json, sys
m = json.load(sys.stdin)
assert (m['width'], m['height']) == (160, 96), m
c = m['colours']
w1 = c.pop('230,25,75', 0)
black = c.pop('0,0,0', 0)
print('MEASURED record map: %d pixels in w1\'s colour, %d black, other colours %s' % (w1, black, c))
assert c == {}, c
assert 0 < w1 <= $COMPUTED, (w1, $COMPUTED)
print('ok: /api/record_map.png shows w1\'s records in its colour')" || fail "record map"
check "bob gets 404 for alice's record map" "$(code -H "Authorization: Bearer $BOB" "http://$HTTP/api/record_map.png?job=$JOB") == 404"
"$BIN/irfarm" fetch --coordinator "$ADDR" "$JOB" -o "$WORK/final.exr"
# The finished preview covers the whole film (no black row: the Cornell box has no black row),
# the mid-job one only the tiles done by then.
python3 - "$WORK/mid.png" "$WORK/final.png" "$(dirname "$0")" <<'PY' || fail "final PNG"
import sys
sys.path.insert(0, sys.argv[3])
from png_colours import decode
def pixels(path):
    w, h, rows = decode(open(path, "rb").read())
    return w, h, sum(1 for r in rows if any(r))
_, h, mid = pixels(sys.argv[1])
_, _, final = pixels(sys.argv[2])
print("MEASURED non-black rows: mid-job %d, final %d of %d" % (mid, final, h))
assert final == h, "final image has black rows"
print("ok: the finished preview covers the film")
PY

# Cancel and priority over HTTP.
kill -STOP "$WORKER"
J2=$(submit -Dresx=64 -Dresy=64)
check "POST without X-Irfarm-Request: 403" "$(code -X POST -d '' -H "Authorization: Bearer $ALICE" "http://$HTTP/api/cancel?job=$J2") == 403"
check "bob cannot cancel alice's job: 404" "$(code -X POST -d '' -H 'X-Irfarm-Request: 1' -H "Authorization: Bearer $BOB" "http://$HTTP/api/cancel?job=$J2") == 404"
check "priority not a number: 400" "$(code -X POST -d '' -H 'X-Irfarm-Request: 1' -H "Authorization: Bearer $ALICE" "http://$HTTP/api/priority?job=$J2&priority=high") == 400"
a -X POST -d '' -H 'X-Irfarm-Request: 1' "http://$HTTP/api/priority?job=$J2&priority=87" >/dev/null
check "priority set over HTTP" "$(job_field "$ADDR" "$J2" "j['priority']") == 87"
a -X POST -d '' -H 'X-Irfarm-Request: 1' "http://$HTTP/api/cancel?job=$J2" >/dev/null
check "cancelled over HTTP" "'$(job_field "$ADDR" "$J2" "j['state']")' == 'JOB_STATE_CANCELLED'"
check "cancel again: 409" "$(code -X POST -d '' -H 'X-Irfarm-Request: 1' -H "Authorization: Bearer $ALICE" "http://$HTTP/api/cancel?job=$J2") == 409"
kill -CONT "$WORKER"
echo PASS

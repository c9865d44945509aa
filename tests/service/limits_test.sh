#!/usr/bin/env bash
# Large-input requests against a real coordinator process: a 100000^2 film, a 2^31-1 pixel wide
# film and 300 -D defines are refused with INVALID_ARGUMENT, each in under 2 s, create no job,
# and leave the coordinator's RSS within 10% of what it was after one warm-up round of the same
# requests (the bug was +230 MiB kept after a cancelled 100000^2 job). Also: without tokens the
# coordinator refuses to listen on 0.0.0.0, and a second coordinator on the port of a running one
# exits with an error (with gRPC's default SO_REUSEPORT it bound the port too, and the kernel
# shared the connections out between the two).
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
ADDR=127.0.0.1:$(free_port)
start_coordinator "$ADDR"
rss() { awk '/VmRSS/ {print $2}' "/proc/$COORD_PID/status"; }
DEFINES=()
for i in $(seq 300); do DEFINES+=(-D "d$i=1"); done

refuse() {  # refuse DESCRIPTION ARGS...: the submit must fail with INVALID_ARGUMENT in < 2 s
  local what=$1 t0 t1; shift
  t0=$(date +%s.%N)
  if "$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" -q "$@" 2>"$WORK/err.txt"; then
    fail "$what was accepted"
  fi
  t1=$(date +%s.%N)
  grep -q INVALID_ARGUMENT "$WORK/err.txt" || fail "$what: $(cat "$WORK/err.txt")"
  python3 -c "import sys; sys.exit(0 if $t1 - $t0 < 2 else 1)" || fail "$what took over 2 s"
}
round() {
  refuse "100000^2 film" -Dresx=100000 -Dresy=100000
  refuse "2^31-1 wide film" -Dresx=2147483647
  refuse "300 defines" "${DEFINES[@]}"
}
round
R0=$(rss)
for _ in 1 2 3; do round; done
R1=$(rss)
echo "MEASURED coordinator RSS after warm-up ${R0} KiB, after 3 more rounds ${R1} KiB"
check "coordinator RSS within 10%" "$R1 <= 1.1 * $R0"
check "no job was created" "'$("$BIN/irfarm" status --coordinator "$ADDR")' == ''"


# Without tokens the coordinator refuses a non-loopback address (unless --insecure).
PORT=$(free_port)
if timeout 10 "$BIN/irfarm-coordinator" --listen "0.0.0.0:$PORT" >"$WORK/open.log" 2>&1; then
  fail "coordinator listened on 0.0.0.0 without tokens"
fi
grep -q "refusing to listen" "$WORK/open.log" || fail "no refusal message: $(cat "$WORK/open.log")"
echo "ok: refuses 0.0.0.0 without tokens"

if timeout 10 "$BIN/irfarm-coordinator" --listen "$ADDR" >"$WORK/second.log" 2>&1; then
  fail "a second coordinator started on $ADDR"
fi
grep -q "cannot listen on $ADDR" "$WORK/second.log" || fail "no clear error: $(tail -3 "$WORK/second.log")"
alive "$COORD_PID" "the first coordinator" "$WORK/coordinator.log"
echo "ok: a second coordinator on $ADDR is refused"
echo PASS

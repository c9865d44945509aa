#!/usr/bin/env bash
# Redis losing its data under a running coordinator (FLUSHALL): the job counter starts again at 1,
# but a new job never takes the id of a job the coordinator holds (it used to replace job-1
# silently). Real redis-server and coordinator on 127.0.0.1, no workers (jobs stay queued).
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
start_redis
ADDR=127.0.0.1:$(free_port)
start_coordinator "$ADDR" --redis "127.0.0.1:$RPORT"
submit() { "$BIN/irfarm" submit --coordinator "$ADDR" "$SCENE" -Dresx=32 -Dresy=32 -q "$@"; }
A=$(submit --priority 1)
B=$(submit --priority 2)
redis-cli -p "$RPORT" flushall >/dev/null
C=$(submit --priority 3)
echo "MEASURED ids before FLUSHALL: $A $B; after: $C"
check "new job id differs from the jobs held" "'$C' not in ('$A', '$B')"
LIST=$("$BIN/irfarm" status --coordinator "$ADDR" --json |
  python3 -c 'import json,sys; print(sorted((j["id"], j["priority"]) for j in map(json.loads, sys.stdin)))')
check "all three jobs listed with their own priority" \
  "$LIST == sorted([('$A', 1), ('$B', 2), ('$C', 3)])"
echo PASS

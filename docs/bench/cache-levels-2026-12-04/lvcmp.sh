#!/bin/bash
# Defaults with the cache-levels threshold 3 (46c3e93) against 1.5 (/tmp/irfarm-lv15, the build
# that became cfdd93a), seeds 7-9. Rooms as in levels.sh; room-301/302 from `python3
# bench/make_room.py S /tmp/mesh/room-S --lamps mesh --reference 4096`. Paths as run.
out=/tmp/lvcmp.txt; : > $out
for sc in /tmp/fresh/room-221 /work/shared/scenes/room-c /work/shared/scenes/room-d /tmp/mesh/room-301 /tmp/mesh/room-302 /work/shared/scenes/living-room; do
  for seed in 7 8 9; do for b in 46c3e93 lv15; do
    /tmp/irfarm-$b render $sc/scene.xml --seed $seed -q -o /tmp/lvc.exr --stats /tmp/lvc.json 2>/dev/null
    r=$(/tmp/irfarm-$b compare /tmp/lvc.exr $sc/reference.exr | python3 -c "import json,sys;print(json.load(sys.stdin)['relmse'])")
    python3 -c "
import json;d=json.load(open('/tmp/lvc.json'))
t=sum(d['seconds'].get(k,0) for k in ('caustics','pilot','overture','render'))
print('$(basename $sc) $seed $b', $r, round(t,3), d['cpu_seconds']['total'], d['settings']['cache_levels'])" >> $out
  done; done
done
echo done >> $out

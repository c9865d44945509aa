#!/bin/bash
# The run behind summary.md (2026-12-04): B is a build of 46c3e93 (cmake --build build, copied);
# the unseen rooms are `python3 bench/make_room.py S /tmp/unseen/room-S --reference 1024` (S =
# 201..206) and `... S /tmp/fresh/room-S --reference 4096` (S = 221..226). Paths as run.
B=/tmp/irfarm-46c3e93
out=/tmp/levels.txt; : > $out
for sc in /work/shared/scenes/{cornell-box,sunlit-room,specular,thin-panels,veach-ajar,room-a,room-b,room-c,room-d} /tmp/unseen/room-20{1,2,3,4,5,6} /tmp/fresh/room-22{1,2,3,4,5,6}; do
  [ -f $sc/reference.exr ] || continue
  for seed in 7 8 9; do
    for lv in default 1 2; do
      a=""; [ $lv != default ] && a="--cache-levels $lv"
      $B render $sc/scene.xml --seed $seed -q -o /tmp/lvx.exr --stats /tmp/lvx.json $a 2>/dev/null
      r=$($B compare /tmp/lvx.exr $sc/reference.exr | python3 -c "import json,sys;print(json.load(sys.stdin)['relmse'])")
      python3 -c "
import json;d=json.load(open('/tmp/lvx.json'));rb=d.get('record_balance',{})
t=sum(d['seconds'].get(k,0) for k in ('caustics','pilot','overture','render'))
print('$(basename $sc) $seed $lv', $r, round(t,3), d['cpu_seconds']['total'], d['settings']['cache_levels'], rb.get('one_level_record_noise_relmse',0), rb.get('one_level_sampling_relmse',0), d['settings']['record_rays'])" >> $out
    done
  done
done
echo done >> $out

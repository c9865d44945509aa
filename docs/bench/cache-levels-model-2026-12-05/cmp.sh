#!/bin/bash
# cmp.sh OUT "SEEDS" BIN...: defaults per scene and seed, binaries alternated
OUT=$1; SEEDS=$2; shift 2
S=/work/shared/scenes
for d in $S/cornell-box $S/sunlit-room $S/specular $S/thin-panels $S/veach-ajar $S/room-a $S/room-b $S/room-c $S/room-d $S/living-room /tmp/bulb/room-40{1,2,3,4} /tmp/env/room-50{1,2,3,4} /tmp/day/room-51{1,2,3} /tmp/r6/room-60{1,2,3} /tmp/vs/layered_kitchen /tmp/vs/layered_shoes; do
  x=$d/scene.xml; ref=$d/reference.exr; name=$(basename $d)
  [ -f $d/kinf.xml ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  [ -f $d/s240.xml ] && { x=$d/s240.xml; ref=$d/ref4096.exr; }
  for seed in $SEEDS; do for BIN in "$@"; do
    $BIN render $x --seed $seed -o /tmp/lv/c.exr -q --stats /tmp/lv/c.json 2>/dev/null
    e=$(python3 /tmp/relmse.py $ref /tmp/lv/c.exr | awk '{print $3}')
    python3 -c "
import json; j=json.load(open('/tmp/lv/c.json')); b=j['record_balance']
print(json.dumps({'scene':'$name','seed':$seed,'bin':'$BIN','relmse':float('$e'),'wall':j['seconds']['total'],'pilot':j['seconds']['pilot'],'cpu':j['cpu_seconds']['total'],'levels':j['settings']['cache_levels'],'rays':j['settings']['record_rays']}))" >> $OUT
  done; done
done
echo DONE >> $OUT

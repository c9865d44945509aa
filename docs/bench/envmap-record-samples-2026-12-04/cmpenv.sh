#!/bin/bash
# cmpenv.sh OUT BIN_A BIN_B : seeds 7 8, envmap scenes, relMSE and user CPU
OUT=$1; A=$2; B=$3
mkdir -p /tmp/cmpenv
scenes="/tmp/vs/layered_kitchen/k240.xml:/tmp/vs/layered_kitchen/ref4096.exr /tmp/vs/layered_kitchen/kinf.xml:/tmp/vs/layered_kitchen/refinf.exr /work/shared/scenes/living-room/scene.xml:/work/shared/scenes/living-room/reference.exr"
for r in /tmp/env/room-50{1,2,3,4} /tmp/day/room-51{1,2,3} /tmp/r6/room-60{1,2}; do scenes="$scenes $r/scene.xml:$r/reference.exr"; done
for sc in $scenes; do x=${sc%%:*}; ref=${sc##*:}; name=$(basename $(dirname $x))-$(basename $x .xml)
  for seed in 7 8; do for tag in A B; do bin=$A; [ $tag = B ] && bin=$B
    /usr/bin/time -f "%U %S" -o /tmp/cmpenv/t $bin render $x --seed $seed -o /tmp/cmpenv/$name-$tag-$seed.exr -q --stats /tmp/cmpenv/$name-$tag-$seed.json 2>/dev/null
    e=$(python3 /tmp/relmse.py $ref /tmp/cmpenv/$name-$tag-$seed.exr | awk '{print $3}')
    lv=$(python3 -c "import json; j=json.load(open('/tmp/cmpenv/$name-$tag-$seed.json')); print(j['settings']['record_rays'], j['settings']['cache_levels'])")
    echo "$name $seed $tag $e $(awk '{print $1+$2}' /tmp/cmpenv/t) $lv" >> $OUT
  done; done; done
echo DONE >> $OUT

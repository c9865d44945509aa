#!/bin/bash
# cmpone.sh OUT BIN TAG SEEDS SCENEDIR...
OUT=$1; BIN=$2; TAG=$3; SEEDS=$4; shift 4
for d in "$@"; do x=$d/scene.xml; ref=$d/reference.exr; name=$(basename $d)
  [ -f $d/k240.xml ] && { x=$d/k240.xml; ref=$d/ref4096.exr; }
  for seed in $SEEDS; do
    /usr/bin/time -f "%U %S" -o /tmp/cmpenv/t-$TAG $BIN render $x --seed $seed -o /tmp/cmpenv/$name-$TAG-$seed.exr -q --stats /tmp/cmpenv/$name-$TAG-$seed.json 2>/dev/null
    e=$(python3 /tmp/relmse.py $ref /tmp/cmpenv/$name-$TAG-$seed.exr | awk '{print $3}')
    lv=$(python3 -c "import json; j=json.load(open('/tmp/cmpenv/$name-$TAG-$seed.json')); print(j['settings']['record_rays'], j['settings']['cache_levels'])")
    echo "$name $seed $TAG $e $(awk '{print $1+$2}' /tmp/cmpenv/t-$TAG) $lv" >> $OUT
  done; done
echo DONE >> $OUT

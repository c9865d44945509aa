#!/bin/bash
# arms.sh OUT SCENE SEEDS "label|env|args" ...   (runs arms interleaved per seed)
OUT=$1; SC=$2; SEEDS=$3; shift 3
f=$(ls -d /work/shared/scenes/$SC /tmp/un/$SC /tmp/fr/$SC 2>/dev/null | head -1)
for s in $SEEDS; do
  for arm in "$@"; do
    IFS='|' read -r label E A <<< "$arm"
    t=$( { /usr/bin/time -f "%U %S %e" $E render $f/scene.xml --seed $s -o /tmp/arm_$label.exr -q $A ; } 2>&1 | tail -1)
    e=$(/tmp/irf0 compare /tmp/arm_$label.exr $f/reference.exr | python3 -c "import json,sys;d=json.load(sys.stdin);print(d['relmse'],d['mean_test'][1]/d['mean_ref'][1])")
    echo "$SC $s $label $t $e" >> $OUT
  done
done
echo done >> $OUT

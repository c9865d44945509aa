#!/bin/bash
# tgt.sh OUT "E..." "SEEDS" BIN... ; scenes from SCENES env (dir list)
OUT=$1; ES=$2; SEEDS=$3; shift 3
for d in $SCENES; do
  x=$d/scene.xml; ref=$d/reference.exr; name=$(basename $d)
  [ -f $d/kinf.xml ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  [ -f $d/s240.xml ] && { x=$d/s240.xml; ref=$d/ref4096.exr; }
  for E in $ES; do for seed in $SEEDS; do for BIN in "$@"; do
    $BIN render $x --seed $seed --target-error $E -o /tmp/tg.exr -q --stats /tmp/tg.json 2>/dev/null
    e=$(python3 /tmp/relmse.py $ref /tmp/tg.exr | awk '{print $3}')
    python3 -c "
import json; j=json.load(open('/tmp/tg.json')); est=j['error_estimate']['relmse']; m=float('$e')
print('%-16s %s seed %s %-14s measured %.3e (%.2f E) estimate %.3e (est/meas %.2f) %.1f s' % ('$name', '$E', '$seed', '$BIN'.split('/')[-1], m, m/float('$E'), est, est/m, j['seconds']['total']))" >> $OUT
  done; done; done
done
echo DONE >> $OUT

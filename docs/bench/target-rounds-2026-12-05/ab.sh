#!/bin/bash
# ab.sh OUT "E..." scene_dir... : old (/tmp/irf_new) and new (/tmp/irf_cs) per scene and E, seed 7
OUT=$1; ES=$2; shift 2
for d in "$@"; do
  x=$d/scene.xml; ref=$d/reference.exr; name=$(basename $d)
  [ -f $d/kinf.xml ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  for E in $ES; do for BIN in /tmp/irf_new /tmp/irf_cs; do
    $BIN render $x --seed 7 --target-error $E -o /tmp/ab.exr -q --stats /tmp/ab.json 2>/dev/null
    m=$(python3 /tmp/relmse.py $ref /tmp/ab.exr | awk '{print $3}')
    python3 -c "
import json; j=json.load(open('/tmp/ab.json')); e=j['error_estimate']; m=float('$m'); E=float('$E')
stop=[w for w in j['warnings'] if 'not reached' in w]
print('%-12s %s %-8s meas %.2e (%.2f E) est/meas %.2f %6.1f s rounds %s %s' % ('$name', '$E', '$BIN'.split('_')[-1], m, m/E, e['relmse']/m, j['seconds']['total'], [(round(r['accuracy'],3), r['record_rays'], '%.1e'%r['cache_relmse']) for r in e['cache_rounds']], stop[0].split('refinement stopped:')[-1][:40] if stop else ''))" >> $OUT
  done; done
done
echo DONE >> $OUT

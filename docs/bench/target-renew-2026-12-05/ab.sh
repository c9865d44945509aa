#!/bin/bash
# ab.sh OUT "E..." "SEEDS" scene_dir... : /tmp/k/irf (old) and /tmp/k/renew (new) per scene, E, seed
OUT=$1; ES=$2; SEEDS=$3; shift 3
for d in "$@"; do
  x=$d/scene.xml; ref=$d/reference.exr; name=$(basename $d)
  [ -f $d/kinf.xml ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  for E in $ES; do for S in $SEEDS; do for BIN in /tmp/k/irf /tmp/k/renew; do
    $BIN render $x --seed $S --target-error $E -o /tmp/k/ab$$.exr -q --stats /tmp/k/ab$$.json 2>/dev/null
    m=$(python3 /tmp/relmse.py $ref /tmp/k/ab$$.exr | awk '{print $3}')
    python3 -c "
import json; j=json.load(open('/tmp/k/ab$$.json')); e=j['error_estimate']; m=float('$m'); E=float('$E')
stop=[w for w in j['warnings'] if 'not reached' in w]
print('%-12s %s s%s %-5s meas %.2e (%.2f E) est/meas %.2f samp %.1e %6.1f s rounds %s %s' % ('$name', '$E', '$S', '$BIN'.split('/')[-1], m, m/E, e['relmse']/m, e['sampling_relmse'], j['seconds']['total'], [(round(r['accuracy'],3), r['record_rays'], '%.1e'%r['cache_relmse']) for r in e['cache_rounds']], stop[0].split('refinement stopped:')[-1][:40] if stop else ''))" >> $OUT
  done; done; done
done
echo DONE >> $OUT

#!/bin/bash
# rounds.sh BIN OUT E... : shared nine + extra dirs in EXTRA, seed 7; prints measured, estimate, rounds, stop
BIN=$1; OUT=$2; shift 2
for d in /work/shared/scenes/{cornell-box,room-a,room-b,room-c,room-d,specular,sunlit-room,thin-panels,veach-ajar} $EXTRA; do
  x=$d/scene.xml; ref=$d/reference.exr; name=$(basename $d)
  [ -f $d/kinf.xml ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  for E in "$@"; do
    $BIN render $x --seed 7 --target-error $E -o /tmp/k/rd$$.exr -q --stats /tmp/k/rd$$.json 2>/tmp/k/rd$$.err
    m=$(python3 /tmp/relmse.py $ref /tmp/k/rd$$.exr | awk '{print $3}')
    python3 -c "
import json; j=json.load(open('/tmp/k/rd$$.json')); e=j['error_estimate']; m=float('$m'); E=float('$E')
stop=[w for w in j['warnings'] if 'not reached' in w]
print('%-12s %s meas %.2e (%.2f E) est/meas %.2f %5.1f s rounds %s %s' % ('$name', '$E', m, m/E, e['relmse']/m, j['seconds']['total'], [(round(r['accuracy'],3), r['record_rays'], '%.1e'%r['cache_relmse']) for r in e['cache_rounds']], stop[0].split('(')[-1][:60] if stop else ''))" >> $OUT
  done
done
echo DONE >> $OUT

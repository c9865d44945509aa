#!/bin/bash
# run1.sh BIN XML REF E [args...] (env passes through)
BIN=$1; X=$2; R=$3; E=$4; shift 4
$BIN render $X --seed ${SEED:-7} --target-error $E "$@" -o /tmp/k/o$$.exr -q --stats /tmp/k/o$$.json 2>/dev/null
m=$(python3 /tmp/relmse.py $R /tmp/k/o$$.exr | awk '{print $3}')
python3 -c "
import json; j=json.load(open('/tmp/k/o$$.json')); e=j['error_estimate']; m=float('$m'); E=float('$E')
stop=[w for w in j['warnings'] if 'not reached' in w]
print('%s meas %.2e (%.2f E) est/meas %.2f samp %.1e %5.1f s lv %s rounds %s %s' % ('$E', m, m/E, e['relmse']/m, e['sampling_relmse'], j['seconds']['total'], j['settings']['cache_levels'], [(round(r['accuracy'],3), r['record_rays'], '%.1e'%r['cache_relmse']) for r in e['cache_rounds']], stop[0].split('(')[-1][:50] if stop else ''))"
rm -f /tmp/k/o$$.exr /tmp/k/o$$.json

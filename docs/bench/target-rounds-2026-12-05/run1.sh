#!/bin/bash
# run1.sh BIN XML REF E [render args...]: one --target-error render (seed $SEED, default 7), then
# one line: the measured relMSE against REF (BIN's own `compare`), it over E, the estimate over
# the measured, the samples' estimate, seconds, cache levels, the refinement's rounds and why
# it stopped short of E if it did. Extra environment passes through to BIN.
set -e
BIN=$1; X=$2; R=$3; E=$4; shift 4
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
"$BIN" render "$X" --seed "${SEED:-7}" --target-error "$E" "$@" -o "$T/o.exr" -q --stats "$T/o.json" 2>/dev/null
"$BIN" compare "$T/o.exr" "$R" > "$T/c.json"
python3 - "$T/o.json" "$T/c.json" "$E" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); m = json.load(open(sys.argv[2]))['relmse']; E = float(sys.argv[3])
e = j['error_estimate']
stop = [w for w in j['warnings'] if 'not reached' in w]
rounds = [(round(r['accuracy'], 3), r['record_rays'], '%.1e' % r['cache_relmse']) for r in e['cache_rounds']]
print('%s meas %.2e (%.2f E) est/meas %.2f samp %.1e %5.1f s lv %s rounds %s %s' % (
    sys.argv[3], m, m / E, e['relmse'] / m, e['sampling_relmse'], j['seconds']['total'],
    j['settings']['cache_levels'], rounds, stop[0].split('refinement stopped:')[-1][:50] if stop else ''))
PY

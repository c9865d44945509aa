#!/bin/bash
# final_ab.sh OUT BIN seeds scenes...: --denoise at defaults (AUTO) and, where it chose path, the cache
OUT=$1; BIN=$2; SEEDS=$3; shift 3
for sc in "$@"; do
 f=$(ls -d /work/shared/scenes/$sc /tmp/fr/$sc /tmp/fr2/$sc 2>/dev/null | head -1)
 for s in $SEEDS; do
  t=$( { /usr/bin/time -f "%U %S %e" $BIN render $f/scene.xml --seed $s --denoise -q -o /tmp/fa.exr --stats /tmp/fa.json ; } 2>&1 | tail -1)
  e=$(/tmp/irf0 compare /tmp/fa.exr $f/reference.exr | python3 -c "import json,sys;print(json.load(sys.stdin)['relmse'])")
  k=$(python3 -c "
import json;d=json.load(open('/tmp/fa.json'));c=d['integrator_choice'];print(d['integrator'],d['spp'],'%.3g'%((c['path_relmse']-c['cache_sampling_relmse'])/c['cache_own_relmse']))")
  echo "$sc $s AUTO $t $e $k" >> $OUT
  if [[ $k == path* ]]; then
   t=$( { /usr/bin/time -f "%U %S %e" $BIN render $f/scene.xml --seed $s --denoise --integrator irrcache -q -o /tmp/fa.exr ; } 2>&1 | tail -1)
   e=$(/tmp/irf0 compare /tmp/fa.exr $f/reference.exr | python3 -c "import json,sys;print(json.load(sys.stdin)['relmse'])")
   echo "$sc $s CACHE $t $e" >> $OUT
  fi
 done
done
echo done >> $OUT

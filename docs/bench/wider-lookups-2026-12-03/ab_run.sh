#!/bin/bash
# usage: ab.sh "scene dirs" seed "binA binB" [extra args]  -> relMSE and CPU per binary
for d in $1; do for b in $3; do
  out=/tmp/ss/$(basename $d)-$(basename $b)-$2.exr
  t=$( { /usr/bin/time -f "%U %e" $b render $d/scene.xml --seed $2 $4 -q -o $out ; } 2>&1 | tail -1)
  echo "$(basename $d) $(basename $b) seed $2 $(python3 /tmp/cmpimg.py $d/reference.exr $out | cut -d' ' -f2-3) cpu/wall $t"
done; done

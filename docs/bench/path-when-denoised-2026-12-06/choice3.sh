#!/bin/bash
# choice3.sh DIR BIN seed scene...   keeps stats per seed
DIR=$1; BIN=$2; SEED=$3; shift 3; mkdir -p $DIR
for sc in "$@"; do
  f=$(ls -d /work/shared/scenes/$sc /tmp/fr/$sc /tmp/fr2/$sc 2>/dev/null | head -1)
  $BIN render $f/scene.xml --denoise -q --seed $SEED -o /tmp/c3_$sc.exr --stats $DIR/$sc-$SEED.json 2>/dev/null
  /tmp/irf0 compare /tmp/c3_$sc.exr $f/reference.exr > $DIR/$sc-$SEED.cmp
done

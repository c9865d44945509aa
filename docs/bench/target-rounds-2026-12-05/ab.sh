#!/bin/bash
# ab.sh OLD NEW OUT "E..." "SEEDS" scene_dir... : the two binaries alternated per scene, E and seed
# (run1.sh), one line each appended to OUT.
HERE=$(cd "$(dirname "$0")" && pwd)
OLD=$1; NEW=$2; OUT=$3; ES=$4; SEEDS=$5; shift 5
for d in "$@"; do
  x=$d/scene.xml; ref=$d/reference.exr
  [ -f "$d/kinf.xml" ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  for E in $ES; do for S in $SEEDS; do for BIN in "$OLD" "$NEW"; do
    printf '%-15s s%s %-6s %s\n' "$(basename "$d")" "$S" "$(basename "$BIN")" \
      "$(SEED=$S "$HERE/run1.sh" "$BIN" "$x" "$ref" "$E")" >> "$OUT"
  done; done; done
done
echo DONE >> "$OUT"

#!/bin/bash
# rounds.sh BIN OUT E... : --target-error on the nine shared scenes with references (SCENES, default
# ../shared/scenes from the repository) and the scene folders in EXTRA, seed 7; one line per run
# (run1.sh) appended to OUT. A folder with kinf.xml / refinf.exr uses those.
HERE=$(cd "$(dirname "$0")" && pwd)
SCENES=${SCENES:-$HERE/../../../../shared/scenes}
BIN=$1; OUT=$2; shift 2
for d in "$SCENES"/{cornell-box,room-a,room-b,room-c,room-d,specular,sunlit-room,thin-panels,veach-ajar} $EXTRA; do
  x=$d/scene.xml; ref=$d/reference.exr
  [ -f "$d/kinf.xml" ] && { x=$d/kinf.xml; ref=$d/refinf.exr; }
  for E in "$@"; do
    printf '%-15s %s\n' "$(basename "$d")" "$("$HERE/run1.sh" "$BIN" "$x" "$ref" "$E")" >> "$OUT"
  done
done
echo DONE >> "$OUT"

#!/bin/bash
# The environment guide on and off (--no-env-guide), same binary, alternated, seeds 7-9:
# relMSE against each scene's reference and CPU seconds; then the seed-to-seed relMSE.
#   run.sh BIN OUT SCENE_DIR... [-- EXTRA irfarm render arguments]
BIN=$1; OUT=$2; shift 2
SCENES=(); EXTRA=()
while [ $# -gt 0 ]; do if [ "$1" = "--" ]; then shift; EXTRA=("$@"); break; fi; SCENES+=("$1"); shift; done
mkdir -p "$OUT"
for sc in "${SCENES[@]}"; do
  name=$(basename "$sc")
  for seed in 7 8 9; do
    for mode in guide off; do
      flag=; [ $mode = off ] && flag=--no-env-guide
      img="$OUT/$name-$mode-$seed.exr"
      "$BIN" render "$sc/scene.xml" --seed $seed -o "$img" -q --stats "$OUT/$name-$mode-$seed.json" $flag "${EXTRA[@]}" >/dev/null 2>&1
      python3 - "$BIN" "$img" "$sc/reference.exr" "$OUT/$name-$mode-$seed.json" "$name" $mode $seed <<'PY'
import json, subprocess, sys
b, img, ref, st, name, mode, seed = sys.argv[1:]
r = json.loads(subprocess.check_output([b, 'compare', img, ref], stderr=subprocess.DEVNULL))
d = json.load(open(st))
print(f"{name:14s} {mode:5s} seed {seed}  relMSE {r['relmse']:.4g}  cpu {d['cpu_seconds']['total']:6.2f}  "
      f"guide cells {d['environment_guide']['cells']:5d}  record rays {d['settings'].get('record_rays', 0)}", flush=True)
PY
    done
  done
  for mode in guide off; do
    for pair in "7 8" "8 9" "7 9"; do set -- $pair
      v=$("$BIN" compare "$OUT/$name-$mode-$1.exr" "$OUT/$name-$mode-$2.exr" 2>/dev/null | python3 -c 'import json,sys; print("%.4g" % json.load(sys.stdin)["relmse"])')
      echo "$name $mode seeds $1-$2 relMSE between them $v"
    done
  done
done

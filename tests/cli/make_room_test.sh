#!/usr/bin/env bash
# bench/make_room.py (random rooms for judging irfarm on scenes it has not seen): rooms of several
# seeds, with and without a window, with rectangle, mesh and bulb lamps or none (lit by day), matte
# and glossy, with a sun and constant sky, an environment map, or the sun and the sky drawn into
# an environment map (sky.hdr) through the window, load in irfarm
# without a warning and render lit (every channel mean above 0.01, no non-finite pixel):
# what the generator writes is a scene the loader accepts as it is, whatever the seed.
#   make_room_test.sh IRFARM_BINARY SOURCE_DIR
set -euo pipefail
irfarm=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for args in "1 --window yes" "2 --window no" "3" "4 --window yes" "5 --lamps mesh" \
  "6 --lamps bulb --finish glossy" "7 --lamps bulb --window yes --finish glossy" \
  "8 --window yes --sky envmap" "9 --window yes --sky envmap --lamps bulb --finish glossy" \
  "10 --lamps none --sky envmap" "11 --lamps none --sky sun-envmap --finish glossy"; do
  read -r seed rest <<<"$args"
  dir=$tmp/room-$seed
  # shellcheck disable=SC2086
  python3 "$src/bench/make_room.py" "$seed" "$dir" $rest
  "$irfarm" render "$dir/scene.xml" -Dresx=64 -Dresy=48 --spp 4 -q -o "$dir/out.exr" \
    --stats "$dir/stats.json" 2>"$dir/stderr"
  if [[ -s $dir/stderr ]]; then
    echo "seed $seed: irfarm printed:" >&2
    cat "$dir/stderr" >&2
    exit 1
  fi
  python3 - "$dir/stats.json" "$seed" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
mean, bad = d["image"]["mean_rgb"], d["image"]["nonfinite_pixels"]
print(f"seed {sys.argv[2]}: mean {mean}, non-finite pixels {bad}, warnings {d['warnings']}")
assert bad == 0 and not d["warnings"], "non-finite pixels or warnings"
assert min(mean) > 0.01, "a dark room: the generator's lamps or walls face the wrong way"
PY
done
echo "make_room: 10 rooms load and render lit"

#!/usr/bin/env bash
# End-to-end checks of the `irfarm` command as a user runs it: a render writes the EXR, the PNG
# preview and a stats JSON with the documented figures; a bad scene fails with a one-line
# file:line error and a non-zero exit, writing nothing; compare prints the relMSE.
set -euo pipefail
irfarm=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$irfarm" render "$data/scenes/cornell-box/scene.xml" -D resx=32 -D resy=32 --spp 4 \
  -o "$tmp/out.exr" --stats "$tmp/out.json" --record-map "$tmp/records.png" -q
for f in out.exr out.png out.json records.png; do [[ -s $tmp/$f ]] || fail "missing $f"; done
python3 - "$tmp/out.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
assert s["integrator"] == "irrcache" and s["width"] == 32 and s["spp"] == 4, s
assert s["records"]["computed"] > 0 and s["rays"]["record"] > 0, s["records"]
assert s["cache"]["lookups"] >= s["cache"]["hits"] > 0, s["cache"]
assert s["seconds"]["render"] > 0 and s["peak_rss_mib"] > 0
assert s["image"]["nonfinite_pixels"] == 0
assert s["settings"]["spacing"] == "hessian", s["settings"]
PY

# --target-error calibrated its model with one spacing and one lookup rule: choosing either is
# refused with the reason, and nothing is written.
for opt in "--spacing split-sphere" "--lookup-factor 2"; do
  set +e
  # shellcheck disable=SC2086
  err=$("$irfarm" render "$data/scenes/cornell-box/scene.xml" --target-error 1e-3 $opt \
    -o "$tmp/t.exr" -q 2>&1)
  code=$?
  set -e
  [[ $code -ne 0 && $err == *"excludes"* ]] || fail "$opt with --target-error: $code $err"
  [[ ! -e $tmp/t.exr ]] || fail "$opt with --target-error wrote an image"
done

# compare: an image against itself has relMSE 0.
"$irfarm" compare "$tmp/out.exr" "$tmp/out.exr" |
  python3 -c 'import json,sys; j=json.load(sys.stdin); assert j["relmse"] == 0 and j["nonfinite_pixels"] == 0, j' ||
  fail "compare"

# A bad scene: unknown BSDF type on line 5.
mkdir -p "$tmp/bad"
cat > "$tmp/bad/scene.xml" <<'XML'
<scene version="3.0.0">
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film>
    </sensor>
    <bsdf type="measured" id="x"/>
</scene>
XML
set +e
err=$("$irfarm" render "$tmp/bad/scene.xml" -o "$tmp/bad/out.exr" -q 2>&1)
code=$?
set -e
[[ $code -ne 0 ]] || fail "bad scene exited 0"
[[ $err == *"scene.xml:5: "*"measured"* ]] || fail "unexpected error: $err"
[[ $(printf '%s\n' "$err" | wc -l) -eq 1 ]] || fail "error is not one line: $err"
[[ ! -e $tmp/bad/out.exr ]] || fail "bad scene wrote an image"

# Bad irrcache parameter in the scene: file:line too.
sed 's|<integrator type="path">|<integrator type="irrcache"><float name="accuracy" value="3"/>|' \
  "$data/scenes/cornell-box/scene.xml" > "$tmp/cb.xml"
cp -r "$data/scenes/cornell-box/meshes" "$tmp/"
set +e
err=$("$irfarm" render "$tmp/cb.xml" -o "$tmp/x.exr" -q 2>&1)
code=$?
set -e
[[ $code -ne 0 && $err == *"cb.xml:"*"accuracy"* ]] || fail "bad accuracy: $code $err"
# Bad flags: the request's one validation (render/render_request.h, shared with the service's
# jobs), before anything is loaded: exit 2, the setting, its range and the value, no image.
for args in "--accuracy 3|accuracy must be in (0, 1], got 3" \
            "--spp -5|spp must be in [1, 1048576]" \
            "--cache-levels 4|cache_levels must be in [1, 3]" \
            "--integrator bdpt|unknown integrator 'bdpt' (supported: irrcache, path)"; do
  flag=${args%%|*} want=${args#*|}
  set +e
  # shellcheck disable=SC2086
  err=$("$irfarm" render "$data/scenes/cornell-box/scene.xml" $flag -o "$tmp/flag.exr" -q 2>&1)
  code=$?
  set -e
  [[ $code -eq 2 && $err == "error: $want"* ]] || fail "$flag: $code $err"
  [[ ! -e $tmp/flag.exr ]] || fail "$flag wrote an image"
done
# --denoise with the integrator left to irfarm: the stats say what the two pilots compared and
# which integrator rendered the image (path where its error less the cache's samples' is under
# kDenoiserGain times the cache's own, on images of at least kPathChoiceMinPixels,
# record_balance.h; this one is smaller); a named integrator is kept, no path pilot.
"$irfarm" render "$data/scenes/materials/scene.xml" -D resx=64 -D resy=48 --denoise \
  -o "$tmp/d.exr" --stats "$tmp/d.json" -q
"$irfarm" render "$data/scenes/materials/scene.xml" -D resx=64 -D resy=48 --denoise \
  --integrator irrcache -o "$tmp/n.exr" --stats "$tmp/n.json" -q
python3 - "$tmp/d.json" "$tmp/n.json" <<'PY'
import json, sys
d, n = (json.load(open(f)) for f in sys.argv[1:3])
c = d["integrator_choice"]
pays = (c["path_relmse"] - c["cache_sampling_relmse"] < c["denoiser_gain"] * c["cache_own_relmse"]
        and c["image_pixels"] >= c["min_pixels"])
assert c["image_pixels"] == 64 * 48 and c["min_pixels"] > c["image_pixels"] and not pays, c
assert c["path_pays"] == pays and d["integrator"] == ("path" if pays else "irrcache"), (d["integrator"], c)
assert c["path_per_sample_relmse"] > 0 and c["cache_thread_seconds"] > 0, c
assert "integrator_choice" not in n and n["integrator"] == "irrcache", n.get("integrator_choice")
PY

echo "cli_test: all checks passed"

#!/usr/bin/env bash
# The film's reconstruction filter through the service: a real coordinator and two workers render
# tests/data/scenes/filter-edges (48 x 36, Mitsuba's default gaussian filter, whose samples land
# up to 1.5 pixels outside their tile) with `path` in 16-pixel tiles. Tiles carry only the scene
# bundle (the XML), so the filter must come from the scene on every worker: the assembled image
# must equal a single-process render with the same seed exactly (path's per-pixel random streams
# do not depend on tiling), and be within Mitsuba's own 256-spp error of the gaussian reference
# (3.1e-3, tests/data/scenes/filter-edges/reference.json). Then the firefly filter, which the
# coordinator applies to the assembled image (see below).
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/filter-edges/scene.xml
REF=$DATA/scenes/filter-edges/reference.exr
OPTS=(--integrator path --spp 256 --seed 5)

"$BIN/irfarm" render "$SCENE" "${OPTS[@]}" --threads 2 -q -o "$WORK/local.exr"

start_cluster "w1 w2"
render_job "$WORK/dist.exr" "$SCENE" "${OPTS[@]}" --tile-size 16
SAME=$(relmse "$WORK/dist.exr" "$WORK/local.exr")
ERR=$(relmse "$WORK/dist.exr" "$REF")
echo "MEASURED two-worker vs single-process relMSE $SAME; vs Mitsuba's gaussian reference $ERR"
check "two workers give the single-process image" "$SAME == 0"
check "within Mitsuba's 256-spp error of the reference" "$ERR < 3.115e-3"

# The firefly filter over the assembled image: path at 16 spp on specular (64 x 64; caustics
# through the glass sphere found by BSDF sampling alone make fireflies), 16-pixel tiles. The
# workers leave their tiles as rendered and send each pixel's peak; the coordinator spreads the
# fireflies as one process does over its whole image: the same image exactly, fireflies were
# spread, and it differs from the image with the filter off.
SPEC=$DATA/scenes/specular/scene.xml
SOPTS=(--integrator path --spp 16 --seed 3 -D resx=64 -D resy=64)
"$BIN/irfarm" render "$SPEC" "${SOPTS[@]}" --threads 2 -q -o "$WORK/spec-local.exr" \
  --stats "$WORK/spec-local.json"
"$BIN/irfarm" render "$SPEC" "${SOPTS[@]}" --threads 2 -q -o "$WORK/spec-unfiltered.exr" \
  --no-firefly-filter
SPREAD=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["sampling"]["fireflies_spread"])' "$WORK/spec-local.json")
render_job "$WORK/spec-dist.exr" "$SPEC" "${SOPTS[@]}" --tile-size 16
SAME=$(relmse "$WORK/spec-dist.exr" "$WORK/spec-local.exr")
UNF=$(relmse "$WORK/spec-dist.exr" "$WORK/spec-unfiltered.exr")
echo "MEASURED specular 16 spp: $SPREAD pixels spread; two-worker vs single-process $SAME, vs unfiltered $UNF"
check "fireflies were spread" "$SPREAD > 0"
check "two workers give the single-process image, fireflies spread alike" "$SAME == 0"
check "the job's image is filtered" "$UNF > 0"

#!/usr/bin/env bash
# The film's reconstruction filter through the service: a real coordinator and two workers render
# tests/data/scenes/filter-edges (48 x 36, Mitsuba's default gaussian filter, whose samples land
# up to 1.5 pixels outside their tile) with `path` in 16-pixel tiles. Tiles carry only the scene
# bundle (the XML), so the filter must come from the scene on every worker: the assembled image
# must equal a single-process render with the same seed exactly (path's per-pixel random streams
# do not depend on tiling), and be within Mitsuba's own 256-spp error of the gaussian reference
# (3.1e-3, tests/data/scenes/filter-edges/reference.json).
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

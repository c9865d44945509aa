#!/usr/bin/env bash
# `irfarm submit --denoise`: a real coordinator and worker render the Cornell box at 64x64 with
# the path tracer at 16 spp (noisy on purpose); the coordinator denoises the assembled image.
# Checks, against the same render made in one process (`irfarm render --denoise --denoise-mode
# image`, same seed: the path tracer gives the same pixels whatever the tiling):
#  - the service's denoised image equals the local denoised one (relMSE between them below
#    1e-6: only OIDN's own float rounding may differ);
#  - denoising lowered the error against the reference to under half the noisy render's.
# Skipped (exit 77) when Open Image Denoise is not installed.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
REF=$DATA/scenes/cornell-box/reference-x4.exr
OPTS=(-Dresx=64 -Dresy=64 --integrator path --spp 16 --seed 3)

# The coordinator denoises the whole image (mode "image": the tiles carry albedo and normal only).
if ! "$BIN/irfarm" render "$SCENE" "${OPTS[@]}" --threads 2 -q --denoise --denoise-mode image \
    -o "$WORK/local.exr" 2>"$WORK/local.log"; then
  grep -q "denoiser unavailable" "$WORK/local.log" || fail "local render failed"
  echo "SKIP: Open Image Denoise not installed"
  exit 77
fi

start_cluster w1
render_job "$WORK/dist.exr" "$SCENE" "${OPTS[@]}" --tile-size 16 --denoise
SAME=$(relmse "$WORK/dist.exr" "$WORK/local.exr")
NOISY=$(relmse "$WORK/local.noisy.exr" "$REF")
CLEAN=$(relmse "$WORK/dist.exr" "$REF")
echo "MEASURED relMSE vs reference: noisy $NOISY, service-denoised $CLEAN; service vs local $SAME"
check "service denoises like a local render" "$SAME < 1e-6"
check "denoising halves the error at least" "$CLEAN < 0.5 * $NOISY"


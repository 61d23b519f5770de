#!/bin/sh
# PDACRT on the GPU against the GPU BVH rebuilt per frame (docs/gpu-check.md, "PDACRT
# against a GPU BVH rebuilt every frame"), on a machine with an NVIDIA GPU and nvcc: builds the CUDA library if
# needed, runs the GPU casting tests, then the tables, as markdown and as JSON lines.
#
#   WARPRAY_MODELS=... BIN=target/release/examples OUT=gpu-out sh cuda/casting.sh
#
# BIN holds gpu_casting (cargo build --release --features cuda,cli --example
# gpu_casting) and, optionally, gpu_tests (the suite's test binary, as in check.sh).
# ROUNDS and FRAMES (default 5) set the medians' rounds and the grid's frames.
set -eu
. "$(dirname "$0")/common.sh"
if [ -x "$BIN/gpu_tests" ]; then
    "$BIN/gpu_tests" gpu:: --include-ignored >"$OUT/casting_tests.txt" 2>&1 || { tail -30 "$OUT/casting_tests.txt"; exit 1; }
    grep "test result" "$OUT/casting_tests.txt"
fi
"$BIN/gpu_casting" --rounds "${ROUNDS:-5}" --frames "${FRAMES:-5}" | tee "$OUT/casting.md"
"$BIN/gpu_casting" --rounds "${ROUNDS:-5}" --frames "${FRAMES:-5}" --json >"$OUT/casting.json"

#!/bin/sh
# The GPU check of docs/gpu-check.md, on a machine with an NVIDIA GPU, nvcc and ncu:
# builds the CUDA library, runs the GPU tests, measures PDACRT's kernels with simt
# and with Nsight Compute on the same rays, and joins the two.
#
#   WARPRAY_MODELS=... BIN=target/release/examples OUT=gpu-out sh cuda/check.sh [model] [size]
#
# BIN holds gpu_check (cargo build --release --features cuda --example gpu_check) and,
# optionally, gpu_tests (the suite's test binary, `cargo test --release --features cuda
# --test suite --no-run`; its `gpu::` tests run). Results go to $OUT.
set -eu
. "$(dirname "$0")/common.sh"
MODEL=${1:-bunny}
SIZE=${2:-512}
BATCHES=${BATCHES:-primary,shadow}
if [ -x "$BIN/gpu_tests" ]; then
    "$BIN/gpu_tests" gpu:: --include-ignored >"$OUT/tests.txt" 2>&1 || true
    tail -5 "$OUT/tests.txt"
fi
"$BIN/gpu_check" simt --model "$MODEL" --batch "$BATCHES" --size "$SIZE" --out "$OUT/simt_$MODEL.tsv"
ncu --clock-control none --csv --page raw --print-units base --metrics "$("$BIN/gpu_check" metrics)" \
    --log-file "$OUT/ncu_$MODEL.csv" \
    "$BIN/gpu_check" gpu --model "$MODEL" --batch "$BATCHES" --size "$SIZE" --repeat 1 --brute-every 0 >/dev/null
"$BIN/gpu_check" report --simt "$OUT/simt_$MODEL.tsv" --ncu "$OUT/ncu_$MODEL.csv" | tee "$OUT/report_$MODEL.md"

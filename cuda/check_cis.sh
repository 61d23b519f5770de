#!/bin/sh
# The CIS-LBDPT half of the GPU check (docs/gpu-check.md), on a machine with an NVIDIA
# GPU, nvcc and ncu: the twin tests, the emulator's measured shading and compaction, the
# same bounces run again on the GPU under ncu, and the joined table.
#
#   BIN=target/release/examples OUT=gpu-out sh cuda/check_cis.sh [scenes] [size]
#
# BIN holds gpu_check (cargo build --release --features cuda --example gpu_check) and,
# optionally, cis_tests (the suite's test binary, `cargo test --release --features cuda
# --test suite --no-run`; its `cis_twin::` tests run). Results go to $OUT.
set -eu
. "$(dirname "$0")/common.sh"
SCENES=${1:-cornell,assets/scenes/materials.toml,assets/scenes/bedroom.toml}
SIZE=${2:-128}
if [ -x "$BIN/cis_tests" ]; then
    "$BIN/cis_tests" cis_twin:: --include-ignored >"$OUT/cis_tests.txt" 2>&1 || true
    tail -5 "$OUT/cis_tests.txt"
fi
"$BIN/gpu_check" cis --scene "$SCENES" --size "$SIZE" --simt "$OUT/simt_cis.tsv"
ncu --csv --page raw --print-units base --metrics "$("$BIN/gpu_check" metrics)" \
    --log-file "$OUT/ncu_cis.csv" "$BIN/gpu_check" cis --scene "$SCENES" --size "$SIZE" >"$OUT/cis_gpu.txt" || true
tail -3 "$OUT/cis_gpu.txt"
"$BIN/gpu_check" report --simt "$OUT/simt_cis.tsv" --ncu "$OUT/ncu_cis.csv" | tee "$OUT/report_cis.md"

#!/bin/sh
# The code a kernel's warps run: Nsight Compute's per-instruction executions (source
# view, SASS) of the LVC megakernel's camera kernel and CIS-LBDPT's shading kernel in
# whole GPU renders, with their warp states, for the instruction-fetch question of
# docs/simt.md (the megakernel's passes). Needs a GPU, nvcc and ncu, and gpu_render
# built with `--features cuda,cli`.
#
#   BIN=target/release/examples OUT=gpu-out sh cuda/hot_code.sh
#   python3 docs/reproduce/hot-code.py gpu-out/source-*.csv.gz
#
# The bedroom at 512² (12 resident warps a SM for the megakernel) and 128² (4), one
# launch each (SKIP_128=1 leaves the 128² one out); CIS-LBDPT's first two shading
# launches at 512².
set -eu
. "$(dirname "$0")/common.sh"
profile() { # name kernel-regex count gpu_render-arguments...
    name=$1 kernel=$2 count=$3
    shift 3
    ncu --clock-control none --section SourceCounters --section WarpStateStats --section LaunchStats --kernel-name-base demangled \
        -k "regex:$kernel" -c "$count" -f -o "$OUT/$name" "$BIN/gpu_render" "$@" >"$OUT/$name.log" 2>&1
    ncu -i "$OUT/$name.ncu-rep" --page source --csv --print-source sass | gzip >"$OUT/source-$name.csv.gz"
    ncu -i "$OUT/$name.ncu-rep" --page raw --csv | gzip >"$OUT/raw-$name.csv.gz"
    rm -f "$OUT/$name.ncu-rep"
}
profile mk-camera-bedroom-512 mk_camera_path 1 --scenes bedroom --integrators lvc-mk --size 512 --passes 1 --rounds 1
[ -n "${SKIP_128:-}" ] || profile mk-camera-bedroom-128 mk_camera_path 1 --scenes bedroom --integrators lvc-mk --size 128 --passes 1 --rounds 1
profile cis-shade-bedroom-512 shade_sample 2 --scenes bedroom --integrators cis --size 512 --passes 1 --rounds 1
ls -la "$OUT"

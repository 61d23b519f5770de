#!/bin/sh
# Prints the SASS of the pdacrt:: kernels of the CUDA library (cuda/build.sh's flags),
# without encodings or padding, to check the instruction weights of
# src/cast/pdacrt/kernels.rs against what nvcc emits (docs/measured/pdacrt-kernels-sm90.sass).
#   OUT=dir sh cuda/pdacrt_sass.sh
set -eu
cd "$(dirname "$0")/.."
OUT=${OUT:-target/cuda}
mkdir -p "$OUT"
[ -f target/cuda/libwarpray_cuda.so ] || sh cuda/build.sh
cuobjdump -sass target/cuda/libwarpray_cuda.so |
    awk '/Function : /{keep = ($0 ~ /_ZN6pdacrt/)} keep' |
    sed -E 's@ +/\* 0x[0-9a-f]+ \*/@@' | grep -v '^[[:space:]]*$' | grep -v '^[[:space:]]*/\*[0-9a-f]*\*/[[:space:]]*NOP;' |
    tee "$OUT/pdacrt-kernels.sass"

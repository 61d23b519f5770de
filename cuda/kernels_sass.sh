#!/bin/sh
# Prints the SASS of one namespace's kernels in the CUDA library (cuda/build.sh's
# flags), without encodings or padding, to check the instruction weights of the emulated
# twins against what nvcc emits:
#   pdacrt: src/cast/pdacrt/kernels.rs (docs/measured/pdacrt-kernels-sm90.sass)
#   bvh:    src/cast/lbvh/kernels.rs   (docs/measured/bvh-kernels-sm90.sass)
#   OUT=dir sh cuda/kernels_sass.sh [pdacrt|bvh]
set -eu
cd "$(dirname "$0")/.."
NS=${1:-pdacrt}
OUT=${OUT:-target/cuda}
mkdir -p "$OUT"
[ -f target/cuda/libwarpray_cuda.so ] || sh cuda/build.sh
cuobjdump -sass target/cuda/libwarpray_cuda.so |
    awk -v ns="_ZN${#NS}${NS}" '/Function : /{keep = (index($0, ns) > 0)} keep' |
    sed -E 's@ +/\* 0x[0-9a-f]+ \*/@@' | grep -v '^[[:space:]]*$' | grep -v '^[[:space:]]*/\*[0-9a-f]*\*/[[:space:]]*NOP;' |
    tee "$OUT/$NS-kernels.sass"

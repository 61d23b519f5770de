#!/bin/sh
# Prints the SASS of cuda/probe_costs.cu, compiled as cuda/build.sh compiles the twins,
# to check the instruction weights of src/cost.rs against what nvcc emits.
#   NVCC=/path/to/nvcc CUDA_ARCH=sm_90 OUT=dir sh cuda/probe_costs.sh
set -eu
cd "$(dirname "$0")/.."
NVCC=${NVCC:-nvcc}
ARCH=${CUDA_ARCH:-sm_90}
OUT=${OUT:-target/cuda}
mkdir -p "$OUT"
"$NVCC" -std=c++17 -O3 -arch="$ARCH" -fmad=false -prec-div=true -prec-sqrt=true -cubin \
    -o "$OUT/probe_costs.cubin" cuda/probe_costs.cu
cuobjdump -sass "$OUT/probe_costs.cubin" | tee "$OUT/probe_costs.sass"

#!/bin/sh
# Builds target/cuda/libwarpray_cuda.so, the GPU twins of PDACRT (cuda/pdacrt.cu), of
# CIS-LBDPT's shading and compaction (cuda/cis.cu), the GPU BVH baseline they are
# measured against (cuda/bvh.cu), and whole renders of CIS-LBDPT and the LVC-BDPT
# megakernels (cuda/render.cu), for the cargo feature `cuda`. Needs nvcc (CUDA 12 or
# 13, with its bundled CUB/Thrust).
#   NVCC=/path/to/nvcc CUDA_ARCH=sm_90 sh cuda/build.sh
# -fmad=false keeps every multiply and add rounded separately, as in the Rust code,
# so the GPU's hit keys equal the emulator's bit for bit.
set -eu
cd "$(dirname "$0")/.."
NVCC=${NVCC:-nvcc}
ARCH=${CUDA_ARCH:-sm_90}
mkdir -p target/cuda
"$NVCC" -std=c++17 -O3 -arch="$ARCH" -fmad=false -prec-div=true -prec-sqrt=true -lineinfo \
    -shared -Xcompiler -fPIC ${NVCC_FLAGS:-} -o target/cuda/libwarpray_cuda.so cuda/pdacrt.cu cuda/bvh.cu cuda/cis.cu cuda/render.cu
echo "built target/cuda/libwarpray_cuda.so ($ARCH)"

# Sourced by the cuda/*.sh scripts that run on the GPU machine: moves to the repository
# root, sets BIN (the built examples) and OUT (the results) unless given, makes OUT, and
# builds the CUDA library (cuda/build.sh) if it is not there yet.
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release/examples}
OUT=${OUT:-gpu-out}
mkdir -p "$OUT"
[ -f target/cuda/libwarpray_cuda.so ] || sh cuda/build.sh

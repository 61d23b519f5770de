#!/bin/sh
# Runs the microbenchmarks of cuda/microbench.cu under Nsight Compute, on a machine with
# an NVIDIA GPU, nvcc and ncu: the two files `gpu_check calibrate` turns into a GPU
# profile for simt's time model (simt/profiles/).
#
#   BIN=target/release/examples OUT=gpu-out sh cuda/microbench.sh
#   gpu_check calibrate --probes gpu-out/micro_probes.tsv --ncu gpu-out/micro_ncu.csv \
#       --name h200 >simt/profiles/h200.toml
#
# MODE=fences runs the atomic-latency and fence probes alone (files micro_fences_*),
# which `gpu_check calibrate` takes as a second --probes/--ncu pair.
# MODE=rounds runs the rounds-of-loads probes alone: their cycles per step are printed
# (lines `timed`), not read by `gpu_check calibrate` (docs/simt.md, "PDACRT's rounds").
# MODE=start runs the start-of-a-kernel probes alone (stores, parameters, cold code).
# MODE=hbm runs the random HBM reads alone (a sector at a time over 1 GiB).
# MODE=stream runs the first-touches-in-order chases alone (a lane, a warp, a warp a SM
# stepping through fresh memory in order, and a warp stepping a DRAM page at a time).
# MODE=icache runs the instruction-fetch probes alone: cycles per instruction of warps
# sharing straight-line code of 4-256 KiB, and per piece of warps jumping about 16-2048
# pieces of branchy code (lines `timed`; docs/simt.md, the megakernel's passes).
# MODE=l2size runs the load-latency-by-data-size chases alone: one thread's chase over
# 8 KiB to 1 GiB (lines `timed`, cycles a hop; docs/simt.md, "A default-cached chase").
# MODE=scan runs CUB's single-pass scan over 1 to 1,024 tiles of one and of three words
# (what a scan's look-back costs by its tiles; docs/simt.md, "The library primitives").
# MODE=grid runs a short kernel (empty, a store, a load and a store a thread) by its
# blocks, 1 to 4 a SM.
# MODE=shared runs the shared-memory latency probes alone: one thread's chase through
# shared words (cycles a hop) and one block's store-barrier-load round at 32 to 1,024
# threads (lines `timed`, not read by `gpu_check calibrate`).
# MODE=fencemix runs the fences-under-load probes alone: every SM full, fences by the
# 128-byte lines and sectors they wait for (1 to 96 lines), lanes active and first
# touches, and a BVH fit's climb without its tree, whole and in parts; not read by
# `gpu_check calibrate` (docs/simt.md, "Fences under load, probed").
# MODE=slots runs the slot probes alone: four waves of blocks whose warps sleep, every
# warp or one a block (does a block hold its SM's slot until its slowest warp ends?);
# not read by `gpu_check calibrate` (docs/simt.md, the latency term).
# MODE=overlap runs the overlap probes alone: L2 loads and arithmetic, alone and
# together, in warps that drift apart (every SM full) and in blocks whose barriers keep
# their warps in one phase (1, 2 or 4 blocks a SM): how a memory and an arithmetic bound
# combine (docs/simt.md, how the bounds combine).
# MODE=inflight runs the in-flight probes alone: L2 streamed by 16, 32 or 64 warps a SM
# each keeping 1 to 8 loads in flight, beside `l2_read` on the same card; not read by
# `gpu_check calibrate`.
#
# ncu runs with --clock-control none (the GPU's own clocks, as in cuda/check.sh) and its
# default --cache-control all (caches flushed before each kernel), as the checked
# kernels are profiled.
set -eu
cd "$(dirname "$0")/.."
NVCC=${NVCC:-nvcc}
ARCH=${CUDA_ARCH:-sm_90}
BIN=${BIN:-target/release/examples}
OUT=${OUT:-gpu-out}
mkdir -p target/cuda "$OUT"
"$NVCC" -std=c++17 -O3 -arch="$ARCH" -o target/cuda/microbench cuda/microbench.cu
MODE=${MODE:-}
STEM=micro${MODE:+_$MODE}
METRICS=${METRICS:-$("$BIN/gpu_check" metrics)}
ncu --clock-control none --csv --page raw --print-units base --metrics "$METRICS" \
    --log-file "$OUT/${STEM}_ncu.csv" target/cuda/microbench $MODE >"$OUT/${STEM}_probes.tsv"
echo "probes: $(grep -c '^probe' "$OUT/${STEM}_probes.tsv"), launches profiled: $(grep -c '^"[0-9]' "$OUT/${STEM}_ncu.csv")"

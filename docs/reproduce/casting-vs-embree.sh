#!/usr/bin/env sh
# The casting tables of docs/dacrt.md: every caster against Embree on the same rays
# (bunny, conference, dragon at 1024², 5 interleaved rounds), DACRT's thread scaling,
# and the animated grid per frame (shadow and diffuse secondary rays).
#
#   cargo build --release --features embree --example dacrt_tables --example animated
#   WARPRAY_MODELS=../shared/models [WARPRAY_EMBREE=/path/libembree4.so.4] \
#       sh docs/reproduce/casting-vs-embree.sh OUT_DIR [BIN_DIR]
#
# BIN_DIR defaults to target/release/examples. Each step writes JSON lines (the first
# line of each file is the machine) and can be run alone by copying its line.
set -eu
out=${1:?usage: casting-vs-embree.sh OUT_DIR [BIN_DIR]}
bin=${2:-target/release/examples}
mkdir -p "$out"
step=${STEP:-all}
if [ "$step" = all ] || [ "$step" = tables ]; then
    # docs/dacrt.md's method: PROCESSES interleaved processes (default 5) of 3 rounds
    # each, DACRT (with its variants without the ray-sampled planes and without the
    # cells' layout), BVH4 and both Embree settings in every process; the summary takes
    # each ratio within its process and gives the median over processes.
    p=1
    while [ "$p" -le "${PROCESSES:-5}" ]; do
        for scenes in dragon bunny,conference; do
            "$bin/dacrt_tables" --size 1024 --scenes $scenes --threads 16 \
                --casters dacrt,dacrt-median,dacrt-by-id,bvh4,embree,embree-fast --rounds 3 --json \
                > "$out/casting-1024-16t-process-$p-$scenes.jsonl"
        done
        p=$((p + 1))
    done
    # Every caster once, in one process of 5 rounds (obvhs, DACRT on SSE alone, PDACRT).
    "$bin/dacrt_tables" --size 1024 --scenes bunny,conference,dragon \
        --casters bvh,bvh4,dacrt,dacrt-sse,pdacrt,embree,embree-fast --rounds 5 --json > "$out/casting-1024-16t.jsonl"
    "$bin/dacrt_tables" --size 1024 --scenes dragon --casters bvh4,dacrt,embree,embree-fast --threads 16 \
        --scaling 1 --rounds 5 --json > "$out/casting-dragon-1-vs-16t.jsonl"
fi
if [ "$step" = all ] || [ "$step" = animated ]; then
    for s in shadow diffuse; do
        "$bin/animated" --threads 16 --frames 7 --secondary $s \
            --casters bvh,bvh4,dacrt,dacrt-median,dacrt-by-id,dacrt-sse,pdacrt,embree,embree-fast,embree-refit \
            --json > "$out/animated-$s-16t.jsonl"
        "$bin/animated" --threads 1,4 --frames 3 --secondary $s \
            --casters bvh,bvh4,dacrt,pdacrt,embree,embree-fast,embree-refit --json > "$out/animated-$s-1-4t.jsonl"
    done
fi

#!/bin/sh
# Per-instruction counters (Nsight Compute's source view) of CIS-LBDPT's shading kernel
# and PDACRT's brute force, split by the array each global access reads or writes and set
# beside the emulator's statistics of the same launches (docs/gpu-check.md, "Which
# instructions the model sees"). Needs a GPU, nvcc and ncu.
#
#   WARPRAY_MODELS=... BIN=target/release/examples OUT=gpu-out sh cuda/source_counters.sh [scenes] [launches]
#
# For each scene and order, the first LAUNCHES (default 2) shading launches are profiled;
# on the primary rays of each model in PDACRT_MODELS (default bunny), the first
# PDACRT_LAUNCHES (default 14) launches of PDACRT's kernels named in PDACRT_KERNELS (two
# or three of each); each kernel's LINES (default 12) busiest source lines are listed;
# exporting takes about 25 s per launch, so the exports run side by side. Results go to
# $OUT/source_*.md; the raw exports are kept gzipped.
set -eu
. "$(dirname "$0")/common.sh"
SCENES=${1-cornell assets/scenes/materials.toml assets/scenes/bedroom.toml}
N=${2:-2}
PDACRT_KERNELS=${PDACRT_KERNELS:-brute_force|node_bounds|classify_children|emit_children|scatter_rays|scatter_triangles}
PDACRT_LAUNCHES=${PDACRT_LAUNCHES:-14}
PDACRT_MODELS=${PDACRT_MODELS:-bunny}
LINES=${LINES:-12}
profile() { # name kernel-regex count command...
    name=$1 kernel=$2 count=$3
    shift 3
    ncu --section SourceCounters --import-source yes -k "regex:$kernel" -c "$count" -f -o "$OUT/$name" "$@" \
        >"$OUT/$name.log" 2>&1
}
names=""
for s in $SCENES; do
    base=$(basename "$s" .toml)
    "$BIN/gpu_check" cis --scene "$s" --size 128 --simt "$OUT/simt_$base.tsv" --simt-launches "$OUT/launches_$base.tsv"
    profile "${base}_sorted" shade_sorted "$N" "$BIN/gpu_check" cis --scene "$s" --size 128
    profile "${base}_unsorted" shade_unsorted "$N" "$BIN/gpu_check" cis --scene "$s" --size 128
    names="$names ${base}_sorted ${base}_unsorted"
done
if [ -n "${WARPRAY_MODELS:-}" ]; then
    for m in $PDACRT_MODELS; do
        "$BIN/gpu_check" simt --model "$m" --batch primary --size 512 --out "$OUT/simt_$m.tsv" --launches "$OUT/launches_$m.tsv"
        profile "${m}_pdacrt" "$PDACRT_KERNELS" "$PDACRT_LAUNCHES" \
            "$BIN/gpu_check" gpu --model "$m" --batch primary --size 512 --repeat 1 --brute-every 0
        names="$names ${m}_pdacrt"
    done
fi
for n in $names; do
    ncu -i "$OUT/$n.ncu-rep" --page source --csv --print-source cuda,sass >"$OUT/$n.csv" 2>&1 &
done
wait
for n in $names; do
    case "$n" in
    *_pdacrt) "$BIN/gpu_check" source --classes all --lines "$LINES" --csv "$OUT/$n.csv" \
        --simt-launches "$OUT/launches_${n%_pdacrt}.tsv" ;;
    *) "$BIN/gpu_check" source --lines "$LINES" --csv "$OUT/$n.csv" --simt-launches "$OUT/launches_${n%_*}.tsv" ;;
    esac >"$OUT/source_$n.md"
    rm -f "$OUT/$n.ncu-rep"
    gzip -f "$OUT/$n.csv"
done
tail -n 8 "$OUT"/source_*.md

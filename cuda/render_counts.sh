#!/bin/sh
# Per-launch counters of the whole GPU renders' heaviest kernels (the LVC megakernels,
# CIS-LBDPT's shading, light and trace stages) in the Cornell box, the white room and the
# bedroom at 128² and 512² (max depth 8, a warm-up and a timed pass): time, warp
# instructions, SIMD efficiency, local-memory sectors, the `no_instruction` wait and
# the SMs' cycles, for docs/simt.md (the megakernel's passes). Needs a GPU, nvcc, ncu and
# gpu_render built with `--features cuda,cli`.
#
#   BIN=target/release/examples OUT=gpu-out sh cuda/render_counts.sh
#   python3 docs/reproduce/render-kernel-rates.py gpu-out/ncu-gpu-render-kernels-3-scenes-128-512.csv.gz
set -eu
. "$(dirname "$0")/common.sh"
M=gpu__time_duration.sum,smsp__inst_executed.sum,smsp__thread_inst_executed.sum
M=$M,l1tex__t_sectors_pipe_lsu_mem_local_op_ld.sum,l1tex__t_sectors_pipe_lsu_mem_local_op_st.sum
M=$M,l1tex__t_sector_pipe_lsu_mem_local_op_ld_hit_rate.pct
M=$M,smsp__average_warps_issue_stalled_no_instruction_per_issue_active.ratio
M=$M,smsp__average_warp_latency_per_inst_issued.ratio,sm__cycles_elapsed.avg
M=$M,launch__registers_per_thread,launch__grid_size,launch__block_size
for size in 128 512; do
    for scene in cornell white-room bedroom; do
        ncu --clock-control none --csv --page raw --print-units base --metrics "$M" --kernel-name-base demangled \
            -k "regex:mk_|shade_sample|light_shade|light_splat|pending_shadow|extend_" \
            --log-file "$OUT/counts-$scene-$size.csv" \
            "$BIN/gpu_render" --scenes "$scene" --integrators lvc-mk,cis --size "$size" --passes 1 --rounds 1 \
            >"$OUT/counts-$scene-$size.log" 2>&1
    done
done
python3 docs/reproduce/render-kernel-rates.py --reduce "$OUT" "$OUT/ncu-gpu-render-kernels-3-scenes-128-512.csv.gz"
ls -la "$OUT"

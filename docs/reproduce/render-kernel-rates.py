#!/usr/bin/env python3
"""What the whole GPU renders' heaviest kernels issue, per pass, from Nsight Compute's
counters (`cuda/render_counts.sh`; the stored copy is
docs/measured/ncu-gpu-render-kernels-3-scenes-128-512-h100.csv.gz): per scene, size and
kernel, milliseconds, warp instructions, SIMD efficiency, warp instructions an SM issued
a cycle, the `no_instruction` wait per issued instruction, and the local-memory sectors.
Each render ran a warm-up pass and a timed pass; the figures are per pass (the sums over
both, halved).

With emulator launch records of the same renders (`warpray render SCENE --integrator
lvc-mk|cis --caster lbvh --spp 1 --size NxN --max-depth 8 --gpu-profile h200
--launch-records FILE.tsv`, files named `{lvc-mk,cis}-{scene}-{size}.tsv` in a folder),
also the share of the GPU's warp instructions the emulator counted.

    python3 docs/reproduce/render-kernel-rates.py FILE.csv.gz [--records FOLDER]
    python3 docs/reproduce/render-kernel-rates.py --reduce RAW_FOLDER OUT.csv.gz
"""
import collections
import csv
import gzip
import io
import os
import re
import sys

KEEP = [
    "gpu__time_duration.sum",
    "smsp__inst_executed.sum",
    "smsp__thread_inst_executed.sum",
    "l1tex__t_sectors_pipe_lsu_mem_local_op_ld.sum",
    "l1tex__t_sectors_pipe_lsu_mem_local_op_st.sum",
    "l1tex__t_sector_pipe_lsu_mem_local_op_ld_hit_rate.pct",
    "smsp__average_warps_issue_stalled_no_instruction_per_issue_active.ratio",
    "smsp__average_warp_latency_per_inst_issued.ratio",
    "sm__cycles_elapsed.avg",
    "launch__registers_per_thread",
    "launch__grid_size",
    "launch__block_size",
]
SCENES = ["cornell", "white-room", "bedroom"]
SIZES = [128, 512]
SMS = 132
# The emulator's kernel for each GPU stage (the CIS trace stages are one emulated kernel,
# `bvh::trace`, which also casts the splats' shadow rays: not set beside them).
EMULATED = {
    "mk_camera_path": ("lvc-mk", "lvc::camera_path"),
    "mk_light_path": ("lvc-mk", "lvc::light_path"),
    "mk_splat": ("lvc-mk", "lvc::splat"),
    "shade_sample": ("cis", "cis::shade"),
    "light_shade": ("cis", "cis::light_shade"),
    "light_splat": ("cis", "cis::light_splat"),
}


def number(s):
    return float(s.replace(",", "")) if s else 0.0


def reduce(folder, out):
    """Keeps the columns above of the raw CSVs `counts-{scene}-{size}.csv` in `folder`."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["scene", "size", "ID", "Kernel Name"] + KEEP)
    for size in SIZES:
        for scene in SCENES:
            path = os.path.join(folder, f"counts-{scene}-{size}.csv")
            lines = [l for l in open(path, errors="replace") if not l.startswith("==")]
            rows = [r for r in csv.reader(lines) if r]
            header = rows[0]
            for r in rows[2:]:  # the second row holds the units
                d = dict(zip(header, r))
                w.writerow([scene, size, d["ID"], d["Kernel Name"]] + [d[k].replace(",", "") for k in KEEP])
    with open(out, "wb") as f:
        f.write(gzip.compress(buf.getvalue().encode(), 9, mtime=0))


def emulated(folder, integrator, scene, size):
    """Warp instructions per kernel of an emulator launch-record file, or None."""
    path = os.path.join(folder, f"{integrator}-{scene}-{size}.tsv")
    if not os.path.exists(path):
        return None
    out = collections.Counter()
    header = None
    for line in open(path):
        f = line.rstrip("\n").split("\t")
        if f[0] == "name":
            header = f
            continue
        d = dict(zip(header, f))
        out[d["name"]] += int(d["ops_issued"]) + int(d["work_issued"])
    return out


def report(path, records):
    rows = list(csv.DictReader(io.StringIO(gzip.open(path, "rt").read())))
    for size in SIZES:
        for scene in SCENES:
            per = collections.OrderedDict()
            for d in rows:
                if d["scene"] != scene or int(d["size"]) != size:
                    continue
                stage = re.search(r"&(\w+)>", d["Kernel Name"]).group(1)
                a = per.setdefault(stage, collections.Counter())
                inst = number(d["smsp__inst_executed.sum"])
                a["launches"] += 1
                a["ms"] += number(d["gpu__time_duration.sum"]) / 1e6
                a["inst"] += inst
                a["threads"] += number(d["smsp__thread_inst_executed.sum"])
                a["cycles"] += number(d["sm__cycles_elapsed.avg"])
                a["fetch"] += inst * number(d["smsp__average_warps_issue_stalled_no_instruction_per_issue_active.ratio"])
                a["local"] += number(d["l1tex__t_sectors_pipe_lsu_mem_local_op_ld.sum"])
                a["local"] += number(d["l1tex__t_sectors_pipe_lsu_mem_local_op_st.sum"])
                a["registers"] = number(d["launch__registers_per_thread"])
            print(f"\n{scene}, {size}², per pass (Nsight Compute, a warm-up and a timed pass halved)\n")
            head = "| kernel | launches | ms | warp instructions | SIMD efficiency | issued a SM cycle | `no_instruction` an issue | local sectors | registers |"
            if records:
                head += " emulator counts |"
            print(head)
            print("|---" * (head.count("|") - 1) + "|")
            for stage, a in per.items():
                inst = a["inst"]
                line = (
                    f"| {stage} | {a['launches'] / 2:.0f} | {a['ms'] / 2:.3f} | {inst / 2:.3e} | "
                    f"{a['threads'] / 32 / max(inst, 1):.3f} | {inst / SMS / max(a['cycles'], 1):.3f} | "
                    f"{a['fetch'] / max(inst, 1):.1f} | {a['local'] / 2:.3e} | {a['registers']:.0f} |"
                )
                if records:
                    share = "-"
                    if stage in EMULATED:
                        integrator, name = EMULATED[stage]
                        e = emulated(records, integrator, scene, size)
                        if e and name in e:
                            share = f"{e[name] / (inst / 2) * 100:.0f} %"
                    line += f" {share} |"
                print(line)


def main(argv):
    if len(argv) == 3 and argv[0] == "--reduce":
        reduce(argv[1], argv[2])
    elif len(argv) == 1:
        report(argv[0], None)
    elif len(argv) == 3 and argv[1] == "--records":
        report(argv[0], argv[2])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])

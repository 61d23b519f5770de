#!/usr/bin/env python3
"""Tables of docs/dacrt.md from the JSON lines of casting-vs-embree.sh.

    python3 docs/reproduce/casting-summary.py OUT_DIR

Prints markdown: the page's table (DACRT, BVH4 and Embree in interleaved processes,
ratios within each process), each batch's build + trace per caster and the ratios to
Embree's default and fastest settings; DACRT's steps (its variants without the
ray-sampled planes and without the cells' layout, where the processes ran them); DACRT's
1 -> 16 thread scaling by stage; the animated grid.
"""
import json
import statistics
import sys
from pathlib import Path

out = Path(sys.argv[1])


def rows(name):
    p = out / name
    if not p.exists():
        return None, []
    lines = [json.loads(l) for l in p.read_text().splitlines() if l.strip()]
    machine = next((l["machine"] for l in lines if "machine" in l), None)
    return machine, [l for l in lines if "machine" not in l]


# docs/dacrt.md's table: per batch, medians over the interleaved processes, each ratio
# taken within its process.
procs = {}
for f in sorted(out.glob("casting-1024-16t-process-*.jsonl")):
    proc = f.name.split("-")[4]
    m, r_all = rows(f.name)
    if m and not procs:
        print(f"Machine: {m['cpu']}, {m['cpus']} CPUs, vector extensions {' '.join(m['extensions'])}\n")
    for r in r_all:
        procs.setdefault((r["scene"], r["batch"]), {}).setdefault(proc, {})[r["caster"]] = r
if procs:
    med = statistics.median
    print(f"DACRT against Embree, {len({p for v in procs.values() for p in v})} interleaved processes "
          "(ms; ratios within each process, medians over them):\n")
    print("| scene | batch | rays | DACRT | tests per ray | core-ns per test | BVH4 | Embree | Embree fastest "
          "| DACRT ÷ Embree | DACRT ÷ Embree fastest | BVH4 ÷ Embree |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for scene in ["bunny", "conference", "dragon"]:
        for batch in ["primary", "shadow", "specular", "ao"]:
            by = procs.get((scene, batch))
            if not by:
                continue
            full = [p for p in by.values() if all(c in p for c in ["dacrt", "embree", "embree-fast"])]
            has_bvh4 = all("bvh4" in p for p in full)
            if not full:
                continue
            d = [p["dacrt"] for p in full]
            cell = lambda c: (f"{med(p[c]['build_ms'] for p in full):.1f} + "
                              f"{med(p[c]['trace_ms'] for p in full):.1f}" if c != "bvh4" or has_bvh4 else "-")
            ratio = lambda a, b: med(p[a]["total_ms"] / p[b]["total_ms"] for p in full)
            tests = med(x["tests"] for x in d)
            busy = med(x["phases"]["groups_busy"] for x in d)
            print(f"| {scene} | {batch} | {d[0]['rays']:,} | {med(x['total_ms'] for x in d):.1f} | "
                  f"{tests / d[0]['rays']:.1f} | {busy * 1e6 / max(tests, 1):.0f} | {cell('bvh4')} | "
                  f"{cell('embree')} | {cell('embree-fast')} | {ratio('dacrt', 'embree'):.2f}× | "
                  f"{ratio('dacrt', 'embree-fast'):.2f}× | "
                  + (f"{ratio('bvh4', 'embree'):.2f}× |" if has_bvh4 else "- |"))

# DACRT's own steps, where the processes ran its variants: without the ray-sampled
# planes (`dacrt-median`) and without the cells' layout (`dacrt-by-id`), each against
# DACRT as it is, within each process.
steps = [("dacrt-median", "ray-sampled planes"), ("dacrt-by-id", "cell layout")]
if any(v in p for by in procs.values() for p in by.values() for v, _ in steps):
    med = statistics.median
    print("\nDACRT's steps: each variant without one step, against DACRT with both "
          "(ms and tests per ray, medians over processes; ratio within each process):\n")
    print("| scene | batch | DACRT | tests per ray | " + " | ".join(
        f"without {what} | tests per ray | DACRT ÷ without" for _, what in steps) + " |")
    print("|---|---|---:|---:|" + "---:|---:|---:|" * len(steps))
    for scene in ["bunny", "conference", "dragon"]:
        for batch in ["primary", "shadow", "specular", "ao"]:
            by = procs.get((scene, batch))
            full = [p for p in (by or {}).values() if all(c in p for c in ["dacrt"] + [v for v, _ in steps])]
            if not full:
                continue
            tpr = lambda c: med(p[c]["tests"] / max(p[c]["rays"], 1) for p in full)
            line = f"| {scene} | {batch} | {med(p['dacrt']['total_ms'] for p in full):.1f} | {tpr('dacrt'):.1f} |"
            for v, _ in steps:
                line += (f" {med(p[v]['total_ms'] for p in full):.1f} | {tpr(v):.1f} | "
                         f"{med(p['dacrt']['total_ms'] / p[v]['total_ms'] for p in full):.2f}× |")
            print(line)

machine, t = rows("casting-1024-16t.jsonl")
if t:
    print("\nEvery caster in one process:\n")
if machine:
    print(f"Machine: {machine['cpu']}, {machine['cpus']} CPUs, vector extensions "
          f"{' '.join(machine['extensions'])}; binary compiled for "
          f"{' '.join(machine['compiled_for']) or 'baseline x86-64'}\n")
cell = {(r["scene"], r["batch"], r["caster"]): r for r in t if r["threads"] == 16}
casters = [c for c in ["embree", "embree-fast", "bvh", "bvh4", "dacrt", "pdacrt"] if any(k[2] == c for k in cell)]
if cell:
    print("| scene | batch | rays | " + " | ".join(f"{c} ms" for c in casters)
          + " | DACRT ÷ Embree | DACRT ÷ Embree fastest | BVH ÷ Embree | BVH4 ÷ Embree | DACRT tests/ray | DACRT core-ns/test |")
    print("|---|---|---:|" + "---:|" * (len(casters) + 6))
for scene in ["bunny", "conference", "dragon"]:
    for batch in ["primary", "shadow", "specular", "ao"]:
        if (scene, batch, "dacrt") not in cell:
            continue
        c = {k: cell[(scene, batch, k)] for k in casters if (scene, batch, k) in cell}
        tot = {k: v["total_ms"] for k, v in c.items()}
        d = c["dacrt"]
        ratio = lambda a, b: f"{tot[a] / tot[b]:.2f}×" if a in tot and b in tot else "-"
        # Core-ns per ray-triangle test: the recursion's time summed over its threads
        # (DACRT's `groups_busy` stage) over its tests, as docs/dacrt.md gives it.
        busy = (d.get("phases") or {}).get("groups_busy")
        ns = busy * 1e6 / max(d["tests"], 1) if busy is not None else float("nan")
        print(f"| {scene} | {batch} | {d['rays']} | "
              + " | ".join(f"{v['build_ms']:.1f} + {v['trace_ms']:.1f} = {v['total_ms']:.1f}" for v in c.values())
              + f" | {ratio('dacrt', 'embree')} | {ratio('dacrt', 'embree-fast')} | {ratio('bvh', 'embree')} | {ratio('bvh4', 'embree')}"
              + f" | {d['tests'] / d['rays']:.1f} | {ns:.1f} |")

_, s = rows("casting-dragon-1-vs-16t.jsonl")
if s:
    print("\nThread scaling, dragon (1 and 16 threads, medians of the rounds):\n")
    print("| caster | batch | 1 thread ms | 16 threads ms | speed-up |")
    print("|---|---|---:|---:|---:|")
    for c in ["bvh4", "dacrt", "embree", "embree-fast"]:
        for b in ["primary", "shadow"]:
            one = [r for r in s if r["caster"] == c and r["batch"] == b and r["threads"] == 1]
            six = [r for r in s if r["caster"] == c and r["batch"] == b and r["threads"] == 16]
            # (With `--scaling 1,16` the main table's 16-thread row comes first and the
            # scaling table's own last: take the last.)
            six = six[-1:]
            if one and six:
                print(f"| {c} | {b} | {one[0]['total_ms']:.1f} | {six[0]['total_ms']:.1f} | "
                      f"{one[0]['total_ms'] / six[0]['total_ms']:.2f}× |")
                if c == "dacrt" and b == "primary" and one[0].get("phases") and six[0].get("phases"):
                    # DACRT's stages (ms), as docs/dacrt.md's scaling table gives them.
                    for stage, key in [("filter", "filter"), ("shared top", "prepare_top"),
                                       ("rays' order and copy", "prepare_rays"), ("recursion", "groups")]:
                        p1, p16 = one[0]["phases"][key], six[0]["phases"][key]
                        print(f"| dacrt: {stage} | {b} | {p1:.1f} | {p16:.1f} | {p1 / p16:.2f}× |")

for sec in ["shadow", "diffuse"]:
    a = rows(f"animated-{sec}-16t.jsonl")[1] + rows(f"animated-{sec}-1-4t.jsonl")[1]
    if not a:
        continue
    print(f"\nAnimated grid (1M triangles, 1024² primary + {sec} rays), per frame, medians over frames:\n")
    print("| threads | caster | set-up ms | primary ms | secondary ms | frame ms | DACRT ÷ this |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for th in sorted({r["threads"] for r in a}):
        med = {}
        for c in ["bvh", "bvh4", "dacrt", "dacrt-median", "dacrt-by-id", "pdacrt", "embree", "embree-fast", "embree-refit"]:
            m = [r for r in a if r["threads"] == th and r["caster"] == c]
            if m:
                med[c] = {k: statistics.median(r[k] for r in m) for k in ["setup_ms", "primary_ms", "secondary_ms", "total_ms"]}
        for c, v in med.items():
            print(f"| {th} | {c} | {v['setup_ms']:.1f} | {v['primary_ms']:.1f} | {v['secondary_ms']:.1f} | "
                  f"{v['total_ms']:.1f} | {med['dacrt']['total_ms'] / v['total_ms']:.2f}× |")

"""Time to Mitsuba's error: each of warpray's integrators against Mitsuba 3's
`llvm_ad_rgb` path tracer on Mitsuba's Cornell box (assets/scenes/mitsuba-cbox.xml as
shipped: 256 x 256, Gaussian filter, rr_depth 5), the figure of docs/mitsuba.md.

For every round, Mitsuba renders 64 spp, then warpray renders SPP spp with each
integrator, one after another (interleaved rounds, seed = round). Each render's mean
squared error against a high-spp Mitsuba reference is measured; the reference's own
noise (1/REF_FACTOR of Mitsuba's 64-spp error) is taken off every figure, and error² is
taken to fall as 1/spp, so a render of time t and error e reaches Mitsuba's 64-spp
error e_m in t × (e / e_m)². The ratio of that to Mitsuba's 64-spp time is the figure,
in CPU seconds (the whole warpray process, scene load included; Mitsuba's process-wide
CPU time around `mi.render`, after a warm-up render compiled its kernels) and in wall
seconds. Medians over rounds for times, means over rounds for squared errors.

The film filter is the one `llvm_ad_rgb` uses. Mitsuba's JIT variants evaluate the
Gaussian exactly; only its scalar variants read the 31-step table (`eval_discretized`
throws in JIT modes: include/mitsuba/core/rfilter.h). warpray's XML scenes default to
the table, scalar_rgb's image (docs/mitsuba.md compares noise pixel by pixel with
scalar_rgb), so warpray is run here with `--filter gaussian:0.5:2`, the exact Gaussian:
against llvm_ad_rgb's reference the stepped filter's image differs by a squared bias
of about 3e-5, 15 % of a 64-spp render's error, which would be counted as noise.
FILTER overrides it (FILTER= keeps the scene's own filter).

Run from the repository root after `cargo build --release` (pip install mitsuba==3.9.1
numpy; the LLVM variant needs a libLLVM it can load, e.g. `apt-get install libllvm19`):

  python3 docs/reproduce/mitsuba_speed.py [ROUNDS] > docs/measured/speed-cbox-vs-mitsuba-llvm-2core.json

Environment: WARPRAY (binary, default target/release/warpray), SPP (warpray's spp per
render, default 64), INTEGRATORS (comma list, default path,light,bdpt,lvc,lvc-mk,cis;
an entry `bdpt@path/to/warpray` runs that integrator of another build in the same rounds),
REF (a cached reference EXR; rendered and written there if absent).
"""
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

import drjit as dr
import mitsuba as mi
import numpy as np

mi.set_variant("llvm_ad_rgb")
SCENE = "assets/scenes/mitsuba-cbox.xml"
ROUNDS = int(sys.argv[1]) if len(sys.argv) > 1 else 5
SPP = int(os.environ.get("SPP", "64"))
FILTER = os.environ.get("FILTER", "gaussian:0.5:2")
MITSUBA_SPP = 64
REF_SPP = 4096
REF_FACTOR = REF_SPP // MITSUBA_SPP
WARPRAY = os.environ.get("WARPRAY", "target/release/warpray")
INTEGRATORS = os.environ.get("INTEGRATORS", "path,light,bdpt,lvc,lvc-mk,cis").split(",")
REF = os.environ.get("REF", "/tmp/mitsuba-cbox-ref-4096.exr")


def cpu_name():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def mitsuba_render(scene, spp, seed):
    wall, cpu = time.perf_counter(), time.process_time()
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    arr = np.array(img, dtype=np.float64)[..., :3]
    return arr, time.perf_counter() - wall, time.process_time() - cpu


def warpray_render(name, seed, tmp):
    # `integrator@binary` runs another build, interleaved with the others.
    integrator, _, binary = name.partition("@")
    out = os.path.join(tmp, f"{abs(hash(binary))}-{integrator}-{seed}.exr")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.perf_counter()
    subprocess.run([binary or WARPRAY, SCENE, "--integrator", integrator, "--spp", str(SPP), "--seed", str(seed),
                    "--output", out, "--quiet"] + (["--filter", FILTER] if FILTER else []),
                   check=True, capture_output=True)
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return np.array(mi.Bitmap(out), dtype=np.float64)[..., :3], wall, cpu


scene = mi.load_file(SCENE)
if os.path.exists(REF):
    ref = np.array(mi.Bitmap(REF), dtype=np.float64)[..., :3]
else:
    # In pieces of 512 spp with distinct seeds, averaged.
    parts = [mitsuba_render(scene, 512, 10_000 + k)[0] for k in range(REF_SPP // 512)]
    ref = np.mean(parts, axis=0)
    mi.Bitmap(ref.astype(np.float32)).write(REF)
    print(f"reference written to {REF}", file=sys.stderr)

mitsuba_render(scene, MITSUBA_SPP, 0)  # warm-up: compiles and caches the kernels
rows = {"mitsuba": []} | {i: [] for i in INTEGRATORS}
with tempfile.TemporaryDirectory() as tmp:
    for r in range(1, ROUNDS + 1):
        img, wall, cpu = mitsuba_render(scene, MITSUBA_SPP, r)
        rows["mitsuba"].append((float(((img - ref) ** 2).mean()), wall, cpu))
        for integrator in INTEGRATORS:
            img, wall, cpu = warpray_render(integrator, r, tmp)
            rows[integrator].append((float(((img - ref) ** 2).mean()), wall, cpu))
        print(f"round {r} of {ROUNDS} done", file=sys.stderr)


def summary(name):
    mse = np.array([x[0] for x in rows[name]])
    return {"mse_measured": float(mse.mean()),
            "wall_s_median": float(np.median([x[1] for x in rows[name]])),
            "cpu_s_median": float(np.median([x[2] for x in rows[name]])),
            "wall_s": [round(x[1], 3) for x in rows[name]],
            "cpu_s": [round(x[2], 3) for x in rows[name]]}


m = summary("mitsuba")
ref_noise = m["mse_measured"] / (REF_FACTOR + 1)  # measured = true + ref; ref = true / REF_FACTOR
m_mse = m["mse_measured"] - ref_noise
result = {
    "scene": SCENE, "machine": {"cpu": cpu_name(), "cpus": os.cpu_count()},
    "mitsuba": f"Mitsuba {mi.__version__} llvm_ad_rgb, {MITSUBA_SPP} spp",
    "warpray": f"{WARPRAY} ({SPP} spp per render)",
    "reference": f"Mitsuba llvm_ad_rgb {REF_SPP} spp; its noise, estimated as Mitsuba's 64-spp MSE / {REF_FACTOR}, taken off every MSE",
    "rounds": ROUNDS,
    "filter": FILTER or "the scene's",
    "command": f"SPP={SPP} INTEGRATORS={','.join(INTEGRATORS)} python3 docs/reproduce/mitsuba_speed.py {ROUNDS}",
    "rows": [],
}
for name in ["mitsuba"] + INTEGRATORS:
    s = m if name == "mitsuba" else summary(name)
    mse = s["mse_measured"] - ref_noise
    factor = mse / m_mse
    s |= {"name": name, "mse": mse, "rmse": float(np.sqrt(mse)), "error_factor": factor,
          "cpu_ratio_to_mitsuba_error": s["cpu_s_median"] * factor / m["cpu_s_median"],
          "wall_ratio_to_mitsuba_error": s["wall_s_median"] * factor / m["wall_s_median"]}
    result["rows"].append(s)
print(json.dumps(result, indent=1))
for s in result["rows"]:
    print(f"{s['name']:8} rmse {s['rmse']:.4e}  cpu {s['cpu_s_median']:6.2f} s  wall {s['wall_s_median']:6.2f} s  "
          f"to Mitsuba's error: {s['cpu_ratio_to_mitsuba_error']:.2f}x cpu, {s['wall_ratio_to_mitsuba_error']:.2f}x wall",
          file=sys.stderr)

"""Equal-spp error of warpray's path tracer against Mitsuba 3's on Mitsuba's Cornell box
(assets/scenes/mitsuba-cbox.xml, 256 x 256, 64 spp, Gaussian filter splatted as
Mitsuba does): each renderer renders the file with SEEDS seeds, and per pixel the
variance over seeds, divided by (mean² + 0.01) with the mean taken over every render
of both, is averaged over the image. That is the relMSE one render has against the
true image (both renderers converge to the same one: their image means agree), so the
ratio of the two says whether warpray's noise is Mitsuba's, pixel by pixel. warpray
renders twice: as the file says (Mitsuba's default rr_depth, 5) and with roulette from
the 4th bounce (`--rr-depth 4`, warpray's own default). Standard errors by jackknife
over seeds.

Run from the repository root after `cargo build --release` (pip install mitsuba==3.9.1
numpy):

  python3 docs/reproduce/mitsuba_relmse.py [SEEDS] > docs/measured/relmse-cbox-64spp-vs-mitsuba.json
"""
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
SCENE = "assets/scenes/mitsuba-cbox.xml"
SPP = 64
SEEDS = int(sys.argv[1]) if len(sys.argv) > 1 else 16
EPS = 0.01
WARPRAY = os.environ.get("WARPRAY", "target/release/warpray")


def warpray(seed, extra, tmp):
    out = os.path.join(tmp, f"w{seed}.exr")
    subprocess.run([WARPRAY, SCENE, "--spp", str(SPP), "--seed", str(seed), "--output", out, "--quiet", *extra],
                   check=True, capture_output=True)
    return np.array(mi.Bitmap(out), dtype=np.float64)[..., :3]


def rel_var(stack, mean):
    """Per-pixel variance over seeds, relative to mean² + EPS, averaged (luminance-free:
    the channels' sum, as `warpray diff` does)."""
    var = stack.var(axis=0, ddof=1).sum(axis=-1)
    return float((var / ((mean ** 2).sum(axis=-1) + EPS)).mean())


def jackknife(stacks, mean):
    """The ratio of every stack's relative variance to the first's, with jackknife errors."""
    full = [rel_var(s, mean) for s in stacks]
    n = stacks[0].shape[0]
    leave = [[rel_var(np.delete(s, i, axis=0), mean) for s in stacks] for i in range(n)]
    out = []
    for k in range(len(stacks)):
        ratio = full[k] / full[0]
        ratios = np.array([lv[k] / lv[0] for lv in leave])
        se = float(np.sqrt((n - 1) / n * ((ratios - ratios.mean()) ** 2).sum()))
        out.append((full[k], ratio, se))
    return out


scene = mi.load_file(SCENE)
with tempfile.TemporaryDirectory() as tmp:
    start = time.time()
    mits = np.stack([np.array(mi.render(scene, spp=SPP, seed=s), dtype=np.float64) for s in range(1, SEEDS + 1)])
    t_mits = time.time() - start
    start = time.time()
    file_rr = np.stack([warpray(s, [], tmp) for s in range(1, SEEDS + 1)])
    t_file = time.time() - start
    rr4 = np.stack([warpray(s, ["--rr-depth", "4"], tmp) for s in range(1, SEEDS + 1)])
mean = np.concatenate([mits, file_rr, rr4]).mean(axis=0)
rows = jackknife([mits, file_rr, rr4], mean)
names = ["mitsuba (rr_depth 5)", "warpray (rr_depth 5, the file's default)", "warpray --rr-depth 4"]
lum = np.array([0.2126, 0.7152, 0.0722])
print(json.dumps({
    "scene": SCENE, "spp": SPP, "seeds": SEEDS, "epsilon": EPS,
    "machine": platform.processor() or platform.machine(),
    "renderer": f"Mitsuba {mi.__version__} scalar_rgb; warpray {WARPRAY}",
    "command": "python3 docs/reproduce/mitsuba_relmse.py",
    "seconds": {"mitsuba": round(t_mits, 1), "warpray": round(t_file, 1)},
    "image_means": {n: float((s.mean(axis=0) @ lum).mean()) for n, s in zip(names, [mits, file_rr, rr4])},
    "rel_var": [{"renderer": n, "relmse_one_render": v, "ratio_to_mitsuba": r, "ratio_se": se}
                for n, (v, r, se) in zip(names, rows)],
}, indent=1))

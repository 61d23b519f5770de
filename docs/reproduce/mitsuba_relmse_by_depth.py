"""Where warpray's excess noise on Mitsuba's Cornell box comes from: the equal-spp
relMSE of warpray's path tracer against Mitsuba 3's (as docs/reproduce/mitsuba_relmse.py
measures it) with the path depth cut, so that depth 2 is direct light only (emitters
seen, next-event estimation and the BSDF-sampled hits of the light, with MIS) and depth
3 adds one bounce; with FILTER=box the pixel filter is a box instead of the file's
Gaussian, so that no sample is splatted onto a neighbour. Both renderers read the same
edited copy of assets/scenes/mitsuba-cbox.xml. Prints one JSON line per depth: the
ratio of warpray's relative variance to Mitsuba's, with a jackknife error over seeds.

Run from the repository root after `cargo build --release` (pip install mitsuba==3.9.1
numpy):

  python3 docs/reproduce/mitsuba_relmse_by_depth.py 2 3
  FILTER=box python3 docs/reproduce/mitsuba_relmse_by_depth.py 2
"""
import json
import os
import subprocess
import sys
import tempfile

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
SCENE = "assets/scenes/mitsuba-cbox.xml"
SPP, SEEDS, EPS = 64, int(os.environ.get("SEEDS", "16")), 0.01
FILTER = os.environ.get("FILTER", "gaussian")
WARPRAY = os.environ.get("WARPRAY", "target/release/warpray")


def rel_var(stack, mean):
    var = stack.var(axis=0, ddof=1).sum(axis=-1)
    return float((var / ((mean ** 2).sum(axis=-1) + EPS)).mean())


def ratio_with_error(mits, war):
    mean = np.concatenate([mits, war]).mean(axis=0)
    full = rel_var(war, mean) / rel_var(mits, mean)
    n = mits.shape[0]
    leave = np.array([rel_var(np.delete(war, i, 0), mean) / rel_var(np.delete(mits, i, 0), mean) for i in range(n)])
    return full, float(np.sqrt((n - 1) / n * ((leave - leave.mean()) ** 2).sum()))


src = open(SCENE).read()
assert '<integer name="max_depth" value="8"/>' in src and '<rfilter type="gaussian"/>' in src
for depth in [int(d) for d in sys.argv[1:]]:
    with tempfile.TemporaryDirectory(dir="assets/scenes") as tmp:
        xml = os.path.join(tmp, "cbox.xml")
        open(xml, "w").write(src.replace('<integer name="max_depth" value="8"/>', f'<integer name="max_depth" value="{depth}"/>')
                             .replace('<rfilter type="gaussian"/>', f'<rfilter type="{FILTER}"/>'))
        scene = mi.load_file(xml)
        mits = np.stack([np.array(mi.render(scene, spp=SPP, seed=s), dtype=np.float64) for s in range(1, SEEDS + 1)])
        war = []
        for s in range(1, SEEDS + 1):
            out = os.path.join(tmp, f"w{s}.exr")
            subprocess.run([WARPRAY, xml, "--spp", str(SPP), "--seed", str(s), "--output", out, "--quiet"],
                           check=True, capture_output=True)
            war.append(np.array(mi.Bitmap(out), dtype=np.float64)[..., :3])
        war = np.stack(war)
    ratio, se = ratio_with_error(mits, war)
    print(json.dumps({"depth": depth, "filter": FILTER, "spp": SPP, "seeds": SEEDS,
                      "mean_mitsuba": float(mits.mean()), "mean_warpray": float(war.mean()),
                      "relvar_ratio_warpray_to_mitsuba": round(ratio, 4), "jackknife_se": round(se, 4)}), flush=True)

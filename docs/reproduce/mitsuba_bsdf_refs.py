"""Renders the one-BSDF scenes of assets/scenes/bsdf/ with Mitsuba 3 and writes the
references that tests/suite/mitsuba_bsdfs.rs compares warpray with:

  tests/data/mitsuba/<scene>.json  per-seed statistics of 16 independent renders
                                   (luminance image mean, then each 8x8 block's mean
                                   per channel, row-major), the same statistics that
                                   tests/suite/seeds.rs computes for warpray
  tests/data/mitsuba/<scene>.exr   the average of the 16 renders, for looking at

Run from the repository root (pip install mitsuba==3.9.1 numpy):

  python3 docs/reproduce/mitsuba_bsdf_refs.py

scalar_rgb is used because llvm_ad_rgb needs Debian's libllvm19.
"""
import json
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

SCENES = ["roughconductor", "conductor", "dielectric", "roughdielectric", "plastic", "roughplastic"]
SEEDS = 16
SPP = 1024
BLOCK = 8
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def stats(img):
    h, w, _ = img.shape
    out = [float((img.astype(np.float64) @ LUMINANCE).mean())]
    for by in range(h // BLOCK):
        for bx in range(w // BLOCK):
            b = img[by * BLOCK:(by + 1) * BLOCK, bx * BLOCK:(bx + 1) * BLOCK].astype(np.float64)
            out.extend(float(v) for v in b.mean(axis=(0, 1)))
    return out


for name in sys.argv[1:] or SCENES:
    scene = mi.load_file(f"assets/scenes/bsdf/{name}.xml")
    images = [np.array(mi.render(scene, spp=SPP, seed=1000 + s)) for s in range(SEEDS)]
    h, w, _ = images[0].shape
    ref = {
        "scene": f"assets/scenes/bsdf/{name}.xml",
        "renderer": f"Mitsuba {mi.__version__}, variant scalar_rgb, integrator from the file",
        "command": "python3 docs/reproduce/mitsuba_bsdf_refs.py",
        "spp_per_seed": SPP,
        "seeds": [1000 + s for s in range(SEEDS)],
        "width": w,
        "height": h,
        "block": BLOCK,
        "per_seed": [stats(img) for img in images],
    }
    with open(f"tests/data/mitsuba/{name}.json", "w") as f:
        json.dump(ref, f, indent=None, separators=(",", ":"))
        f.write("\n")
    mean = np.mean(images, axis=0).astype(np.float32)
    mi.Bitmap(mean).write(f"tests/data/mitsuba/{name}.exr")
    lum = [s[0] for s in ref["per_seed"]]
    print(f"{name}: luminance {np.mean(lum):.5f} +- {np.std(lum, ddof=1) / np.sqrt(SEEDS):.5f}")

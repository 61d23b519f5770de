"""Evaluates Mitsuba 3's `plastic` and `roughplastic` BSDFs at fixed direction pairs
and writes what tests/suite/bsdf_reference.rs compares warpray's plastic with:

  tests/data/mitsuba/plastic_values.json   per material and pair: Mitsuba's eval
                                           (f times the cosine of the sampled
                                           direction), pdf, and for the smooth
                                           plastic its specular sample's probability
                                           and weight

Run from the repository root (pip install mitsuba==3.9.1):

  python3 docs/reproduce/mitsuba_plastic_values.py

Mitsuba's `si.wi` is the direction toward the viewer (warpray's `wo`); its `wo` is
the sampled one (warpray's `wi`).
"""
import json
import math

import mitsuba as mi

mi.set_variant("scalar_rgb")

MATERIALS = {
    "plastic": {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": [0.2, 0.4, 0.7]}},
    "plastic-nonlinear": {
        "type": "plastic",
        "int_ior": 1.3,
        "nonlinear": True,
        "diffuse_reflectance": {"type": "rgb", "value": [0.9, 0.5, 0.1]},
        "specular_reflectance": {"type": "rgb", "value": [0.8, 0.8, 0.6]},
    },
    "roughplastic": {
        "type": "roughplastic",
        "distribution": "ggx",
        "alpha": 0.25,
        "int_ior": 1.6,
        "nonlinear": True,
        "diffuse_reflectance": {"type": "rgb", "value": [0.7, 0.3, 0.1]},
    },
    "roughplastic-wide": {
        "type": "roughplastic",
        "distribution": "ggx",
        "alpha": 0.6,
        "diffuse_reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]},
        "specular_reflectance": {"type": "rgb", "value": [0.8, 0.8, 0.8]},
    },
}


def direction(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


# (toward the viewer, sampled): near-normal, oblique, grazing, near the mirror direction.
PAIRS = [
    (direction(5, 0), direction(10, 90)),
    (direction(30, 0), direction(30, 180)),
    (direction(30, 0), direction(35, 170)),
    (direction(60, 45), direction(20, 200)),
    (direction(75, 0), direction(70, 180)),
    (direction(85, 10), direction(45, 90)),
    (direction(45, 0), direction(80, 30)),
]

out = {"renderer": f"Mitsuba {mi.__version__}, variant scalar_rgb", "command":
       "python3 docs/reproduce/mitsuba_plastic_values.py", "materials": {}}
ctx = mi.BSDFContext()
for name, spec in MATERIALS.items():
    bsdf = mi.load_dict(spec)
    rows = []
    for wo, wi in PAIRS:
        si = mi.SurfaceInteraction3f()
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        si.wi = mi.Vector3f(wo)
        value = bsdf.eval(ctx, si, mi.Vector3f(wi))
        row = {"wo": wo, "wi": wi, "eval": [float(value[k]) for k in range(3)],
               "pdf": float(bsdf.pdf(ctx, si, mi.Vector3f(wi)))}
        if spec["type"] == "plastic":
            bs, weight = bsdf.sample(ctx, si, 0.0, mi.Point2f(0.5, 0.5))
            row["specular_pdf"] = float(bs.pdf)
            row["specular_weight"] = [float(weight[k]) for k in range(3)]
        rows.append(row)
    out["materials"][name] = {"spec": spec, "pairs": rows}

with open("tests/data/mitsuba/plastic_values.json", "w") as f:
    json.dump(out, f, indent=1)
    f.write("\n")
print(json.dumps(out["materials"]["roughplastic"]["pairs"][1]))

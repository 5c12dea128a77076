#!/usr/bin/env python3
"""An independent estimate of reference-scenes/volumetric-caustic's image mean.

The scene's file (pbrt-v4 format) is read for its geometry and rebuilt in Mitsuba 3
(`llvm_ad_rgb`, `volpath`): the same walls, glass sphere, 5x4 mm light, homogeneous gas
(sigma_s = 1, sigma_a = 0) behind the interface front wall, the same camera (19.5 degrees,
from (0, 1, 7)) and max depth (pbrt's maxdepth 7 is Mitsuba's max_depth 8). Prints each
run's channel means and their average, to hold against Kiln's estimate and pbrt-v4's single
1.054 0.737 0.252 (reference-scenes/README.md).

Usage: python3 volumetric_caustic.py [--res 32] [--spp 4096] [--runs 4] [--sigma-s 1]
"""
import argparse
import os
import re
import sys
import tempfile

SCENE = "/work/shared/reference-scenes/volumetric-caustic/scene.pbrt"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, default=32)
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--sigma-s", type=float, default=1.0, help="the gas's scattering coefficient")
    args = ap.parse_args()
    if not os.path.exists(SCENE):
        print(f"SKIPPED: {SCENE} is absent")
        return
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    text = open(SCENE).read()
    # The meshes in file order, with the material named before each and the medium
    # interface in effect.
    tokens = re.findall(r'"[^"]*"|\[|\]|[^\s\[\]"]+', text)
    meshes, material, interface, stack = [], None, ("", ""), []
    i = 0
    while i < len(tokens):
        t = tokens[i]
        if t == "AttributeBegin":
            stack.append(interface)
        elif t == "AttributeEnd":
            interface = stack.pop()
        elif t == "NamedMaterial":
            material = tokens[i + 1].strip('"')
        elif t == "MediumInterface":
            interface = (tokens[i + 1].strip('"'), tokens[i + 2].strip('"'))
        elif t == '"point3 P"':
            j = tokens.index("]", i + 2)
            p = [float(v) for v in tokens[i + 2 : j]]
            k = tokens.index('"integer indices"', j)
            e = tokens.index("]", k + 2)
            idx = [int(v) for v in tokens[k + 2 : e]]
            meshes.append((material, interface, p, idx))
        i += 1
    radiance = [541126.75, 381971.8, 127323.94]
    tmp = tempfile.mkdtemp()
    gas = {"type": "homogeneous", "albedo": 1.0, "sigma_t": args.sigma_s, "scale": 1.0}
    scene = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": 8},
        "sensor": {
            "type": "perspective",
            "fov": 19.5,
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[0, 1, 7], target=[0, 1, 0], up=[0, 1, 0]
            ),
            "film": {
                "type": "hdrfilm",
                "width": args.res,
                "height": args.res,
                "rfilter": {"type": "tent"},
            },
            "sampler": {"type": "independent", "sample_count": args.spp},
        },
        "gas": gas,
        "sphere": {
            "type": "sphere",
            "center": [-0.22827, 1.2, 0.152505],
            "radius": 0.3,
            "bsdf": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0},
            "exterior": {"type": "ref", "id": "gas"},
        },
    }
    colours = {
        "LeftWall": [0.63, 0.065, 0.05],
        "RightWall": [0.14, 0.45, 0.091],
        "Floor": [0.725, 0.71, 0.68],
        "Ceiling": [0.725, 0.71, 0.68],
        "BackWall": [0.725, 0.71, 0.68],
        "Light": [0.0, 0.0, 0.0],
    }
    for n, (material, interface, p, idx) in enumerate(meshes):
        path = os.path.join(tmp, f"m{n}.obj")
        with open(path, "w") as f:
            for v in range(0, len(p), 3):
                f.write(f"v {p[v]} {p[v + 1]} {p[v + 2]}\n")
            for t in range(0, len(idx), 3):
                f.write(f"f {idx[t] + 1} {idx[t + 1] + 1} {idx[t + 2] + 1}\n")
        shape = {"type": "obj", "filename": path, "face_normals": True}
        if material == "FrontWall":
            # The interface: gas inside (behind its +z normal), vacuum where the camera is.
            shape["bsdf"] = {"type": "null"}
            shape["interior"] = {"type": "ref", "id": "gas"}
        else:
            # pbrt's diffuse reflects on both sides; Mitsuba's on the normal's side only (and
            # some walls' normals point out of the box).
            shape["bsdf"] = {
                "type": "twosided",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": colours[material]}},
            }
            # Gas on both sides: the path stays in the gas whichever way it leaves.
            shape["interior"] = {"type": "ref", "id": "gas"}
            shape["exterior"] = {"type": "ref", "id": "gas"}
        if material == "Light":
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": radiance}}
        scene[f"mesh{n}"] = shape
    s = mi.load_dict(scene)
    import numpy as np

    # The 5x4 mm light covers a sliver of one pixel, which camera samples hit or miss whole
    # (each hit moves the mean by L / (spp * pixels)): the block of pixels around it is left
    # out of the "masked" mean (rows 1-5, columns 13-18 of 32x32: both image orientations).
    res = args.res
    mask = np.ones((res, res), bool)
    r0, r1 = res * 1 // 32, res * 6 // 32
    c0, c1 = res * 13 // 32, res * 19 // 32
    mask[r0:r1, c0:c1] = False
    full, masked = [], []
    for run in range(args.runs):
        img = np.array(mi.render(s, seed=run + 1), dtype=np.float64)[..., :3]
        full.append(img.mean(axis=(0, 1)))
        masked.append(img[mask].mean(axis=0))
        f, m = full[-1], masked[-1]
        print(f"run {run + 1}: mean {f[0]:.5f} {f[1]:.5f} {f[2]:.5f} masked {m[0]:.5f} {m[1]:.5f} {m[2]:.5f}", flush=True)
    for name, values in (("mean", full), ("masked mean", masked)):
        v = np.array(values)
        avg = v.mean(axis=0)
        se = v.std(axis=0, ddof=1) / np.sqrt(len(v)) if len(v) > 1 else np.zeros(3)
        print(
            f"{name} over {len(v)} runs ({res}x{res}, {args.spp} spp each): "
            f"{avg[0]:.5f} {avg[1]:.5f} {avg[2]:.5f} (standard error {se[0]:.5f} {se[1]:.5f} {se[2]:.5f})"
        )


if __name__ == "__main__":
    sys.exit(main())

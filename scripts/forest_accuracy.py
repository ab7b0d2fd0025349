#!/usr/bin/env python3
"""Accuracy of the forest hierarchy (docs/forest.md): a small forest relit from base solutions,
(a) with each instance's local light only and (b) scaled by the coarse forest factors, compared
node by node with a full static bake of the whole forest as one fine lattice (the same LB model,
no hierarchy). Prints the table, writes results.csv and a picture (PNG, top view of the light
averaged down each occupied column) into the output folder.

    scripts/forest_accuracy.py --lblight build/lblight --out docs/forest [--elevations 20 45 70]

Needs /usr/bin/python3 with pyopenvdb and numpy (Debian: python3-openvdb, python3-numpy).
"""
import argparse
import csv
import json
import math
import os
import struct
import subprocess
import sys
import time
import zlib

import numpy as np
import pyopenvdb as vdb

H = 0.125  # world voxel edge of both models


def run(cmd, cwd):
    t = time.time()
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stdout}\n{p.stderr}")
    return time.time() - t, p.stdout


def models():
    return [
        {"name": "tree", "density": {"type": "procedural", "shape": "plant", "resolution": 40, "seed": 7, "size": 40 * H},
         "material": "leaf", "wood_material": "bark"},
        {"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 32, "seed": 3, "size": 32 * H},
         "material": "leaf", "wood_material": "bark"},
    ]


def instances(offsets):
    # Two rows of four, canopies overlapping; quarter turns land on the world grid exactly
    # (position = H n - R offset), the 30 and 135 degree ones are resampled.
    out = []
    layout = [("tree", 0, 0, 0), ("shrub", 3.5, 0.4, 90), ("tree", 7.0, -0.3, 180), ("shrub", 10.5, 0.2, 30),
              ("shrub", 0.3, 3.6, 270), ("tree", 3.8, 3.4, 135), ("shrub", 7.2, 3.7, 0), ("tree", 10.4, 3.5, 90)]
    for model, x, y, yaw in layout:
        ox, oy, oz = offsets[model]
        c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
        if yaw % 90 == 0:
            c, s = round(c), round(s)
        rx, ry = c * ox - s * oy, s * ox + c * oy
        px = H * round((x + rx) / H) - rx
        py = H * round((y + ry) / H) - ry
        pz = -oz
        out.append({"model": model, "position": [px, py, pz], "yaw_degrees": yaw})
    return out


def with_ground(scene, albedo):
    # every model's base voxels sit at z = 0 (instances at -oz), so the ground is right under them
    if albedo >= 0:
        scene["ground"] = {"albedo": albedo, "height": 0}
    return scene


def scene_base(offsets, cell):
    return {"version": 1, "name": "small-forest", "models": models(),
            "lighting": {"mode": "base", "solutions": "auto", "sun_range": {"min_elevation": 0, "max_elevation": 90},
                         "instance_rotation": "yaw"},
            "solver": {"iterations": "auto", "tolerance": 1e-4},
            "forest": {"instances": instances(offsets), "coarse": {"cell_size": cell * H}}}


def scene_full(density_vdb, elevation, azimuth, ambient):
    return {"version": 1, "name": "small-forest-full",
            "models": [{"name": "full", "density": {"type": "vdb", "path": density_vdb, "grid": "density", "wood_grid": "brown"},
                        "material": "leaf", "wood_material": "bark"}],
            "lighting": {"mode": "static", "sun": {"elevation": elevation, "azimuth": azimuth}, "intensity": 1.0,
                         "ambient": ambient},
            "solver": {"iterations": "auto", "tolerance": 1e-4}}


def dense(grid, bbox):
    lo, hi = bbox
    shape = tuple(hi[a] - lo[a] + 1 for a in range(3))
    if grid.valueTypeName == "vec3s":
        arr = np.zeros(shape + (3,), dtype=np.float32)
    else:
        arr = np.zeros(shape, dtype=np.float32)
    grid.copyToArray(arr, ijk=lo)
    return arr


def png(path, rgb):
    h, w, _ = rgb.shape
    raw = b"".join(b"\0" + rgb[y].astype(np.uint8).tobytes() for y in range(h))
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def colour(v):
    # black - red - yellow - white ramp for v in [0, 1]
    v = np.clip(v, 0, 1)
    return np.stack([np.clip(3 * v, 0, 1), np.clip(3 * v - 1, 0, 1), np.clip(3 * v - 2, 0, 1)], axis=-1) * 255


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lblight", default="build/lblight")
    ap.add_argument("--out", default="docs/forest")
    ap.add_argument("--work", default="/tmp/lblight-forest-accuracy")
    ap.add_argument("--elevations", type=float, nargs="+", default=[20, 45, 70])
    ap.add_argument("--azimuth", type=float, default=200)
    ap.add_argument("--ambient", type=float, default=0.02)
    ap.add_argument("--cell", type=float, default=2, help="coarse cell edge in model voxels")
    ap.add_argument("--albedo", type=float, default=0.15, help="ground albedo (negative: no ground)")
    ap.add_argument("--suffix", default="", help="appended to results.csv and accuracy.png")
    a = ap.parse_args()
    lb = os.path.abspath(a.lblight)
    os.makedirs(a.work, exist_ok=True)
    os.makedirs(a.out, exist_ok=True)
    # The models' frames first: where their voxel centres sit, to put quarter turns on the grid.
    probe = {"version": 1, "models": models(), "lighting": {"mode": "base", "solutions": "0"}}
    json.dump(probe, open(os.path.join(a.work, "probe.json"), "w"))
    _, out = run([lb, "validate", "probe.json", "--json"], a.work)
    offsets = {}
    for m in json.loads(out)["models"]:
        t = m["lattice"]["index_to_world"]
        offsets[m["name"]] = (t[3], t[7], t[11])
    json.dump(with_ground(scene_base(offsets, a.cell), a.albedo), open(os.path.join(a.work, "forest.json"), "w"), indent=1)
    base_seconds, _ = run([lb, "-q", "bake", "forest.json", "-o", "bake", "--backend", "cpu"], a.work)
    manifest = json.load(open(os.path.join(a.work, "bake", "manifest.json")))
    seconds = {m["name"]: sum(s["seconds"] for s in m["solutions"]) for m in manifest["models"]}
    fine = sum(v for k, v in seconds.items() if not k.startswith("forest"))
    coarse = sum(v for k, v in seconds.items() if k.startswith("forest"))
    rows = []
    pictures = []
    for e in a.elevations:
        tag = f"e{int(e)}"
        common = ["--sun-elevation", str(e), "--sun-azimuth", str(a.azimuth), "--ambient", str(a.ambient)]
        t_local, _ = run([lb, "relight", "bake", *common, "--local", "-o", f"{tag}-local.vdb"], a.work)
        t_coarse, _ = run([lb, "relight", "bake", *common, "-o", f"{tag}-coarse.vdb"], a.work)
        json.dump(with_ground(scene_full(f"{tag}-local.vdb", e, a.azimuth, a.ambient), a.albedo), open(os.path.join(a.work, f"{tag}-full.json"), "w"))
        t_full, _ = run([lb, "-q", "bake", f"{tag}-full.json", "-o", f"{tag}-full", "--backend", "cpu"], a.work)
        full_manifest = json.load(open(os.path.join(a.work, f"{tag}-full", "manifest.json")))
        full_solve = sum(s["seconds"] for s in full_manifest["models"][0]["solutions"])
        ref_light = vdb.read(os.path.join(a.work, f"{tag}-full", "full.vdb"), "light")
        ref_density = vdb.read(os.path.join(a.work, f"{tag}-full", "full.vdb"), "density")
        bbox = ref_density.evalActiveVoxelBoundingBox()
        ref = dense(ref_light, bbox)
        rho = dense(ref_density, bbox)
        occ = rho > 0
        result = {"elevation": e}
        tops = {}
        for route, file in (("local", f"{tag}-local.vdb"), ("coarse", f"{tag}-coarse.vdb")):
            got = dense(vdb.read(os.path.join(a.work, file), "light"), bbox)
            diff = (got - ref)[occ]
            result[f"{route}_l2"] = float(np.sqrt((diff ** 2).sum() / (ref[occ] ** 2).sum()))
            result[f"{route}_max"] = float(np.abs(diff).max() / np.abs(ref[occ]).max())
            result[f"{route}_bias"] = float(got[occ].sum() / ref[occ].sum() - 1)
            tops[route] = got
        tops["full"] = ref
        result.update({"full_bake_s": t_full, "full_solve_s": full_solve, "relight_local_s": t_local,
                       "relight_coarse_s": t_coarse})
        rows.append(result)
        # Top view: the green light averaged down each column over its occupied voxels.
        n = occ.sum(axis=2)
        scale = None
        panels = []
        for route in ("full", "local", "coarse"):
            g = (tops[route][..., 1] * occ).sum(axis=2) / np.maximum(n, 1)
            if scale is None:
                scale = np.percentile(g[n > 0], 99)
            img = colour(g / scale)
            img[n == 0] = 40
            panels.append(np.transpose(img, (1, 0, 2))[::-1])
        gap = np.full((panels[0].shape[0], 6, 3), 255)
        pictures.append(np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1))
    sheet = np.concatenate([np.vstack([p, np.full((6, p.shape[1], 3), 255)]) for p in pictures])
    png(os.path.join(a.out, f"accuracy{a.suffix}.png"), sheet.repeat(3, axis=0).repeat(3, axis=1))
    with open(os.path.join(a.out, f"results{a.suffix}.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print(f"base solutions: fine models {fine:.2f} s, coarse lattices {coarse:.2f} s (bake wall {base_seconds:.2f} s)")
    print("| sun elevation | (a) local: L2 / max / bias | (b) local x coarse: L2 / max / bias | full bake s | relight s (a / b) |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['elevation']:.0f} | {r['local_l2']:.3f} / {r['local_max']:.3f} / {r['local_bias']:+.3f} | "
              f"{r['coarse_l2']:.3f} / {r['coarse_max']:.3f} / {r['coarse_bias']:+.3f} | {r['full_bake_s']:.2f} "
              f"(solve {r['full_solve_s']:.2f}) | {r['relight_local_s']:.2f} / {r['relight_coarse_s']:.2f} |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Independent check of `lblight bake`: writes a density VDB with pyopenvdb, bakes it with fixed
step counts, reopens the output with OpenVDB's own Python reader and compares every stored total
with lb_reference.py (NumPy, float64). Exit 77 (skipped) without pyopenvdb.
usage: check_bake.py LBLIGHT_EXE"""
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

try:
    import pyopenvdb as vdb
except ImportError:
    print("SKIPPED: pyopenvdb (Debian python3-openvdb) not available")
    sys.exit(77)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lb_reference as ref  # noqa: E402

LEAF = dict(sigma_a=[0.109, 0.091, 0.118], sigma_s=[0.891, 0.909, 0.882], g=[-0.12, 0.0909, -0.3333])


def main():
    exe = os.path.abspath(sys.argv[1])
    rng = np.random.default_rng(4)
    nx, ny, nz = 11, 9, 8  # density grid; lattice adds a margin of 1
    dens = rng.uniform(0.05, 0.95, size=(nx, ny, nz)).astype(np.float32)  # pyopenvdb arrays are [x, y, z]
    wood = (rng.uniform(size=(nx, ny, nz)) < 0.2).astype(np.float32)
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        dg = vdb.FloatGrid()
        dg.copyFromArray(dens, ijk=(3, -2, 5))
        dg.name = "density"
        dg.transform = vdb.createLinearTransform(voxelSize=0.25)
        wg = vdb.FloatGrid()
        wg.copyFromArray(wood, ijk=(3, -2, 5))
        wg.name = "brown"
        wg.transform = vdb.createLinearTransform(voxelSize=0.25)
        vdb.write(os.path.join(tmp, "in.vdb"), grids=[dg, wg])
        cases = [
            ("leafy", {"preset": "leaf", "sigma_a": LEAF["sigma_a"], "sigma_s": LEAF["sigma_s"], "g": LEAF["g"]},
             {"sigma_a": LEAF["sigma_a"], "sigma_s": LEAF["sigma_s"], "g": -1, "absorb": False}, "brown"),
            ("cloud", {"sigma_a": 0.008, "sigma_s": 0.792, "g": 0.9, "absorb": False}, None, None),
        ]
        for name, mat, wood_mat, wood_grid in cases:
            density = {"type": "vdb", "path": "in.vdb", "grid": "density"}
            if wood_grid:
                density["wood_grid"] = wood_grid
            model = {"name": name, "density": density, "material": mat}
            if wood_mat:
                model["wood_material"] = wood_mat
            scene = {"version": 1, "models": [model], "lighting": {"mode": "base", "solutions": "0,1,8,13"},
                     "solver": {"iterations": 30, "model": "paper"}, "output": {"full_box": True}}
            with open(os.path.join(tmp, name + ".json"), "w") as f:
                json.dump(scene, f)
            out = os.path.join(tmp, "out-" + name)
            subprocess.run([exe, "bake", name + ".json", "-o", out, "--backend", "cpu", "-q"], cwd=tmp, check=True)
            manifest = json.load(open(os.path.join(out, "manifest.json")))
            lat = manifest["models"][0]["lattice"]
            lo = lat["index_min"]
            dims = lat["dims"]
            assert lo == [2, -3, 4] and dims == [nx + 2, ny + 2, nz + 2], (lo, dims)
            # lattice arrays [z, y, x] for the reference
            density_l = np.zeros((nz + 2, ny + 2, nx + 2))
            density_l[1:-1, 1:-1, 1:-1] = np.transpose(dens, (2, 1, 0))
            material_l = np.zeros(density_l.shape, dtype=np.int64)
            if wood_grid:
                material_l[1:-1, 1:-1, 1:-1] = np.transpose(wood, (2, 1, 0)) > 0.5
            for j in (0, 1, 8, 13):
                g = vdb.read(os.path.join(out, name + ".vdb"), "B%02d" % j)
                assert abs(g.transform.voxelSize()[0] - 0.25) < 1e-12
                got = np.zeros((dims[0], dims[1], dims[2], 3), dtype=np.float32)
                g.copyToArray(got, ijk=tuple(lo))
                for c in range(3):
                    if name == "cloud":
                        oms, absorbs = [ref.omega(0.008, 0.792, 0.9)], [False]
                    else:
                        oms = [ref.omega(LEAF["sigma_a"][c], LEAF["sigma_s"][c], LEAF["g"][c]),
                               ref.omega(LEAF["sigma_a"][c], LEAF["sigma_s"][c], -1.0)]
                        absorbs = [True, False]
                    want = ref.solve(density_l, material_l, oms, absorbs, ref.base_boundary(j), 30)
                    have = np.transpose(got[..., c], (2, 1, 0)).astype(np.float64)
                    floor = 1e-3 * np.abs(want).max()
                    rel = np.abs(have - want) / np.maximum(np.abs(want), floor)
                    if not np.isfinite(have).all() or not rel.max() <= worst:  # NaN wins (max() would drop it)
                        worst = float("inf") if not np.isfinite(have).all() else rel.max()
                    print("%s B%02d channel %d: max relative difference %.2e" % (name, j, c, rel.max()))
    print("worst relative difference: %.2e (limit 1e-5)" % worst)
    return 0 if worst < 1e-5 else 1


if __name__ == "__main__":
    sys.exit(main())

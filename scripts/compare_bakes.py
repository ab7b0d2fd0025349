#!/usr/bin/python3
"""Compares the base-solution grids of two lblight bakes (e.g. GPU against CPU): per grid, the
largest difference relative to the reference value, with values below 1e-6 of the grid's largest
counted against that floor (light that small is noise in either bake). Needs pyopenvdb
(Debian python3-openvdb) and NumPy.

usage: scripts/compare_bakes.py REFERENCE_DIR OTHER_DIR [--tolerance T]
Exit 1 when a grid differs by more than T (default 1e-5), 2 on bad input, 77 without pyopenvdb."""
import argparse
import json
import os
import sys

try:
    import numpy as np
    import pyopenvdb as vdb
except ImportError as e:
    print(f"compare_bakes.py: skipped, {e} (Debian: apt-get install python3-openvdb)", file=sys.stderr)
    sys.exit(77)


def dense(path, name, lo, dims):
    g = vdb.read(path, name)
    a = np.zeros(tuple(dims) + (3,), dtype=np.float32)
    g.copyToArray(a, ijk=tuple(lo))
    return a


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("reference")
    ap.add_argument("other")
    ap.add_argument("--tolerance", type=float, default=1e-5)
    args = ap.parse_args()
    manifests = []
    for d in (args.reference, args.other):
        try:
            manifests.append(json.load(open(os.path.join(d, "manifest.json"))))
        except (OSError, ValueError) as e:
            print(f"{d}: not an lblight output ({e})", file=sys.stderr)
            return 2
    worst_all = 0.0
    for model in manifests[0]["models"]:
        other = next((m for m in manifests[1]["models"] if m["name"] == model["name"]), None)
        if other is None or other["lattice"]["dims"] != model["lattice"]["dims"]:
            print(f"model {model['name']}: missing or on another lattice in {args.other}", file=sys.stderr)
            return 2
        lo, dims = model["lattice"]["index_min"], model["lattice"]["dims"]
        for s in model["solutions"]:
            a = dense(os.path.join(args.reference, model["file"]), s["grid"], lo, dims)
            b = dense(os.path.join(args.other, other["file"]), s["grid"], lo, dims)
            floor = max(1e-30, 1e-6 * float(np.abs(a).max()))
            rel = float(np.max(np.abs(b - a) / np.maximum(np.abs(a), floor)))
            worst_all = max(worst_all, rel)
            print(f"{model['name']} {s['grid']}: max relative difference {rel:.3g}")
    verdict = "within" if worst_all <= args.tolerance else "ABOVE"
    print(f"largest: {worst_all:.3g} ({verdict} {args.tolerance:g})")
    return 0 if worst_all <= args.tolerance else 1


if __name__ == "__main__":
    sys.exit(main())

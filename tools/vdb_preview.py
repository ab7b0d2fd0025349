#!/usr/bin/python3
"""Quick looks at lblight volumes as PNG images (Debian's python3-openvdb and python3-numpy).

    /usr/bin/python3 tools/vdb_preview.py tree.vdb --out tree.png
        side view (x right, z up) of a voxelised mesh: density summed along y, green for leaf
        nodes, brown for wood nodes
    /usr/bin/python3 tools/vdb_preview.py out/plant/tree.vdb --grid B06 --slice 0.5 --out b06.png
        a slice through a bake output's base solution at half depth along y (x right, z up),
        grey levels scaled to the slice's maximum; --print prints mean totals per z layer

Use /usr/bin/python3: Debian's Python modules do not load in another python3 earlier on PATH.
"""
import argparse
import struct
import zlib

import numpy as np
import pyopenvdb as vdb


def write_png(path, rgb):
    """rgb: uint8 array (height, width, 3), row 0 at the top."""
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def dense(grid, bbox):
    lo, hi = bbox
    shape = tuple(hi[i] - lo[i] + 1 for i in range(3))
    if isinstance(grid, vdb.Vec3SGrid):
        a = np.zeros(shape + (3,), dtype=np.float32)
    else:
        a = np.zeros(shape, dtype=np.float32)
    grid.copyToArray(a, ijk=lo)
    return a  # indexed [x, y, z]


def frame(grid):
    meta = grid.metadata
    if "lblight_lattice_min" in meta and "lblight_lattice_dims" in meta:
        lo = tuple(meta["lblight_lattice_min"])
        d = meta["lblight_lattice_dims"]
        return lo, (lo[0] + d[0] - 1, lo[1] + d[1] - 1, lo[2] + d[2] - 1)
    return grid.evalActiveVoxelBoundingBox()


def upscale(img, scale):
    return np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("--grid", default="density", help="density (mesh side view) or a solution grid such as B06")
    ap.add_argument("--slice", type=float, default=0.5, help="solution grids: slice position along y in 0..1")
    ap.add_argument("--scale", type=int, default=3, help="pixels per voxel")
    ap.add_argument("--print", action="store_true", help="solution grids: print mean total per z layer")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()

    g = vdb.read(a.file, a.grid)
    bbox = frame(g)
    if a.grid == "density":
        d = dense(g, bbox)
        try:
            brown = dense(vdb.read(a.file, "brown"), bbox) > 0.5
        except Exception:
            brown = np.zeros_like(d, dtype=bool)
        leaf = np.where(brown, 0, d).sum(axis=1)  # along y -> [x, z]
        wood = np.where(brown, d, 0).sum(axis=1)
        leaf = 1 - np.exp(-leaf * 1.5)
        wood = 1 - np.exp(-wood * 3.0)
        rgb = np.ones(leaf.shape + (3,))
        for c, (lc, wc) in enumerate(zip((0.15, 0.55, 0.1), (0.45, 0.25, 0.08))):
            rgb[..., c] = (1 - leaf) * (1 - wood) + leaf * (1 - wood) * lc + wood * wc
        img = (np.clip(rgb, 0, 1) * 255).astype(np.uint8)
    else:
        d = dense(g, bbox)
        if d.ndim == 4:
            d = d.mean(axis=3)
        j = min(d.shape[1] - 1, max(0, int(round(a.slice * (d.shape[1] - 1)))))
        s = d[:, j, :]  # [x, z]
        if a.print:
            for k in range(s.shape[1] - 1, -1, -1):
                print("z %3d  mean %.4f  min %.4f  max %.4f" % (k, s[:, k].mean(), s[:, k].min(), s[:, k].max()))
        v = np.clip(s / max(float(s.max()), 1e-30), 0, 1)
        img = (np.stack([v, v, v], axis=-1) * 255).astype(np.uint8)
    img = np.ascontiguousarray(np.transpose(img, (1, 0, 2))[::-1])  # rows = z from the top, columns = x
    write_png(a.out, upscale(img, a.scale))
    print("wrote %s (%dx%d)" % (a.out, img.shape[1] * a.scale, img.shape[0] * a.scale))


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Where the bytes of an .lbh stream go: sub-blocks by kind, for one relative threshold.

    /usr/bin/python3 scripts/lbh_block_classes.py MODEL.vdb [REL_THRESHOLD] [--replace-boundary]

Reads the Vec3f grids (B00..B18 or light) and `density` of a bake's .vdb (Debian's
python3-openvdb and python3-numpy), re-implements the encoder of docs/lbh-format.md sec. 3 in
float64 (the ratio matches `lblight compress` to rounding) and splits the 3^3 sub-blocks into:
occupied (a node of the 4^3 block has density > 0), empty blocks touching the lattice's outer
layer (the fixed boundary), and empty interior blocks. Prints each class's share of the blocks and
of the stream bytes and its ratio (27 nodes per block, approximate at the far faces), summed over
all grids. --replace-boundary also reports the ratio with the outer layer replaced by its inner
neighbour (how much the boundary's jump costs).
"""
import sys

import numpy as np
import pyopenvdb as vdb


def dense(grid, dims, index_min, vec):
    a = np.zeros(tuple(dims) + ((3,) if vec else ()), dtype=np.float32)
    grid.copyToArray(a, ijk=tuple(index_min))
    return a


def haar_axis(x, axis):
    x = np.moveaxis(x, axis, -1)
    s0, s1 = (x[..., 0] + x[..., 1]) / 2, (x[..., 2] + x[..., 3]) / 2
    d0, d1 = (x[..., 0] - x[..., 1]) / 2, (x[..., 2] - x[..., 3]) / 2
    return np.moveaxis(np.stack([(s0 + s1) / 2, (s0 - s1) / 2, d0, d1], -1), -1, axis)


def main(argv):
    args = [a for a in argv[1:] if not a.startswith("--")]
    if not args:
        print(__doc__)
        return 2
    path, rel = args[0], float(args[1]) if len(args) > 1 else 0.01
    names = sorted(g.name for g in vdb.readAllGridMetadata(path)
                   if g.name == "light" or (g.name.startswith("B") and g.name[1:].isdigit()))
    first = vdb.read(path, names[0])
    index_min, dims = first.metadata["lblight_lattice_min"], first.metadata["lblight_lattice_dims"]
    nb = [max(1, -(-(n - 1) // 3)) for n in dims]
    idx = [np.minimum(3 * np.arange(b)[:, None] + np.arange(4)[None, :], n - 1) for b, n in zip(nb, dims)]

    def blocks(a):  # (nx, ny, nz, ...) -> (bx, by, bz, 4, 4, 4, ...)
        return a[idx[0][:, None, None, :, None, None], idx[1][None, :, None, None, :, None],
                 idx[2][None, None, :, None, None, :]]

    def kept(a, t):  # coefficients kept per block (docs/lbh-format.md sec. 3.3)
        b = blocks(a).astype(np.float64)
        for ax in (5, 4, 3):  # z, then y, then x
            b = haar_axis(b, ax)
        keep = (np.abs(b) >= t).any(-1) & ~(b == 0).all(-1)
        keep[..., 0, 0, 0] = True
        return keep.reshape(keep.shape[:3] + (-1,)).sum(-1)

    occupied = (blocks(dense(vdb.read(path, "density"), dims, index_min, False)) > 0).reshape(
        tuple(nb) + (-1,)).any(-1)
    b = np.meshgrid(*[np.arange(n) for n in nb], indexing="ij")
    boundary = np.zeros(occupied.shape, bool)
    for ax in range(3):
        boundary |= (b[ax] == 0) | (3 * b[ax] + 3 >= dims[ax] - 1)
    classes = {"occupied": occupied, "empty, touching the outer layer": boundary & ~occupied,
               "empty interior": ~boundary & ~occupied}
    stream = dict.fromkeys(classes, 0)
    replaced = 0
    for name in names:
        a = dense(vdb.read(path, name), dims, index_min, True)
        t = np.float32(rel * np.abs(a).max())
        k = kept(a, t)
        for c, m in classes.items():
            stream[c] += 12 * (m.sum() + k[m].sum())
        if "--replace-boundary" in argv:
            a[0], a[-1], a[:, 0], a[:, -1], a[:, :, 0], a[:, :, -1] = (
                a[1], a[-2], a[:, 1], a[:, -2], a[:, :, 1], a[:, :, -2])
            replaced += 12 * (k.size + kept(a, t).sum())
    raw = 12 * int(np.prod(dims)) * len(names)
    total = sum(stream.values())
    print(f"{path}: {len(names)} grids, lattice {tuple(dims)}, {int(np.prod(nb))} blocks, "
          f"threshold {rel:g} relative: ratio {raw / total:.2f}:1")
    if replaced:
        print(f"  outer layer replaced by its neighbour: {raw / replaced:.2f}:1")
    print("| blocks | share of blocks | share of stream bytes | ratio within the class |")
    print("|---|---|---|---|")
    for c, m in classes.items():
        print(f"| {c} | {100 * m.mean():.1f}% | {100 * stream[c] / total:.1f}% | "
              f"{27 * 12 * m.sum() * len(names) / stream[c]:.2f}:1 |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

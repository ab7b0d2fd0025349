#!/usr/bin/env python3
"""Procedural plant meshes for lblight's example scenes: a broadleaf tree or a dogrose-like bush.

Writes a Wavefront OBJ (+ .mtl) with two materials, `bark` (trunk, branches, twigs as tapered
tubes) and `leaves` (leaf blades as slightly folded quads), in metres with +z up and the base of
the plant at the origin. Python 3 standard library only; the output is byte-identical for the
same arguments (random.Random with a fixed seed, fixed number formatting).

    python3 tools/make_tree_obj.py --kind tree --out configs/meshes/tree.obj
    python3 tools/make_tree_obj.py --kind bush --out configs/meshes/bush.obj

Own work of the lblight project, same licence as the project (configs/meshes/README.md).
"""
import argparse
import math
import os
import random

from vec3 import add, cross, dot, mul, norm, sub  # tools/vec3.py


def rotate(v, axis, angle):
    """Rodrigues' rotation of v about the unit axis."""
    c, s = math.cos(angle), math.sin(angle)
    return add(add(mul(v, c), mul(cross(axis, v), s)), mul(axis, dot(axis, v) * (1 - c)))


def perpendicular(d):
    """A unit vector perpendicular to d."""
    helper = (1.0, 0.0, 0.0) if abs(d[0]) < 0.9 else (0.0, 1.0, 0.0)
    return norm(cross(d, helper))


# --------------------------------------------------------------------------------------------
# plant descriptions

KINDS = {
    # A broadleaf tree about 5 m tall with a rounded crown.
    "tree": dict(
        stems=1, stem_length=3.2, stem_radius=0.15, stem_lean=0.04, stem_spread=0.0,
        levels=3,                                   # trunk -> branches -> sub-branches -> twigs
        children=(13, 6, 5), child_start=(0.30, 0.15, 0.20),
        child_angle=(0.95, 0.75, 0.70),             # radians from the parent direction
        length_ratio=(0.62, 0.52, 0.50), radius_ratio=(0.55, 0.55, 0.55),
        uplift=(0.10, 0.05, 0.00),                  # bend towards +z per segment
        sides=(10, 7, 5, 4), segments=(12, 8, 5, 3),
        leaf_levels=(2, 3), leaves_per_metre=(24, 60),
        leaf_length=0.13, leaf_width=0.065, leaf_stalk=0.02,
    ),
    # A dogrose-like shrub about 1.6 m tall: arching canes from the ground, small leaflets.
    "bush": dict(
        stems=7, stem_length=1.5, stem_radius=0.014, stem_lean=0.55, stem_spread=0.12,
        levels=2,
        children=(9, 4), child_start=(0.15, 0.2),
        child_angle=(0.9, 0.8),
        length_ratio=(0.45, 0.5), radius_ratio=(0.6, 0.6),
        uplift=(-0.06, -0.02),                      # canes arch over
        sides=(6, 5, 4), segments=(10, 5, 3),
        leaf_levels=(1, 2), leaves_per_metre=(40, 90),
        leaf_length=0.055, leaf_width=0.03, leaf_stalk=0.01,
    ),
}


class Mesh:
    def __init__(self):
        self.vertices = []
        self.bark = []    # faces (tuples of 1-based vertex indices)
        self.leaves = []

    def vertex(self, p):
        self.vertices.append(p)
        return len(self.vertices)


def tube(mesh, path, radii, sides):
    """Tapered tube along `path` (list of points) with parallel-transported rings; quads."""
    d0 = norm(sub(path[1], path[0]))
    u = perpendicular(d0)
    rings = []
    for i, p in enumerate(path):
        if i == 0:
            d = d0
        elif i == len(path) - 1:
            d = norm(sub(path[i], path[i - 1]))
        else:
            d = norm(sub(path[i + 1], path[i - 1]))
        u = norm(sub(u, mul(d, dot(u, d))))  # parallel transport: keep u perpendicular to d
        v = cross(d, u)
        ring = []
        for k in range(sides):
            a = 2 * math.pi * k / sides
            ring.append(mesh.vertex(add(p, add(mul(u, radii[i] * math.cos(a)), mul(v, radii[i] * math.sin(a))))))
        rings.append(ring)
    for i in range(len(rings) - 1):
        a, b = rings[i], rings[i + 1]
        for k in range(sides):
            k1 = (k + 1) % sides
            mesh.bark.append((a[k], a[k1], b[k1], b[k]))  # outward facing
    tip = mesh.vertex(add(path[-1], mul(norm(sub(path[-1], path[-2])), radii[-1])))
    last = rings[-1]
    for k in range(sides):
        mesh.bark.append((last[k], last[(k + 1) % sides], tip))


def leaf(mesh, rng, base, along, spec):
    """One leaf blade: a diamond quad folded slightly along its midrib, on a short stalk."""
    side = perpendicular(along)
    side = rotate(side, along, rng.uniform(0, 2 * math.pi))
    # Leaves turn their faces roughly upward: tilt the blade direction outward and sideways.
    direction = norm(add(rotate(along, side, rng.uniform(0.6, 1.2)), (0.0, 0.0, rng.uniform(0.0, 0.5))))
    normal = norm(cross(direction, side))
    if normal[2] < 0:
        side = mul(side, -1.0)
        normal = mul(normal, -1.0)
    length = spec["leaf_length"] * rng.uniform(0.75, 1.2)
    width = spec["leaf_width"] * rng.uniform(0.8, 1.2)
    b = add(base, mul(direction, spec["leaf_stalk"]))
    tip = add(b, mul(direction, length))
    mid = add(b, mul(direction, 0.42 * length))
    fold = mul(normal, 0.12 * width)
    left = add(add(mid, mul(side, 0.5 * width)), fold)
    right = add(add(mid, mul(side, -0.5 * width)), fold)
    i = [mesh.vertex(p) for p in (b, right, tip, left)]
    mesh.leaves.append((i[0], i[1], i[2], i[3]))


def branch(mesh, rng, spec, level, start, direction, length, radius):
    segments = spec["segments"][level]
    uplift = spec["uplift"][level] if level < len(spec["uplift"]) else 0.0
    path = [start]
    d = direction
    for s in range(segments):
        wobble = rotate(perpendicular(d), d, rng.uniform(0, 2 * math.pi))
        d = norm(add(rotate(d, wobble, rng.uniform(0.0, 0.12)), (0.0, 0.0, uplift)))
        path.append(add(path[-1], mul(d, length / segments)))
    radii = [radius * (1.0 - 0.75 * i / segments) for i in range(segments + 1)]
    tube(mesh, path, radii, spec["sides"][level])

    def point_at(t):
        x = t * segments
        i = min(int(x), segments - 1)
        f = x - i
        return add(path[i], mul(sub(path[i + 1], path[i]), f)), norm(sub(path[i + 1], path[i])), \
            radii[i] * (1 - f) + radii[i + 1] * f

    if level in spec["leaf_levels"]:
        per_metre = spec["leaves_per_metre"][spec["leaf_levels"].index(level)]
        count = max(1, int(round(per_metre * length)))
        for n in range(count):
            t = 0.25 + 0.75 * (n + rng.random()) / count
            p, along, r = point_at(min(t, 0.999))
            leaf(mesh, rng, p, along, spec)
    if level < spec["levels"]:
        count = spec["children"][level]
        phase = rng.uniform(0, 2 * math.pi)
        for n in range(count):
            t = spec["child_start"][level] + (1 - spec["child_start"][level]) * (n + rng.uniform(0.2, 0.8)) / count
            p, along, r = point_at(t)
            axis = rotate(perpendicular(along), along, phase + n * 2.39996 + rng.uniform(-0.3, 0.3))  # golden angle
            angle = spec["child_angle"][level] * rng.uniform(0.8, 1.15)
            child_dir = rotate(along, axis, angle)
            # Crown shape: children low on a stem are longest, shortening towards the top.
            taper = 1.0 - 0.55 * (t - spec["child_start"][level]) / (1 - spec["child_start"][level]) if level == 0 else 1.0
            child_len = length * spec["length_ratio"][level] * taper * rng.uniform(0.85, 1.15)
            branch(mesh, rng, spec, level + 1, p, child_dir, child_len, r * spec["radius_ratio"][level])


def build(kind, seed):
    spec = KINDS[kind]
    rng = random.Random(seed)
    mesh = Mesh()
    for s in range(spec["stems"]):
        azimuth = 2 * math.pi * s / spec["stems"] + rng.uniform(-0.3, 0.3)
        out = (math.cos(azimuth), math.sin(azimuth), 0.0)
        start = mul(out, spec["stem_spread"] * rng.uniform(0.3, 1.0))
        direction = norm(add((0.0, 0.0, 1.0), mul(out, spec["stem_lean"] * rng.uniform(0.6, 1.2))))
        length = spec["stem_length"] * rng.uniform(0.8, 1.1) if spec["stems"] > 1 else spec["stem_length"]
        branch(mesh, rng, spec, 0, start, direction, length, spec["stem_radius"])
    return mesh


def fmt(x):
    s = "%.4f" % x
    if s.startswith("-0.0000"):
        s = "0.0000"
    s = s.rstrip("0").rstrip(".")
    return s if s not in ("", "-") else "0"


def write(mesh, out_path, kind, seed):
    mtl_name = os.path.splitext(os.path.basename(out_path))[0] + ".mtl"
    mtl_path = os.path.join(os.path.dirname(out_path), mtl_name)
    with open(mtl_path, "w", newline="\n") as f:
        f.write("# lblight example plant materials (tools/make_tree_obj.py)\n")
        f.write("newmtl bark\nKd 0.35 0.25 0.16\n\nnewmtl leaves\nKd 0.20 0.45 0.12\n")
    n_tris = sum(len(face) - 2 for face in mesh.bark + mesh.leaves)
    with open(out_path, "w", newline="\n") as f:
        f.write("# lblight example plant: %s, seed %d, generated by tools/make_tree_obj.py\n" % (kind, seed))
        f.write("# %d vertices, %d bark faces, %d leaf faces, %d triangles; metres, +z up\n"
                % (len(mesh.vertices), len(mesh.bark), len(mesh.leaves), n_tris))
        f.write("# Own work of the lblight project; see configs/meshes/README.md for the licence.\n")
        f.write("mtllib %s\n" % mtl_name)
        for p in mesh.vertices:
            f.write("v %s %s %s\n" % (fmt(p[0]), fmt(p[1]), fmt(p[2])))
        f.write("o %s\ng wood\nusemtl bark\n" % kind)
        for face in mesh.bark:
            f.write("f " + " ".join(str(i) for i in face) + "\n")
        f.write("g foliage\nusemtl leaves\n")
        for face in mesh.leaves:
            f.write("f " + " ".join(str(i) for i in face) + "\n")
    return n_tris


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kind", choices=sorted(KINDS), default="tree")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", required=True, help="output .obj (a .mtl is written beside it)")
    a = ap.parse_args()
    mesh = build(a.kind, a.seed)
    n = write(mesh, a.out, a.kind, a.seed)
    print("%s: %d vertices, %d triangles (%d bark faces, %d leaves), %.2f MB"
          % (a.out, len(mesh.vertices), n, len(mesh.bark), len(mesh.leaves), os.path.getsize(a.out) / 1e6))


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""A closed, teapot-like solid for the PMMA example ([Geist2010] sec. 3.2.3, Table 2).

Three closed, outward-oriented parts that overlap: a body of revolution with a lid and knob, a
curved spout and a handle (tubes with capped ends). `lblight voxelize --fill winding` (or a mesh
source with "fill": "winding") fills their union. Units are decimetres-ish: the body is 1.6 wide.
Python 3 standard library only, deterministic.

    python3 tools/make_teapot_obj.py --out configs/meshes/teapot.obj

Own work of the lblight project, same licence as the project (configs/meshes/README.md).
"""
import argparse
import math
import os


from vec3 import add, cross, dot, mul, norm, sub  # tools/vec3.py


class Part:
    def __init__(self, name):
        self.name, self.vertices, self.faces = name, [], []  # faces index self.vertices (0-based)

    def vertex(self, p):
        self.vertices.append(p)
        return len(self.vertices) - 1

    def signed_volume(self):
        v = 0.0
        for f in self.faces:
            for i in range(1, len(f) - 1):
                a, b, c = self.vertices[f[0]], self.vertices[f[i]], self.vertices[f[i + 1]]
                v += dot(a, cross(b, c)) / 6.0
        return v

    def orient_outward(self):
        if self.signed_volume() < 0:
            self.faces = [tuple(reversed(f)) for f in self.faces]


def revolve(name, profile, segments):
    """Surface of revolution about z of a profile [(r, z)] that starts and ends on the axis."""
    part = Part(name)
    bottom = part.vertex((0.0, 0.0, profile[0][1]))
    top = part.vertex((0.0, 0.0, profile[-1][1]))
    rings = []
    for r, z in profile[1:-1]:
        rings.append([part.vertex((r * math.cos(2 * math.pi * s / segments), r * math.sin(2 * math.pi * s / segments), z))
                      for s in range(segments)])
    for s in range(segments):
        t = (s + 1) % segments
        part.faces.append((bottom, rings[0][t], rings[0][s]))
        for i in range(len(rings) - 1):
            part.faces.append((rings[i][s], rings[i][t], rings[i + 1][t], rings[i + 1][s]))
        part.faces.append((top, rings[-1][s], rings[-1][t]))
    part.orient_outward()
    return part


def tube(name, path, radii, sides):
    """Closed tube: rings along `path` with parallel-transported frames, flat caps at both ends."""
    part = Part(name)
    d = norm(sub(path[1], path[0]))
    u = norm(cross(d, (0.0, 0.0, 1.0) if abs(d[2]) < 0.9 else (1.0, 0.0, 0.0)))
    rings = []
    for i, p in enumerate(path):
        d = norm(sub(path[min(i + 1, len(path) - 1)], path[max(i - 1, 0)]))
        u = norm(sub(u, mul(d, dot(u, d))))
        v = cross(d, u)
        rings.append([part.vertex(add(p, add(mul(u, radii[i] * math.cos(2 * math.pi * k / sides)),
                                             mul(v, radii[i] * math.sin(2 * math.pi * k / sides)))))
                      for k in range(sides)])
    for i in range(len(rings) - 1):
        for k in range(sides):
            k1 = (k + 1) % sides
            part.faces.append((rings[i][k], rings[i][k1], rings[i + 1][k1], rings[i + 1][k]))
    c0, c1 = part.vertex(path[0]), part.vertex(path[-1])
    for k in range(sides):
        k1 = (k + 1) % sides
        part.faces.append((c0, rings[0][k1], rings[0][k]))
        part.faces.append((c1, rings[-1][k], rings[-1][k1]))
    part.orient_outward()
    return part


def build():
    body_profile = [(0.0, 0.0), (0.50, 0.0), (0.62, 0.04), (0.74, 0.15), (0.80, 0.32), (0.79, 0.50), (0.73, 0.66),
                    (0.62, 0.80), (0.50, 0.88), (0.46, 0.90), (0.46, 0.93), (0.38, 0.99), (0.22, 1.05),
                    (0.08, 1.08), (0.07, 1.12), (0.11, 1.17), (0.09, 1.22), (0.0, 1.24)]
    body = revolve("body", body_profile, 64)
    # Spout: from inside the body's lower side out and up along a quadratic curve.
    spout_path = []
    for i in range(17):
        t = i / 16.0
        x = 0.55 + 0.75 * t
        z = 0.30 + 0.75 * t * t + 0.10 * t
        spout_path.append((x, 0.0, z))
    spout = tube("spout", spout_path, [0.16 - 0.09 * i / 16.0 for i in range(17)], 20)
    # Handle: a C-shaped arc on the other side, both ends buried in the body.
    handle_path = []
    for i in range(21):
        a = math.pi * (-0.5 + i / 20.0)
        handle_path.append((-0.62 - 0.38 * math.cos(a), 0.0, 0.52 + 0.30 * math.sin(a)))
    handle = tube("handle", handle_path, [0.06] * 21, 16)
    return [body, spout, handle]


def fmt(x):
    s = ("%.5f" % x).rstrip("0").rstrip(".")
    return "0" if s in ("", "-0") else s


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    parts = build()
    mtl = os.path.splitext(os.path.basename(a.out))[0] + ".mtl"
    with open(os.path.join(os.path.dirname(a.out), mtl), "w", newline="\n") as f:
        f.write("# lblight example PMMA teapot (tools/make_teapot_obj.py)\nnewmtl pmma\nKd 0.9 0.3 0.25\nd 0.6\n")
    tris = 0
    with open(a.out, "w", newline="\n") as f:
        f.write("# lblight example: a closed teapot-like solid of 3 overlapping parts, generated by "
                "tools/make_teapot_obj.py\n# Own work of the lblight project; see configs/meshes/README.md.\n")
        f.write("mtllib %s\n" % mtl)
        base = 1
        for p in parts:
            f.write("o %s\nusemtl pmma\n" % p.name)
            for v in p.vertices:
                f.write("v %s %s %s\n" % (fmt(v[0]), fmt(v[1]), fmt(v[2])))
            for face in p.faces:
                f.write("f " + " ".join(str(base + i) for i in face) + "\n")
                tris += len(face) - 2
            base += len(p.vertices)
    print("%s: %d parts, %d triangles, volumes %s" % (a.out, len(parts), tris,
                                                      ", ".join("%.3f" % p.signed_volume() for p in parts)))


if __name__ == "__main__":
    main()

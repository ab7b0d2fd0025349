#!/usr/bin/env python3
"""Log-log plot of wall time (and steps) against lattice edge R, one line per method, from the CSV
that docs/accuracy.md's "Cost against lattice size" was measured with (scene,R,method,steps,seconds,
estimate,method_used). Usage: plot_scaling.py results.csv scene out.svg"""
import csv, math, sys

rows = [r for r in csv.reader(open(sys.argv[1])) if r[0] == sys.argv[2]]
series = {}
for scene, R, method, steps, seconds, est, used in rows:
    series.setdefault(method, []).append((int(R), float(seconds), int(steps)))
W, H, M = 640, 420, 60
xs = [p[0] for v in series.values() for p in v]
ys = [p[1] for v in series.values() for p in v]
x0, x1 = math.log10(min(xs)), math.log10(max(xs))
y0, y1 = math.floor(math.log10(min(ys))), math.ceil(math.log10(max(ys)))
px = lambda x: M + (math.log10(x) - x0) / (x1 - x0) * (W - 2 * M)
py = lambda y: H - M - (math.log10(y) - y0) / (y1 - y0) * (H - 2 * M)
colours = {"plain": "#d62728", "bicgstab": "#1f77b4", "dsa": "#2ca02c"}
out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
       f'<rect width="{W}" height="{H}" fill="white"/>',
       f'<text x="{W/2}" y="20" text-anchor="middle">{sys.argv[2]}: wall time to 1e-4 (one solution) against lattice edge R</text>']
for e in range(y0, y1 + 1):
    out.append(f'<line x1="{M}" x2="{W-M}" y1="{py(10**e)}" y2="{py(10**e)}" stroke="#ddd"/>')
    out.append(f'<text x="{M-6}" y="{py(10**e)+4}" text-anchor="end">1e{e} s</text>')
for R in sorted(set(xs)):
    out.append(f'<line x1="{px(R)}" x2="{px(R)}" y1="{M}" y2="{H-M}" stroke="#eee"/>')
    out.append(f'<text x="{px(R)}" y="{H-M+16}" text-anchor="middle">{R}</text>')
for k, (method, pts) in enumerate(sorted(series.items())):
    pts.sort()
    lx = [math.log(p[0]) for p in pts]; ly = [math.log(p[1]) for p in pts]
    n = len(lx); mx = sum(lx) / n; my = sum(ly) / n
    slope = sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / sum((a - mx) ** 2 for a in lx)
    c = colours.get(method, "black")
    out.append('<polyline fill="none" stroke="%s" stroke-width="2" points="%s"/>' % (c, " ".join(f"{px(p[0])},{py(p[1])}" for p in pts)))
    for p in pts:
        out.append(f'<circle cx="{px(p[0])}" cy="{py(p[1])}" r="3" fill="{c}"/>')
    out.append(f'<text x="{M+10}" y="{M+16*k+10}" fill="{c}">{method}: time ~ R^{slope:.2f}, steps {pts[0][2]}..{pts[-1][2]}</text>')
out.append('</svg>')
open(sys.argv[3], "w").write("\n".join(out))

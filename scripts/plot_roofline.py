#!/usr/bin/env python3
"""Roofline picture of `lblight bench --json` output: lattice updates per second against updates
per byte of memory traffic (the inverse of the bytes one update moves: 157 in float32 step by step,
157/k with k steps per pass), one point per run. Roofs, both measured in the same bench run: the copy
bandwidth (MLUPS = bandwidth x updates per byte) and the fastest run whose state sits in the cache
(the collision's own rate). Usage: plot_roofline.py bench.json out.svg [title]"""
import json, math, sys

bench = json.load(open(sys.argv[1]))
title = sys.argv[3] if len(sys.argv) > 3 else bench["backend"]["description"]
bw = bench["copy_bandwidth_gbs"] * 1e9
runs = bench["runs"]
cached = [r["updates_per_second_per_channel"] for r in runs if r["state_within_cache"]]
compute = max(cached) if cached else None
# every run a point; hollow where the state is within twice the cache (timed partly against it)
pts = [(1.0 / r["memory_bytes_per_update"], r["updates_per_second_per_channel"], r) for r in runs]
W, H, M = 680, 440, 70
x0, x1 = math.log10(1 / 400), math.log10(1 / 8)
ys = [p[1] for p in pts] + ([compute] if compute else []) + [bw / 400, bw / 8]
y0, y1 = math.floor(math.log10(min(ys))), math.ceil(math.log10(max(ys)))
px = lambda x: M + (math.log10(x) - x0) / (x1 - x0) * (W - 2 * M)
py = lambda y: H - M - (math.log10(y) - y0) / (y1 - y0) * (H - 2 * M)
out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
       f'<rect width="{W}" height="{H}" fill="white"/>',
       f'<text x="{W/2}" y="20" text-anchor="middle">{title}</text>']
for e in range(y0, y1 + 1):
    out.append(f'<line x1="{M}" x2="{W-M}" y1="{py(10**e)}" y2="{py(10**e)}" stroke="#ddd"/>')
    out.append(f'<text x="{M-6}" y="{py(10**e)+4}" text-anchor="end">{10**e/1e6:g} M</text>')
for b in (400, 200, 157, 80, 40, 20, 10):
    out.append(f'<line x1="{px(1/b)}" x2="{px(1/b)}" y1="{M}" y2="{H-M}" stroke="#eee"/>')
    out.append(f'<text x="{px(1/b)}" y="{H-M+16}" text-anchor="middle">1/{b}</text>')
out.append(f'<text x="{W/2}" y="{H-M+34}" text-anchor="middle">updates per byte of memory traffic (1 / bytes moved per update)</text>')
out.append(f'<text x="16" y="{H/2}" transform="rotate(-90 16 {H/2})" text-anchor="middle">lattice updates per second per channel</text>')
# memory roof: updates/s = bandwidth x updates per byte, up to the compute roof
xa, xb = 10 ** x0, 10 ** x1
if compute:
    xb = min(xb, compute / bw)
out.append(f'<line x1="{px(xa)}" y1="{py(bw*xa)}" x2="{px(xb)}" y2="{py(bw*xb)}" stroke="#555" stroke-width="2"/>')
out.append(f'<text x="{px(xa)+4}" y="{py(bw*xa)-6}" fill="#555">copy bandwidth {bw/1e9:.1f} GB/s</text>')
if compute:
    out.append(f'<line x1="{px(xb)}" y1="{py(compute)}" x2="{px(10**x1)}" y2="{py(compute)}" stroke="#555" stroke-width="2" stroke-dasharray="6 3"/>')
    out.append(f'<text x="{px(10**x1)-4}" y="{py(compute)-6}" text-anchor="end" fill="#555">in-cache rate {compute/1e6:.0f} M/s</text>')
colours = {"float32": "#1f77b4", "float64": "#d62728", "float16": "#2ca02c"}
for k, (x, y, r) in enumerate(pts):
    c = colours.get(r["precision"], "black")
    label = ("(c) " if r["state_within_cache"] else "") + f'{r["lattice"][0]}^3 {r["precision"]}, {r["steps_per_pass"]} step{"s" if r["steps_per_pass"] > 1 else ""}/pass' + (", in place" if r.get("state") == "in-place" else "")
    fill = "white" if r["state_within_cache"] else c
    out.append(f'<circle cx="{px(x)}" cy="{py(y)}" r="5" fill="{fill}" stroke="{c}" stroke-width="2"/>')
    out.append(f'<text x="{px(x)+8}" y="{py(y)+4+13*(k%4)-20}" fill="{c}">{label}: {y/1e6:.0f} M</text>')
out.append('</svg>')
open(sys.argv[2], "w").write("\n".join(out))

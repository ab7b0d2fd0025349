#!/usr/bin/env python3
"""The add-on's relighting weights (tools/blender/lblight_blender/relight.py, plain Python) against
`lblight sun-weights`: the 32 faces and the weights for suns all over the sphere, with ambient and
sky. Runs without Blender."""
import json
import os
import subprocess
import sys

lblight = sys.argv[1]
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "blender",
                                "lblight_blender"))
import relight  # noqa: E402

failures = []
faces = json.loads(subprocess.run([lblight, "sun-weights", "--faces", "--json"], check=True, capture_output=True,
                                  text=True).stdout)
theirs = sorted(tuple(sorted(f["grids"])) for f in faces)
mine = sorted(tuple(sorted(relight.grid_name(j) for j in f)) for f in relight.FACES)
if theirs != mine:
    failures.append("the 32 faces differ from lblight's")
for f in faces:
    for g, d in zip(f["grids"], f["directions"]):
        if tuple(d) != relight.DIRECTIONS[int(g[1:])]:
            failures.append(f"{g} is {d} in lblight, {relight.DIRECTIONS[int(g[1:])]} in the add-on")
suns = [(e, a) for e in (-90, -45, -10, 0, 10, 35.26, 45, 60, 89, 90) for a in (0, 30, 45, 90, 137, 180, 225, 300)]
for e, a in suns:
    out = json.loads(subprocess.run([lblight, "sun-weights", "--elevation", str(e), "--azimuth", str(a), "--intensity",
                                     "2", "--ambient", "0.3", "--sky", "0.1", "--json"], check=True, capture_output=True,
                                    text=True).stdout)
    ref = {}
    for w in out["weights"]:
        ref[w["grid"]] = ref.get(w["grid"], 0.0) + w["weight"]
    got = relight.weights(relight.toward_sun_from_angles(e, a), 2.0, 0.3, 0.1)
    if set(ref) != set(got) or any(abs(ref[g] - got[g]) > 1e-9 for g in ref):
        failures.append(f"sun elevation {e} azimuth {a}: add-on {got}, lblight {ref}")
# Whatever sun stands at or above an object's horizon (and its sky and ambient), the add-on's material
# needs only B00 and the 13 level/downward directions (relight.HEMISPHERE); below it, no sun weights.
for e in (0, 0.5, 5, 10, 35.26, 45, 60, 89.9, 90):
    for a in range(0, 360, 5):
        got = relight.frame_weights(relight.toward_sun_from_angles(e, a), 1.0, 0.2, 0.1)
        if not set(got) <= set(relight.HEMISPHERE):
            failures.append(f"sun elevation {e} azimuth {a} needs {sorted(set(got) - set(relight.HEMISPHERE))}")
for e in (-0.5, -10, -45, -90):
    got = relight.frame_weights(relight.toward_sun_from_angles(e, 30), 1.0, 0.2, 0.1)
    if got != relight.weights((0, 0, 1), 0.0, 0.2, 0.1):
        failures.append(f"sun below the horizon (elevation {e}) still lights: {got}")
for line in failures:
    print("FAIL:", line)
print(f"{len(faces)} faces, {len(suns)} suns checked")
sys.exit(1 if failures else 0)

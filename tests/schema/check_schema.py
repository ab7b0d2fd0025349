#!/usr/bin/env python3
"""`lblight schema` against the shipped configs, with an independent validator (Debian's
python3-jsonschema, draft 2020-12): the schema is valid, equals docs/scene.schema.json, every
shipped config names it in "$schema" and passes it, and for a set of edits the schema and the
parser (`lblight validate`) agree on accept or reject. Exit 77 (skipped) without jsonschema."""
import copy
import glob
import json
import os
import subprocess
import sys
import tempfile

try:
    import jsonschema
except ImportError:
    print("SKIPPED: python3-jsonschema is not installed (scripts/setup-debian.sh installs it)")
    sys.exit(77)

lblight, root = sys.argv[1], sys.argv[2]
schema = json.loads(subprocess.run([lblight, "schema"], check=True, capture_output=True, text=True).stdout)
jsonschema.Draft202012Validator.check_schema(schema)
validator = jsonschema.Draft202012Validator(schema)
failures = []

shipped = os.path.join(root, "docs", "scene.schema.json")
with open(shipped) as f:
    if json.load(f) != schema:
        failures.append("docs/scene.schema.json is stale: regenerate it with `lblight schema -o docs/scene.schema.json`")

configs = sorted(glob.glob(os.path.join(root, "configs", "**", "*.json"), recursive=True))
assert len(configs) >= 10, configs
for path in configs:
    with open(path) as f:
        scene = json.load(f)
    named = os.path.normpath(os.path.join(os.path.dirname(path), scene.get("$schema", "")))
    if named != os.path.normpath(shipped):
        failures.append(f"{path}: \"$schema\" should name docs/scene.schema.json, found {scene.get('$schema')!r}")
    for e in validator.iter_errors(scene):
        failures.append(f"{path}: {e.json_path}: {e.message}")

# Edits of a small scene: the schema and the parser must give the same verdict.
base = {"version": 1, "models": [{"name": "m", "density": {"type": "procedural", "shape": "box", "resolution": 8},
                                  "material": "cloud"}],
        "lighting": {"sun_range": {"min_elevation": 0}}, "solver": {"tolerance": 1e-3}}


def edit(path, value):
    s = copy.deepcopy(base)
    node = s
    for k in path[:-1]:
        node = node[k]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return s


m = ["models", 0]
d = m + ["density"]
cases = [
    ("unchanged", base, True),
    ("unknown model field", edit(m + ["colour"], 1), False),
    ("resolution within range", edit(d + ["resolution"], 12), True),
    ("resolution over its maximum", edit(d + ["resolution"], 1025), False),
    ("resolution not an integer", edit(d + ["resolution"], 8.5), False),
    ("unknown shape", edit(d + ["shape"], "sphere"), False),
    ("unknown material preset", edit(m + ["material"], "glass"), False),
    ("material object", edit(m + ["material"], {"sigma_a": 0.1, "sigma_s": [0.2, 0.3, 0.4], "g": 0.5}), True),
    ("g out of range", edit(m + ["material"], {"sigma_a": 0.1, "sigma_s": 0.2, "g": 1.5}), False),
    ("model without a density", edit(d, KeyError), False),
    ("model name with a slash", edit(m + ["name"], "a/b"), False),
    ("static sun by angles", edit(["lighting"], {"mode": "static", "sun": {"elevation": 30, "azimuth": 10}}), True),
    ("static sun without azimuth", edit(["lighting"], {"mode": "static", "sun": {"elevation": 30}}), False),
    ("elevation out of range", edit(["lighting", "sun_range", "min_elevation"], -91), False),
    ("unknown solver method", edit(["solver", "method"], "jacobi"), False),
    ("bicgstab", edit(["solver", "method"], "bicgstab"), True),
    ("iterations paper", edit(["solver", "iterations"], "paper"), True),
    ("iterations zero", edit(["solver", "iterations"], 0), False),
    ("tolerance too big", edit(["solver", "tolerance"], 0.6), False),
    ("unknown calibration switch",
     edit(["solver"], {"model": "calibrated", "calibration": {"phase_moment": True, "warp": True}}), False),
    ("lbh object", edit(["output"], {"lbh": {"threshold": 0.02, "coefficients": "q8"}}), True),
    ("lbh coefficients unknown", edit(["output"], {"lbh": {"coefficients": "f16"}}), False),
    ("unknown top-level field", edit(["render"], {}), False),
    ("version 2", edit(["version"], 2), False),
]
with tempfile.TemporaryDirectory() as tmp:
    for name, scene, expected in cases:
        schema_ok = validator.is_valid(scene)
        path = os.path.join(tmp, "scene.json")
        with open(path, "w") as f:
            json.dump(scene, f)
        parser_ok = subprocess.run([lblight, "-q", "validate", path], capture_output=True).returncode == 0
        if schema_ok != expected or parser_ok != expected:
            failures.append(f"edit '{name}': expected {'accept' if expected else 'reject'}, "
                            f"schema {'accepts' if schema_ok else 'rejects'}, parser {'accepts' if parser_ok else 'rejects'}")

for line in failures:
    print("FAIL:", line)
print(f"{len(configs)} configs, {len(cases)} edits checked")
sys.exit(1 if failures else 0)

#!/usr/bin/env python3
"""Ratio and error of `lblight compress` against the threshold, as a Markdown table.

    scripts/compression_table.py LBLIGHT_EXE MODEL.vdb [REL_THRESHOLD ...]

Runs `lblight compress MODEL.vdb --threshold T --relative --json` for each threshold (default
0, 0.001, 0.003, 0.01, 0.02, 0.05) and prints, over all Vec3f grids of the file: total ratio
(float RGB bytes / stream bytes), RMS error (over all nodes, channels and solutions), the largest
max error, the same relative to each solution's max |value|, the share of fast-path blocks and the
total encode time, for the default coefficient storage (8-bit details when T > 0), then ratio,
RMS and max error with f32 coefficients (--coefficients f32, [Steele2009]'s scheme).
"""
import json
import math
import os
import subprocess
import sys
import tempfile


def run(exe, vdb, t, coefficients, out):
    r = subprocess.run([exe, "compress", vdb, "--threshold", str(t), "--relative", "--coefficients", coefficients,
                        "-o", out, "--json"], capture_output=True, text=True, check=True)
    j = json.loads(r.stdout)
    sols = j["solutions"]
    nodes = [s["float_rgb_bytes"] / 12 for s in sols]
    sq = sum(s["rms_error"] ** 2 * 3 * n for s, n in zip(sols, nodes))
    return dict(ratio=j["ratio"], rms=math.sqrt(sq / (3 * sum(nodes))),
                max=max(s["max_abs_error"] for s in sols),
                max_rel=max(s["max_abs_error"] / s["max_abs_value"] for s in sols if s["max_abs_value"] > 0),
                rms_rel=max(s["rms_error"] / s["max_abs_value"] for s in sols if s["max_abs_value"] > 0),
                fast=sum(s["fast_path_blocks"] for s in sols) / sum(s["blocks"] for s in sols),
                enc=sum(s["encode_seconds"] for s in sols))


def main(argv):
    if len(argv) < 3:
        print(__doc__)
        return 2
    exe, vdb = argv[1], argv[2]
    thresholds = [float(t) for t in argv[3:]] or [0.0, 0.001, 0.003, 0.01, 0.02, 0.05]
    print("| relative threshold | ratio | RMS error | max error | max error / max value | RMS / max value | "
          "fast-path blocks | encode s (all grids) | f32 coefficients: ratio | RMS error | max error |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "x.lbh")
        for t in thresholds:
            q = run(exe, vdb, t, "auto", out)  # 8-bit details when t > 0, lossless f32 at 0
            f = run(exe, vdb, t, "f32", out)
            print("| %g | %.2f:1 | %.3g | %.3g | %.2f%% | %.3f%% (worst grid) | %.1f%% | %.2f | %.2f:1 | %.3g | %.3g |" % (
                t, q["ratio"], q["rms"], q["max"], 100 * q["max_rel"], 100 * q["rms_rel"], 100 * q["fast"], q["enc"],
                f["ratio"], f["rms"], f["max"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

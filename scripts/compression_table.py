#!/usr/bin/env python3
"""Ratio and error of `lblight compress` against the threshold, as a Markdown table.

    scripts/compression_table.py LBLIGHT_EXE MODEL.vdb [REL_THRESHOLD ...]

Runs `lblight compress MODEL.vdb --threshold T --relative --json` for each threshold (default
0, 0.001, 0.003, 0.01, 0.02, 0.05) and prints, over all Vec3f grids of the file: total ratio
(float RGB bytes / stream bytes), RMS error (over all nodes, channels and solutions), the largest
max error, the same relative to each solution's max |value|, the share of fast-path blocks and the
total encode time.
"""
import json
import math
import os
import subprocess
import sys
import tempfile


def main(argv):
    if len(argv) < 3:
        print(__doc__)
        return 2
    exe, vdb = argv[1], argv[2]
    thresholds = [float(t) for t in argv[3:]] or [0.0, 0.001, 0.003, 0.01, 0.02, 0.05]
    print("| relative threshold | ratio | RMS error | max error | max error / max value | RMS / max value | "
          "fast-path blocks | encode s (all grids) |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for t in thresholds:
            out = os.path.join(tmp, "x.lbh")
            r = subprocess.run([exe, "compress", vdb, "--threshold", str(t), "--relative", "-o", out, "--json"],
                               capture_output=True, text=True, check=True)
            j = json.loads(r.stdout)
            sols = j["solutions"]
            nodes = [s["float_rgb_bytes"] / 12 for s in sols]
            sq = sum(s["rms_error"] ** 2 * 3 * n for s, n in zip(sols, nodes))
            rms = math.sqrt(sq / (3 * sum(nodes)))
            mx = max(s["max_abs_error"] for s in sols)
            mx_rel = max(s["max_abs_error"] / s["max_abs_value"] for s in sols if s["max_abs_value"] > 0)
            rms_rel = max(s["rms_error"] / s["max_abs_value"] for s in sols if s["max_abs_value"] > 0)
            fast = sum(s["fast_path_blocks"] for s in sols) / sum(s["blocks"] for s in sols)
            enc = sum(s["encode_seconds"] for s in sols)
            print("| %g | %.2f:1 | %.3g | %.3g | %.2f%% | %.3f%% (worst grid) | %.1f%% | %.2f |" % (
                t, j["ratio"], rms, mx, 100 * mx_rel, 100 * rms_rel, 100 * fast, enc))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

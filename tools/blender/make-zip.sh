#!/usr/bin/env bash
# Packs the Blender add-on for Edit > Preferences > Add-ons > Install: lblight_blender.zip (or $1).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
out="$(realpath -m "${1:-lblight_blender.zip}")"
rm -f "$out"
(cd "$here" && python3 -c "
import sys, zipfile, glob
with zipfile.ZipFile(sys.argv[1], 'w', zipfile.ZIP_DEFLATED) as z:
    for f in sorted(glob.glob('lblight_blender/*.py')):
        z.write(f)
" "$out")
echo "$out"

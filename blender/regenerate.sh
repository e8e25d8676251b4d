#!/usr/bin/env bash
# Regenerate every golden light curve in tests/golden with real Blender, from
# the committed scene files (blender/golden_scenes, written by make_scenes.py)
# and blender/render_golden.py. jaxppo is not needed. Blender runs as a Python
# module in its own environment, created here on first use:
#   python3.11 -m venv .bpy && .bpy/bin/pip install "numpy==1.26.*" "bpy==4.5.*"
# Usage: bash blender/regenerate.sh [NAME ...]   (default: every scene)
set -euo pipefail
cd "$(dirname "$0")/.."
BPY=${BPY_PYTHON:-.bpy/bin/python}
if [ ! -x "$BPY" ]; then
  python3.11 -m venv .bpy
  .bpy/bin/pip install -q "numpy==1.26.*" "bpy==4.5.*"
  BPY=.bpy/bin/python
fi
"$BPY" blender/make_scenes.py blender/golden_scenes
if [ $# -eq 0 ]; then
  set -- $(ls blender/golden_scenes | sed 's/\.json$//')
fi
for name in "$@"; do
  # one scene at a time: Cycles uses every core
  "$BPY" blender/render_golden.py "blender/golden_scenes/$name.json" "tests/golden/$name.txt" 2>&1 \
    | grep -v -e "^Fra:" -e "^Saved:" -e "^Time:" -e "^$" -e "Freeing memory" || true
done

#!/usr/bin/env bash
# Regenerate every golden light curve in tests/golden with real Blender.
# Needs: jaxppo installed in the current Python, and Blender as a module in
# its own environment (created here on first use; Python 3.11, numpy 1.26).
set -euo pipefail
cd "$(dirname "$0")/.."
BPY=${BPY_PYTHON:-.bpy/bin/python}
if [ ! -x "$BPY" ]; then
  python3.11 -m venv .bpy 2>/dev/null || python3 -m venv .bpy
  .bpy/bin/pip install -q "numpy==1.26.*" "bpy==4.5.*"
  BPY=.bpy/bin/python
fi
python blender/make_scenes.py blender/scenes
for scene in blender/scenes/*.json; do
  name=$(basename "$scene" .json)
  "$BPY" blender/render_golden.py "$scene" "tests/golden/$name.txt" | grep -v "^Fra:" || true
done

"""Blender's accuracy and speed against resolution and samples, on the
uniform-star golden scene (exact answer: the area of the union of the disks),
next to jaxppo's time for the same frames. Run in jaxppo's environment with
the Blender environment given by BPY_PYTHON (default .bpy/bin/python):

    python blender/accuracy_study.py [--resolutions 250 500 1000] [--samples 16 64 256]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from make_scenes import _scene, golden_systems  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--resolutions", type=int, nargs="+", default=[250, 500, 1000])
    ap.add_argument("--samples", type=int, nargs="+", default=[16, 64, 256])
    args = ap.parse_args()
    bpy_python = os.environ.get("BPY_PYTHON", str(HERE.parent / ".bpy" / "bin" / "python"))
    system, t, alpha, case, desc, extra = golden_systems()["uniform_overlap"]
    exact = np.asarray(system.flux(t, alpha, case, method="exact"))
    t0 = time.perf_counter()
    for _ in range(20):
        np.asarray(system.flux(t, alpha, case, method="exact"))
    jax_ms = (time.perf_counter() - t0) / 20 / t.size * 1e3
    work = Path(tempfile.mkdtemp(prefix="jaxppo_bstudy_"))
    print(f"{'N':>5s} {'samples':>7s} {'max err':>9s} {'rms err':>9s} {'s/frame (border)':>17s} {'s/frame (full)':>15s}")
    for n in args.resolutions:
        for s in args.samples:
            spec = _scene("study", desc, system, t, alpha, case, resolution=n, samples=s, params=extra)
            (work / "scene.json").write_text(json.dumps(spec))
            subprocess.run([bpy_python, str(HERE / "render_golden.py"), str(work / "scene.json"), str(work / "out.txt")],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            lines = (work / "out.txt").read_text().splitlines()
            meta = {ln[2:].split(":", 1)[0]: ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("# ")}
            data = np.array([[float(v) for v in ln.split()] for ln in lines if not ln.startswith("#")])
            err = data[:, 1] - exact
            full_s = float(meta.get("full_frame_seconds", "nan"))
            print(f"{n:5d} {s:7d} {np.max(np.abs(err)):9.2e} {np.sqrt(np.mean(err ** 2)):9.2e} "
                  f"{float(meta['seconds_per_rendered_frame']):17.3f} {full_s:15.2f}", flush=True)
    print(f"jaxppo exact, same frames: {jax_ms:.4f} ms per frame (error vs the union area < 1e-15)")


if __name__ == "__main__":
    main()

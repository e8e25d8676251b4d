"""Blender's accuracy and speed against resolution and samples, on the
uniform-star golden scene (exact answer: the area of the union of the two
disks, which jaxppo's exact engine gives to ~1e-15). Run in jaxppo's
environment; Blender runs in its own (BPY_PYTHON, default .bpy/bin/python):

    python blender/accuracy_study.py [--resolutions 250 500 1000] [--samples 16 64]

Prints one row per setting as it finishes.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--resolutions", type=int, nargs="+", default=[250, 500, 1000])
    ap.add_argument("--samples", type=int, nargs="+", default=[16, 64])
    args = ap.parse_args()
    bpy_python = os.environ.get("BPY_PYTHON", str(HERE.parent / ".bpy" / "bin" / "python"))
    spec = json.loads((HERE / "golden_scenes" / "uniform_overlap.json").read_text())
    system = jp.System(jp.Star.uniform(), [jp.Planet(**{k: p[k] for k in ("period", "t0", "a", "inc", "radius")})
                                           for p in spec["planets"]], tilted=spec["tilted"])
    t = np.asarray(spec["times"])
    exact = np.asarray(system.flux(t, spec["alpha"], spec["case"], method="exact"))
    work = Path(tempfile.mkdtemp(prefix="jaxppo_bstudy_"))
    print(f"{'N':>5s} {'samples':>7s} {'max err':>9s} {'rms err':>9s} {'s/frame (border)':>17s} {'s/full frame':>13s}")
    for n in args.resolutions:
        for s in args.samples:
            (work / "scene.json").write_text(json.dumps(spec | {"resolution": n, "samples": s}))
            subprocess.run([bpy_python, str(HERE / "render_golden.py"), str(work / "scene.json"), str(work / "out.txt")],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            lines = (work / "out.txt").read_text().splitlines()
            meta = {ln[2:].split(":", 1)[0]: json.loads(ln.split(":", 1)[1]) for ln in lines if ln.startswith("# ")
                    and not ln.startswith("# columns")}
            data = np.array([[float(v) for v in ln.split()] for ln in lines if not ln.startswith("#")])
            err = data[:, 1] - exact
            per_frame = (meta["render_seconds"] - meta["full_frame_seconds"]) / max(meta["frames_rendered"], 1)
            print(f"{n:5d} {s:7d} {np.max(np.abs(err)):9.2e} {np.sqrt(np.mean(err ** 2)):9.2e} "
                  f"{per_frame:17.3f} {meta['full_frame_seconds']:13.2f}", flush=True)


if __name__ == "__main__":
    main()

"""Write the Blender scene files for the golden light curves from jaxppo's own
System objects (run in jaxppo's environment):

    python blender/make_scenes.py blender/scenes
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402

RESOLUTION = 1000
SAMPLES = 64
MU = np.linspace(0.0, 1.0, 4097)


def _scene(name, description, system, t, alpha, case, resolution=RESOLUTION, samples=SAMPLES, params=None):
    x, y, r = (np.asarray(v) for v in system.positions(t, alpha, case))
    z = np.stack([np.asarray(pl.position(t)[2]) for pl in system.planets], -1)
    frames = [{"time": float(ti), "disks": [[float(a), float(b), float(c), float(d)] for a, b, c, d in zip(xi, yi, zi, ri)]}
              for ti, xi, yi, zi, ri in zip(t, x, y, z, r)]
    inten = np.asarray(system.star.intensity(MU))
    star_desc = repr(system.star)
    planets = [{k: float(getattr(pl, k)) for k in ("period", "t0", "a", "inc", "radius")} | {"name": pl.name} for pl in system.planets]
    return {
        "name": name, "description": description, "resolution": resolution, "samples": samples, "seed": 0,
        "star": {"mu": MU.tolist(), "intensity": (inten / inten[-1]).tolist()},
        "frames": frames,
        "params": (params or {}) | {"star": star_desc, "planets": planets, "tilted": system.tilted, "alpha": alpha, "case": case},
    }


def golden_systems():
    """name -> (System, times, alpha, case, description, extra params): the
    scenes of the goldens. The regression tests rebuild the same systems and
    compare jaxppo's light curves with Blender's."""
    out = {}
    # 1. uniform star, two overlapping planets: the exact answer is the area of the union
    sysu = jp.System(jp.Star.uniform(), [
        jp.Planet(period=3.0, t0=0.0, a=8.0, inc=88.0, radius=0.1, name="b"),
        jp.Planet(period=7.0, t0=0.004, a=14.0, inc=89.2, radius=0.07, name="c"),
    ])
    out["uniform_overlap"] = (sysu, np.linspace(-0.075, 0.075, 61), 0.0, "same",
                              "uniform star; planets b (p=0.1) and c (p=0.07) overlap each other on the disk", {})
    # 2. quadratic single transit
    sysq = jp.System(jp.Star.quadratic(0.4, 0.26), [jp.Planet(period=3.0, t0=0.0, a=8.0, inc=87.0, radius=0.1, name="b")])
    out["quadratic_single"] = (sysq, np.linspace(-0.08, 0.08, 61), 0.0, "same",
                               "quadratic limb darkening u1=0.4, u2=0.26; single transit p=0.1, b=0.42", {})
    # 3. Kepler-20 b + c, double transit 3 (BKJD 844.13), alpha = 90 deg: b passes over c, both cases
    k20 = jp.kepler20_system()
    for case in ("same", "opposite"):
        out[f"kepler20_ppo_{case}"] = (
            k20, np.arange(844.13, 844.175, 1.0 / 1440.0), 90.0, case,
            f"Kepler-20 b + c (paper Table 3), PHOENIX-based star (P100), double transit at BKJD 844.13, alpha = 90 deg, case {case}: b passes over c",
            {})
    # 4. large planets (Kepler-89-like d and e sizes) with a PPO, on a tabulated PHOENIX-like profile
    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 78))[:-1]]))
    mu[-1] = 1.0
    table = np.asarray(jp.claret_power2(5700, 4.5).intensity(mu))
    sys89 = jp.System(jp.Star.tabulated(mu, table), [
        jp.Planet(period=22.34, t0=0.0, a=31.0, inc=89.5, radius=0.055, name="d"),
        jp.Planet(period=54.32, t0=0.01, a=56.0, inc=89.75, radius=0.068, name="e"),
    ])
    out["kepler89_like_phoenix"] = (
        sys89, np.linspace(-0.2, 0.2, 81), -1.13, "same",
        "Kepler-89-like large planets d (p=0.055) and e (p=0.068) with a PPO near mid-transit, alpha = -1.13 deg; tabulated PHOENIX-like profile (78 mu points, power-2 PHOENIX-COND 5700 K)",
        {"table_mu": mu.tolist(), "table_intensity": table.tolist()})
    return out


def scenes():
    return [_scene(name, desc, system, t, alpha, case, params=extra)
            for name, (system, t, alpha, case, desc, extra) in golden_systems().items()]


def main(folder):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for sc in scenes():
        (folder / f"{sc['name']}.json").write_text(json.dumps(sc))
        print(f"wrote {folder / (sc['name'] + '.json')}: {len(sc['frames'])} frames")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "blender/scenes")

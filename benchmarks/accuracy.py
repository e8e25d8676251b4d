"""Accuracy table of the exact engine and of "auto" (its cheaper rules where
they converge): max |flux - reference| per class of configuration, float64
and float32, against the independent radial reference
of tests/helpers.py (adaptive Gauss-Kronrod, split at every kink).

    python benchmarks/accuracy.py
    python benchmarks/accuracy.py lightcurve   # float32 end to end (x64 off)

``lightcurve``: the Kepler-20 model light curve (quadratic law, 1-minute
cadence over the paper's seven double transits, planet b tilted by 87-99.5
deg in case "same", which gives planet-planet occultations on the star)
computed once with JAX's x64 on and once with it off (each in a fresh
process), and the difference reported for all frames and for the frames
with a PPO.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import jaxppo as jp  # noqa: E402
import jaxppo.model._plan  # noqa: E402
from helpers import (  # noqa: E402
    KEPLER20_P100,
    adversarial_pairs,
    adversarial_single,
    numpy_intensity,
    random_configs,
    reference_deficit,
    reference_total,
)

warnings.filterwarnings("ignore")
# "auto" sends calls with few crossing pairs to the union integral (cheaper to
# compile); the "auto" column is measured with its lens path on every call.
jaxppo.model._plan.LENS_MIN_PAIRS = 0


def main() -> None:
    rng = np.random.default_rng(2024)
    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 78))[:-1]]))
    mu[-1] = 1.0
    stars = {
        "quadratic": jp.Star.quadratic(0.495, 0.154),
        "nonlinear P100": jp.Star.nonlinear(*KEPLER20_P100),
        "power-2": jp.Star.power2(0.7178, 0.7764),
        "tabulated (sqrt-poly, 78 mu)": jp.Star.tabulated(mu, np.asarray(jp.Star.power2(0.7178, 0.7764).intensity(mu))),
    }
    classes = {
        "single, b in {0,p,1-p,1,1+p} +-1e-12": adversarial_single(),
        "pairs/triples: tangent, nested, concentric, identical, limb": adversarial_pairs(),
        "random overlapping pairs": random_configs(rng, 40, 2),
        "random overlapping triples": random_configs(rng, 20, 3),
    }
    print(f"{'star':30s} {'configurations':60s} {'n':>4s} {'float64':>9s} {'float32':>9s} {'auto f64':>9s}")
    for sname, star in stars.items():
        inten = numpy_intensity(star)  # numpy profile from the coefficients (fast, independent)
        ir = lambda r, inten=inten: float(inten(np.sqrt(max(1 - r * r, 0.0))))  # noqa: E731
        f0 = reference_total(ir)
        star32 = jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, star)
        for cname, cfgs in classes.items():
            e64 = e32 = ea = 0.0
            for x, y, p in cfgs:
                ref = 1 - reference_deficit(ir, x, y, p) / f0
                v64 = float(jp.occultation_flux(star, np.array(x), np.array(y), np.array(p), method="exact"))
                v32 = float(jp.occultation_flux(star32, np.array(x, np.float32), np.array(y, np.float32), np.array(p, np.float32), method="exact"))
                va = float(jp.occultation_flux(star, np.array(x), np.array(y), np.array(p)))
                e64, e32, ea = max(e64, abs(v64 - ref)), max(e32, abs(v32 - ref)), max(ea, abs(va - ref))
            print(f"{sname:30s} {cname:60s} {len(cfgs):4d} {e64:9.1e} {e32:9.1e} {ea:9.1e}")


_LC = """
import json, sys, warnings
import numpy as np
import jax
jax.config.update("jax_enable_x64", sys.argv[1] == "64")
warnings.simplefilter("ignore")
import jaxppo as jp
from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits
system = kepler20_system(jp.Star.quadratic(0.495, 0.154))
t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in paper_multi_transits(system)])
alphas = np.arange(87.0, 100.0, 0.5)
flux = np.stack([np.asarray(system.flux(t, alpha=float(a), case="same"), float) for a in alphas])
json.dump(flux.tolist(), sys.stdout)
"""


def lightcurve() -> None:
    import json
    import subprocess

    from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits

    runs = {}
    for bits in ("64", "32"):
        out = subprocess.run([sys.executable, "-c", _LC, bits], capture_output=True, text=True, check=True)
        runs[bits] = np.array(json.loads(out.stdout))
    system = kepler20_system()
    t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in paper_multi_transits(system)])
    alphas = np.arange(87.0, 100.0, 0.5)
    x, y, r = (np.asarray(v) for v in system.positions(t[None], alphas[:, None], "same", xp=np))
    on = (r > 0) & (np.hypot(x, y) - r < 1)
    ppo = on.all(-1) & (np.hypot(x[..., 0] - x[..., 1], y[..., 0] - y[..., 1]) < r.sum(-1))
    err = np.abs(runs["64"] - runs["32"]) * 1e6
    transit = runs["64"] < 1
    print(f"Kepler-20, {alphas.size} tilts x {t.size} times; float32 (x64 off) - float64 [ppm]")
    print(f"  in transit ({transit.sum()} frames): max {err[transit].max():.1f}, median {np.median(err[transit]):.2f}")
    print(f"  with a PPO on the star ({ppo.sum()} frames): max {err[ppo].max():.1f}, median {np.median(err[ppo]):.2f}")
    # the kernel's share: float64 positions rounded to float32, flux in float32
    star = jp.Star.quadratic(0.495, 0.154)
    star32 = jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, star)
    f64 = np.asarray(jp.occultation_flux(star, x[ppo], y[ppo], r[ppo], method="exact"))
    f32 = np.asarray(jp.occultation_flux(star32, *(v[ppo].astype(np.float32) for v in (x, y, r)), method="exact"), float)
    print(f"  of which the flux kernel (float32 positions, PPO frames): max {np.abs(f32 - f64).max() * 1e6:.2f}")


if __name__ == "__main__":
    if sys.argv[1:] == ["lightcurve"]:
        lightcurve()
    else:
        main()

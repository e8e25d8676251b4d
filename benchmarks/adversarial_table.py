"""Adversarial accuracy table (issue 16): worst |flux - reference| per class
of degenerate scene, law and dtype, for "exact" and "auto", against the
independent radial reference of tests/helpers.py, and the worst gradient
error where the flux is smooth (one-sided finite differences agree to 1e-6).

    python benchmarks/adversarial_table.py [scenes per class, default 16]

The same generators run, with fewer scenes, in tests/core/test_adversarial.py.
float32 columns use the scenes float32 can carry (radii 1e-3 to 100; see
``float32_representable``), the reference computed for the rounded inputs.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
import jaxppo as jp  # noqa: E402
import jaxppo.model._plan  # noqa: E402
from helpers import adversarial_classes, pad_scenes  # noqa: E402
from test_adversarial import STARS, _as32, _fd_step, _reference, float32_representable  # noqa: E402

warnings.filterwarnings("ignore")
# the "auto" column with its lens path on every call (see benchmarks/accuracy.py)
jaxppo.model._plan.LENS_MIN_PAIRS = 0


def _grad_error(star, x, y, r):
    """Worst |grad - central difference| per scene over x, y, r of every
    disk, where the one-sided differences agree to 1e-6 (smooth)."""
    x, y, r = (jnp.asarray(v) for v in (x, y, r))
    flux = jax.jit(lambda x, y, r: jp.occultation_flux(star, x, y, r, method="exact"))
    grads = jax.jit(jax.grad(lambda x, y, r: jnp.sum(flux(x, y, r)), argnums=(0, 1, 2)))(x, y, r)
    h = _fd_step(np.asarray(r))
    f0 = np.asarray(flux(x, y, r))
    worst = np.zeros(x.shape[0])
    finite = np.ones(x.shape[0], bool)
    for arg, g in enumerate(grads):
        g = np.asarray(g)
        finite &= np.all(np.isfinite(g), axis=1)
        for k in range(x.shape[1]):
            args = [x, y, r]
            step = jnp.zeros_like(x).at[:, k].set(jnp.asarray(h))
            base = args[arg]
            args[arg] = base + step
            fp, hp = np.asarray(flux(*args)), np.asarray(args[arg] - base)[:, k]
            args[arg] = base - step
            fm, hm = np.asarray(flux(*args)), np.asarray(base - args[arg])[:, k]
            plus, minus = (fp - f0) / hp, (f0 - fm) / hm
            smooth = (np.abs(plus - minus) < 1e-6) & (np.asarray(r)[:, k] > 0)
            worst = np.maximum(worst, np.where(smooth, np.abs(g[:, k] - 0.5 * (plus + minus)), 0.0))
    return worst, finite


def main(n: int) -> None:
    t0 = time.time()
    classes = adversarial_classes(np.random.default_rng(2026), n)
    print(f"{n} scenes per generator call, seed 2026; errors are max |flux - reference| [F0]\n")
    head = f"{'class':36s} {'law':10s} {'n':>4s} {'exact64':>8s} {'auto64':>8s} {'n32':>4s} {'exact32':>8s} {'auto32':>8s} {'grad64':>8s}"
    print(head)
    print("-" * len(head))
    overall = {}
    for cname, cfgs in classes.items():
        x, y, r = pad_scenes(cfgs)
        keep = float32_representable(cfgs)
        cfgs32 = [tuple(list(np.asarray(v, np.float32).astype(float)) for v in c) for c, k in zip(cfgs, keep) if k]
        for law, star in STARS.items():
            ref = _reference(star, cfgs)
            row = [np.max(np.abs(np.asarray(jp.occultation_flux(star, x, y, r, method=m)) - ref)) for m in ("exact", "auto")]
            if keep.any():
                ref32 = _reference(star, cfgs32)
                x32, y32, r32 = (v[keep].astype(np.float32) for v in (x, y, r))
                row += [
                    np.max(np.abs(np.asarray(jp.occultation_flux(_as32(star), x32, y32, r32, method=m), float) - ref32))
                    for m in ("exact", "auto")
                ]
            else:
                row += [np.nan, np.nan]
            gerr, finite = _grad_error(star, x, y, r)
            row.append(np.max(gerr) if finite.all() else np.inf)
            for key, v in zip(("exact64", "auto64", "exact32", "auto32", "grad64"), row):
                overall[key] = np.nanmax([overall.get(key, 0.0), v])
            cells = " ".join(f"{v:8.1e}" for v in row[:2]) + f" {int(keep.sum()):4d} " + " ".join(
                f"{'-':>8s}" if np.isnan(v) else f"{v:8.1e}" for v in row[2:])  # '-': no float32 scenes
            print(f"{cname:36s} {law:10s} {len(cfgs):4d} {cells}")
    print("-" * len(head))
    print("worst: " + ", ".join(f"{k} {v:.1e}" for k, v in overall.items()))
    print(f"({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 16)

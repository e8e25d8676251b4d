"""The paper's obliquity grid for Kepler-20 b and c: the seven double transits
at 1-minute cadence with 0.05 d of margin, alpha = 0..359 deg in 1-degree
steps, both hemisphere cases, PHOENIX-based star (non-linear P100), float64.

    python benchmarks/kepler20_grid.py [--check N]

Prints wall time (warm, best of 3, and cold including compilation), frames
per second, and the largest difference from the exact union integral on all
frames with a planet-planet overlap plus N random frames.
"""

from __future__ import annotations

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo.model._kepler20 import kepler20_system  # noqa: E402

PAPER_MIDS = (334.02, 670.45, 844.13, 1017.82, 1180.56, 1354.25, 1527.93)


def grid_times(system):
    events = jp.multi_transits(system, 300.0, 1600.0)
    events = [min(events, key=lambda e: abs(e.mid - m)) for m in PAPER_MIDS]
    return np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1.0 / 1440.0) for e in events])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", type=int, default=20000)
    args = ap.parse_args()
    system = kepler20_system()
    t = grid_times(system)
    alpha = np.arange(0.0, 360.0, 1.0)
    t0 = time.perf_counter()
    flux, stats = jp.sweep(system, t, alpha, return_stats=True)
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(3):
        t0 = time.perf_counter()
        jp.sweep(system, t, alpha)
        warm.append(time.perf_counter() - t0)
    n = flux.size
    print(f"grid: 2 cases x {alpha.size} alphas x {t.size} times = {n} frames "
          f"({stats.union} with a planet-planet overlap)")
    print(f"wall time: {min(warm):.3f} s warm (best of 3), {cold:.2f} s cold incl. compilation")
    print(f"frames per second: {n / min(warm):,.0f}  (paper: 2.42 frames/s on two Titan Xp GPUs; "
          f"speed-up {n / min(warm) / 2.42:,.0f}x)")
    # accuracy against the exact union integral
    rng = np.random.default_rng(0)
    idx = [np.nonzero(flux[ci] != flux[ci, 0][None, :])  for ci in range(2)]
    worst = 0.0
    for ci, case in enumerate(("same", "opposite")):
        ai, ti = idx[ci]
        pick_a = np.concatenate([ai, rng.integers(0, alpha.size, args.check // 2)])
        pick_t = np.concatenate([ti, rng.integers(0, t.size, args.check // 2)])
        x, y, r = (np.asarray(v) for v in system.positions(t[pick_t], alpha[pick_a], case))
        exact = np.asarray(jp.occultation_flux(system.star, x, y, r, method="exact"))
        worst = max(worst, float(np.max(np.abs(exact - flux[ci, pick_a, pick_t]))))
    print(f"max |auto - exact| over all PPO frames + {args.check} random frames: {worst:.1e}")


if __name__ == "__main__":
    main()

"""Microseconds per frame of the exact engine, float64, 1e5 frames in one
batch, next to batman (single disks) and gefera (pairs) measured in the same
run when they are installed. "auto" is timed twice: on concrete arrays (the
host plan) and inside ``jax.jit`` (the traced plan, what a user's jitted
model runs); the jitted rows exclude compilation, which is printed apart.

    python benchmarks/bench_occult.py [--frames 100000] [--stars tabulated]
"""

from __future__ import annotations

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo.model._terms import exact_frames, separate_frames  # noqa: E402


def best_of(fn, repeat=5):
    fn()  # compile / warm up
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=100_000)
    ap.add_argument("--stars", default="quadratic,nonlinear,tabulated", help="comma-separated subset")
    args = ap.parse_args()
    n = args.frames
    rng = np.random.default_rng(0)
    # single disks crossing the star (impact parameters 0..1.1), p = 0.01..0.1
    d = rng.uniform(0, 1.1, n)
    p = rng.uniform(0.01, 0.1, n)
    # overlapping pairs anywhere on the star
    x1, y1 = rng.uniform(-0.9, 0.9, n), rng.uniform(-0.4, 0.4, n)
    r1, r2 = rng.uniform(0.01, 0.1, n), rng.uniform(0.01, 0.1, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    sep = rng.uniform(np.abs(r1 - r2) + 1e-3, r1 + r2)
    x2, y2 = x1 + sep * np.cos(ang), y1 + sep * np.sin(ang)

    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 78))[:-1]]))
    mu[-1] = 1.0
    phoenix_like = jp.Star.tabulated(mu, np.asarray(jp.kepler20_star().intensity(mu)))
    stars = {
        "quadratic": jp.Star.quadratic(0.4, 0.26),
        "nonlinear (PHOENIX P100)": jp.kepler20_star(),
        "tabulated PHOENIX-like, 78 mu (sqrt-poly)": phoenix_like,
    }
    stars = {name: star for name, star in stars.items() if name.split()[0] in args.stars.split(",")}
    print(f"{n} frames, float64, {jax.devices()[0].platform}, microseconds per frame (best of 5)")
    print(f"{'case':50s} {'us/frame':>9s}")
    xs, ys, rs = jnp.asarray(d[:, None]), jnp.zeros((n, 1)), jnp.asarray(p[:, None])
    X = jnp.asarray(np.stack([x1, x2], 1))
    Y = jnp.asarray(np.stack([y1, y2], 1))
    R = jnp.asarray(np.stack([r1, r2], 1))
    for name, star in stars.items():
        t = best_of(lambda: np.asarray(jp.occultation_flux(star, xs, ys, rs)))
        print(f"{'single disk (auto), ' + name:50s} {t / n * 1e6:9.3f}")
        jitted = jax.jit(lambda x, y, r, star=star: jp.occultation_flux(star, x, y, r))
        t0 = time.perf_counter()
        jitted(xs, ys, rs).block_until_ready()
        cold = time.perf_counter() - t0
        t = best_of(lambda: jitted(xs, ys, rs).block_until_ready())
        print(f"{'single disk (auto under jax.jit), ' + name:50s} {t / n * 1e6:9.3f}   (compile + first call {cold:.1f} s)")
        t = best_of(lambda: separate_frames(star, xs, ys, rs, 24).block_until_ready())
        print(f"{'single disk (general rule only), ' + name:50s} {t / n * 1e6:9.3f}")
        t = best_of(lambda: np.asarray(jp.occultation_flux(star, X, Y, R)))
        print(f"{'overlapping pair (auto), ' + name:50s} {t / n * 1e6:9.3f}")
        t0 = time.perf_counter()
        jitted(X, Y, R).block_until_ready()
        cold = time.perf_counter() - t0
        t = best_of(lambda: jitted(X, Y, R).block_until_ready())
        print(f"{'overlapping pair (auto under jax.jit), ' + name:50s} {t / n * 1e6:9.3f}   (compile + first call {cold:.1f} s)")
        t = best_of(lambda: exact_frames(star, X, Y, R, 24).block_until_ready())
        print(f"{'overlapping pair (general union only), ' + name:50s} {t / n * 1e6:9.3f}")
    # which path "auto" takes for the pair frames
    from jaxppo.model._terms import lens_rho_jit
    from jaxppo.core.occult import LENS_RULES

    rho = np.asarray(lens_rho_jit(X, Y, R))
    tiers = [f"{nodes} nodes {np.mean(np.select([rho >= m for _, m in LENS_RULES], list(range(len(LENS_RULES))), -1) == t):.1%}"
             for t, (nodes, _) in enumerate(LENS_RULES)]
    print(f"pair frames by path: lens with {', '.join(tiers)}; union integral {np.mean(rho < LENS_RULES[-1][1]):.1%}")
    try:
        from batman import _quadratic_ld

        t = best_of(lambda: _quadratic_ld._quadratic_ld(d, 0.05, 0.4, 0.26, 1))
        print(f"{'batman single disk, quadratic (1 thread)':50s} {t / n * 1e6:9.3f}")
    except ImportError:
        print("batman not installed")
    try:
        from gefera.phot import flux_ng

        bp = np.hypot(x1, y1)
        bpm = np.hypot(x2 - x1, y2 - y1)
        v = np.stack([-x1, -y1], 1)
        w = np.stack([x2 - x1, y2 - y1], 1)
        th = np.arccos(np.clip(np.sum(v * w, 1) / np.linalg.norm(v, axis=1) / np.linalg.norm(w, axis=1), -1, 1))
        c, s = np.cos(th), np.sin(th)
        t = best_of(lambda: flux_ng(0.4, 0.26, 0.05, 0.03, bp, bpm, c, s))
        print(f"{'gefera overlapping pair, quadratic':50s} {t / n * 1e6:9.3f}")
    except ImportError:
        print("gefera not installed")


if __name__ == "__main__":
    main()

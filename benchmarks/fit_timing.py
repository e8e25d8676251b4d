"""Fit and MCMC timings for Kepler-20 b + c over the seven double transits
(about 2900 one-minute points), float64, this machine:

* fit: jp.fit (Levenberg-Marquardt and its minimum check) of b and c (t0, P,
  a, i, p), cold (incl. compilation) and warm;
* NUTS: numpyro, --warmup + --samples (default 1000 + 1000), four free
  parameters;
* gradient: the cost of jax.grad of chi^2 relative to one forward evaluation.

    python benchmarks/fit_timing.py [--warmup 1000 --samples 1000] [--no-nuts]
    python benchmarks/fit_timing.py --once [--cache DIR]

--once: the fit alone, once (what a new process of a user costs: run it
twice with the same --cache DIR, jaxppo.compilation_cache's folder, for
the first and the second run).
"""

from __future__ import annotations

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo.inference._model import Model  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--warmup", type=int, default=1000)
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--no-nuts", action="store_true", help="fit and gradient timings only")
    ap.add_argument("--once", action="store_true", help="one fit, nothing else")
    ap.add_argument("--cache", default=None, help="JAX's persistent compilation cache folder (jp.compilation_cache)")
    args = ap.parse_args()
    if args.cache:
        jp.compilation_cache(args.cache)
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=7, noise=4e-4)
    b, c = truth.planets
    start = truth.replace(planets=(b.replace(t0=b.t0 + 0.002, radius=0.019, a=10.0, inc=87.9), c.replace(t0=c.t0 - 0.001, radius=0.028)))
    free = ("b.t0", "b.period", "b.a", "b.inc", "b.radius", "c.t0", "c.period", "c.a", "c.inc", "c.radius")
    print(f"{len(lc)} points, {len(free)} free parameters")
    t0 = time.perf_counter()
    res = jp.fit(start, lc, free=free)
    cold = time.perf_counter() - t0
    if args.once:
        print(f"fit: {cold:.2f} s; {res.message}, reduced chi2 {res.reduced_chi2:.3f}")
        return
    t0 = time.perf_counter()
    jp.fit(start, lc, free=free)
    warm = time.perf_counter() - t0
    print(f"fit: {cold:.2f} s cold (incl. compilation), {warm:.2f} s second call; {res.message}, reduced chi2 {res.reduced_chi2:.3f}")
    print(res.table())

    model = Model(truth, lc, free)
    theta = model.to_theta(truth)
    chi2 = jax.jit(lambda th: jnp.sum(model.residuals(th) ** 2))
    grad = jax.jit(jax.grad(lambda th: jnp.sum(model.residuals(th) ** 2)))
    chi2(theta).block_until_ready()
    grad(theta).block_until_ready()
    tf = min(_time(lambda: chi2(theta).block_until_ready()) for _ in range(5))
    tg = min(_time(lambda: grad(theta).block_until_ready()) for _ in range(5))
    print(f"chi2 forward {tf * 1e3:.2f} ms, gradient {tg * 1e3:.2f} ms: ratio {tg / tf:.2f}")

    if args.no_nuts:
        return
    t0 = time.perf_counter()
    post = jp.sample(truth, lc, free=("b.t0", "b.radius", "c.t0", "c.radius"), num_warmup=args.warmup,
                     num_samples=args.samples, seed=0, progress_bar=False)
    tn = time.perf_counter() - t0
    rh = max(d["r_hat"] for d in post.diagnostics.values())
    ne = min(d["n_eff"] for d in post.diagnostics.values())
    print(f"NUTS {args.warmup} + {args.samples}: {tn:.1f} s; max r_hat {rh:.3f}, min n_eff {ne:.0f}")


def _time(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()

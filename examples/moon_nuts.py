"""A planet with a moon, recovered by NUTS: a simulated 2-minute transit of
a planet (p = 0.09) with a moon (p = 0.04, a = 0.35 R* from the planet,
mass ratio 0.05) on a quadratic star, 200 ppm noise; a fit from a start
with the moon's phase, distance and size off, then NUTS over the planet's
time and radius and the moon's phase, distance and radius.

    python examples/moon_nuts.py [--warmup 300 --samples 300 --chains 2]

Prints the truth, the fit and the posterior (median and 16-84 % interval,
R-hat, bulk ESS) of each free parameter, and the time taken.
"""

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402

FREE = ("b.t0", "b.radius", "b.I.t0", "b.I.a", "b.I.radius")


def system_with_moon(t0=0.15, a=0.35, radius=0.04) -> jp.System:
    """The simulated system: the moon "I" of planet "b" (its phase t0, distance a and radius set)."""
    moon = jp.Moon(period=1.2, t0=t0, a=a, inc=88.0, radius=radius, mass_ratio=0.05, name="I")
    planet = jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.9, radius=0.09, moons=[moon], name="b")
    return jp.System(jp.Star.quadratic(0.4, 0.25), [planet])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warmup", type=int, default=300)
    ap.add_argument("--samples", type=int, default=300)
    ap.add_argument("--chains", type=int, default=2)
    args = ap.parse_args(argv)
    truth = system_with_moon()
    lc = jp.simulate(truth, np.arange(-0.35, 0.35, 2.0 / 1440.0), noise=2e-4, seed=3)
    start = system_with_moon(t0=0.1, a=0.3, radius=0.03)
    t0 = time.perf_counter()
    fit = jp.fit(start, lc, free=FREE)
    t_fit = time.perf_counter() - t0
    t0 = time.perf_counter()
    post = jp.sample(fit.system, lc, free=FREE, num_warmup=args.warmup, num_samples=args.samples,
                     num_chains=args.chains, progress_bar=False)
    t_nuts = time.perf_counter() - t0
    true = dict(zip(FREE, (0.0, 0.09, 0.15, 0.35, 0.04)))
    print(f"fit {t_fit:.0f} s (reduced chi^2 {fit.reduced_chi2:.3f}); NUTS {args.chains} x ({args.warmup} + "
          f"{args.samples}) in {t_nuts:.0f} s")
    print(f"{'parameter':12s} {'truth':>9s} {'fit':>20s} {'posterior median [16, 84 %]':>34s} {'R-hat':>6s} "
          f"{'ESS':>6s}")
    for k, name in enumerate(FREE):
        med, lo, hi = post.intervals[name]
        diag = post.diagnostics[name]
        print(f"{name:12s} {true[name]:9.4f} {fit.values[k]:10.4f} +- {fit.errors[k]:.4f} "
              f"{med:12.4f} [{lo:.4f}, {hi:.4f}] {diag['r_hat']:6.3f} {diag['ess_bulk']:6.0f}")


if __name__ == "__main__":
    main()

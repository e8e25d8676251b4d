"""Photodynamical fit of Kepler-51 b, c, d: planets moved by their mutual
gravity (jnkepler's N-body integrator), overlaps exact, fitted to the REAL
Kepler long-cadence photometry around 30 transits (BKJD 158.8-1575.2; the
author of these data left out the overlapping b + d transit near BKJD
1513.7, which the fitted model then predicts).

    pip install "jaxppo[nbody]"
    python examples/kepler51_photodynamics.py --out kepler51_photodynamics.png

The start: the osculating Jacobi elements at BKJD 155 of a fit of the
transit times (the bundled ``kep51_dt1.0_start155.00_end2950.00_pdict.csv``;
periods, e, omega, t0, masses), every inclination 89.7 deg, radius ratios
0.07, 0.06, 0.1, a 0.881 R_sun, 0.985 M_sun star (Libby-Roberts et al. 2020)
and a quadratic star q1 = q2 = 0.3. Free: the radius ratios,
inclinations, times of conjunction, periods and masses of the three
planets, the stellar radius and Kipping's q1, q2 (18 parameters). Prints
the fit, chi^2 / N, the transit times the fitted system predicts beside
the measured ones (those the starting elements were fitted to, Masuda 2014
and Libby-Roberts et al. 2020), and plots the predicted b + d double
transit with the exact model and the sum of single-planet deficits.
"""

import argparse
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402

DATA = Path(jp.__file__).parent / "data" / "kepler51"
LONG_CADENCE = 0.0204335982  # [d] Kepler long cadence (29.4 min)
NAMES = ("b", "c", "d")
FREE = tuple(f"{p}.{k}" for p in NAMES for k in ("radius", "inc", "t0", "period", "mass")) + (
    "star.radius", "star.q1", "star.q2")


def start_system() -> jp.System:
    """Kepler-51 as an N-body System at the start of the fit."""
    el = np.genfromtxt(DATA / "kep51_dt1.0_start155.00_end2950.00_pdict.csv", delimiter=",", names=True)
    star_mass = 0.985
    planets = [jp.Planet(period=el["period"][j], t0=el["tic"][j], a=None, inc=89.7, radius=(0.07, 0.06, 0.1)[j],
                         e=el["ecc"][j], omega=np.rad2deg(el["omega"][j]), mass=el["mass"][j] * star_mass,
                         name=NAMES[j]) for j in range(3)]
    u1, u2 = jp.kipping_u(0.3, 0.3)
    return jp.System(jp.Star.quadratic(float(u1), float(u2)), planets, orbits="nbody", epoch=155.0,
                     star_mass=star_mass, star_radius=0.881)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="kepler51_photodynamics.png")
    args = ap.parse_args(argv)
    d = np.genfromtxt(DATA / "kep51_lc_photodtest.csv", delimiter=",", names=True)
    lc = jp.LightCurve(d["time"], d["flux"], d["flux_err"], exposure=LONG_CADENCE)
    system = start_system()
    t0 = time.perf_counter()
    res = jp.fit(system, lc, free=FREE)
    print(f"fit: {time.perf_counter() - t0:.0f} s, {res.message}")
    print(f"chi^2 = {res.chi2:.1f} for {lc.time.size} points, {len(FREE)} free: chi^2 / N = "
          f"{res.chi2 / lc.time.size:.3f}, reduced {res.reduced_chi2:.3f}")
    for name, v, e in zip(res.names, res.values, res.errors):
        scale, unit = (332946.0, "M_earth") if name.endswith(".mass") else (1.0, "")
        print(f"  {name:12s} {v * scale:14.6f} +- {e * scale:.6f} {unit}")
    measured = np.genfromtxt(DATA / "kepler51_transit_times_jnkepler.csv", delimiter=",", names=True,
                             dtype=None, encoding="utf-8")
    for label, sysm in (("start", system), ("fit", res.system)):
        predicted = sysm.transit_times(155.0, 1600.0)
        text = []
        for p in NAMES:
            tc = np.asarray(predicted["tc"][predicted["planet"] == p], float)
            rows = measured[(measured["planet"] == p) & (measured["tc"] < 1600.0)]
            z = np.array([(tc[np.argmin(np.abs(tc - r["tc"]))] - r["tc"]) / r["tc_err"] for r in rows])
            text.append(f"{p} {np.sqrt(np.mean(z**2)):.2f} ({z.size})")
        print(f"  measured transit times, rms (model - measured) / error, {label}: " + ", ".join(text))
    # the model as the data see it: averaged over the 29.4-minute exposures (as in the fit's chi^2)
    t = np.linspace(1513.4, 1514.1, 400)
    t_sub, n_sub = jp.LightCurve(t, np.ones_like(t), np.ones_like(t), exposure=LONG_CADENCE).supersampled_times()
    x, y, r = res.system.positions(t_sub, xp=np)
    exact = np.asarray(jp.occultation_flux(res.system.star, x, y, r, method="exact")).reshape(-1, n_sub).mean(1)
    summed = 1.0 + sum(np.asarray(jp.occultation_flux(res.system.star, x[:, [j]], y[:, [j]], r[:, [j]])) - 1.0
                       for j in range(3)).reshape(-1, n_sub).mean(1)
    print(f"b + d double transit: the sum of single-planet deficits is off by up to "
          f"{1e6 * np.abs(summed - exact).max():.0f} ppm")
    fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True, height_ratios=(3, 1))
    ax[0].set_title("Kepler-51 b + d near BKJD 1513.7, predicted by the fit (29.4-min exposures)", fontsize=9)
    ax[0].plot(t, exact, "k", label="N-body, exact overlap")
    ax[0].plot(t, summed, "C3--", label="sum of single-planet deficits")
    ax[0].set_ylabel("relative flux")
    ax[0].legend(fontsize=8)
    ax[1].plot(t, 1e6 * (summed - exact), "C3")
    ax[1].set_ylabel("sum - exact [ppm]")
    ax[1].set_xlabel("BKJD")
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

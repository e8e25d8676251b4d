"""N-body sky positions (``jaxppo.model._nbody``; the orbits integrated by
jnkepler): the Keplerian limit against :meth:`jaxppo.System.positions`,
Kepler-51 against REBOUND, jit and gradients.

The REBOUND reference is stored, not run here (REBOUND is no dependency of
jaxppo's tests): ``tests/data/kepler51_rebound_transits.csv`` (every
mid-transit of Kepler-51 b, c, d from BKJD 155 to 1600, the Kepler
baseline) and ``tests/data/kepler51_rebound_positions.csv`` (astrocentric
positions [au] in REBOUND's frame at 170 times: random over the baseline,
10 before the epoch of the elements, and 60 off mid-transit), both from
REBOUND 5.2.2's IAS15 with the elements below, written by
``python benchmarks/nbody_vs_rebound.py --write-csv``.

Measured (jnkepler 0.2.9, default dt = P_b / 40 = 1.13 d): transit times
within 0.0004 min (0.03 s) of REBOUND's, positions within 3.6e-6 R*; the
Keplerian limit within 3.6e-6 R* over 600 d at masses 1e-10 M_sun (the
osculating periods are not the mean ones, a drift proportional to the
masses) and 3e-10 R* at 1e-14 M_sun.
"""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

if importlib.util.find_spec("jnkepler") is None:
    # CI installs the nbody extra and sets JAXPPO_REQUIRE_NBODY=1: there a
    # missing jnkepler fails instead of skipping these comparisons
    if os.environ.get("JAXPPO_REQUIRE_NBODY") == "1":
        raise ImportError("jnkepler is required here (JAXPPO_REQUIRE_NBODY=1): pip install 'jaxppo[nbody]'")
    pytest.skip("jnkepler is not installed (pip install 'jaxppo[nbody]')", allow_module_level=True)

import jaxppo as jp  # noqa: E402
from jaxppo.model._nbody import R_SUN_AU, nbody_positions, nbody_xyz, semi_major_axis  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "data"

# Kepler-51 b, c, d: osculating Jacobi elements at BKJD 155 from Masuda's jnkepler example
# (kep51_dt1.0_start155.00_end2950.00_pdict.csv; masses are planet / star mass ratios, star 1 M_sun)
K51_PERIOD = np.array([45.15410798392322, 85.31448324119035, 130.18413706111033])
K51_ECOSW = np.array([-0.017185959106750172, 0.018881511466098927, 0.011665980547369371])
K51_ESINW = np.array([-0.04069871999841418, -0.034823941422281166, -0.028107346169576518])
K51_TIC = np.array([159.11026537277118, 295.32101703450786, 212.0234348357531])
K51_MASS = np.array([9.914288803950785e-06, 1.2239239443515162e-05, 1.5982929660558063e-05])
K51 = dict(periods=K51_PERIOD, eccs=np.hypot(K51_ECOSW, K51_ESINW),
           omegas=np.rad2deg(np.arctan2(K51_ESINW, K51_ECOSW)), incs=np.full(3, 90.0), lnodes=np.zeros(3),
           tics=K51_TIC, masses=K51_MASS, star_mass=1.0, star_radius=0.881, epoch=155.0)
NAMES = ("b", "c", "d")


def _read(name):
    return np.genfromtxt(DATA / name, delimiter=",", names=True, dtype=None, encoding="utf-8")


def test_keplerian_limit_equals_system_positions():
    """Tiny masses: the N-body positions are System.positions of the same Keplerian planets (tilt alpha =
    Omega, t0 = tic, a from Kepler's third law), before and after the epoch; (i, Omega) -> (180 - i, -Omega)
    mirrors y."""
    period = np.array([7.3, 13.1, 31.7])
    ecc, omega = np.array([0.0, 0.1, 0.25]), np.array([90.0, 40.0, 250.0])
    inc, lnode = np.array([88.5, 89.2, 89.7]), np.array([0.0, 20.0, -35.0])
    tic, radii = np.array([100.2, 103.5, 111.0]), np.array([0.02, 0.03, 0.05])
    star_mass, star_radius, epoch = 0.9, 0.85, 95.0
    t = np.sort(np.concatenate([np.random.default_rng(1).uniform(epoch - 100, epoch + 500, 600), tic]))
    kw = dict(periods=period, eccs=ecc, omegas=omega, lnodes=lnode, tics=tic, radii=radii, star_mass=star_mass,
              star_radius=star_radius, epoch=epoch)
    a = np.asarray(semi_major_axis(period, star_mass, star_radius))
    planets = [jp.Planet(period=period[i], t0=tic[i], a=a[i], inc=inc[i], radius=radii[i], e=ecc[i], omega=omega[i],
                         name="bcd"[i]) for i in range(3)]
    ref = np.zeros((3, len(t), 3))
    for i in range(3):
        system = jp.System(jp.Star.quadratic(0.4, 0.2), planets, tilted=i)
        ref[:, :, i] = np.asarray(system.positions(t, alpha=lnode[i]))[:, :, i]
    for mass, tol in ((1e-10, 1e-5), (1e-14, 5e-9)):
        x, y, r = nbody_positions(t, incs=inc, masses=np.full(3, mass), **kw)
        err = np.hypot(np.asarray(x) - ref[0], np.asarray(y) - ref[1]).max()
        assert err < tol, f"masses {mass}: {err:.2e} R* from the Keplerian orbits"
        np.testing.assert_array_equal(np.asarray(r), ref[2])
    x2, y2, _ = nbody_positions(t, incs=180.0 - inc, masses=np.full(3, 1e-14), **{**kw, "lnodes": -lnode})
    np.testing.assert_allclose(np.asarray(x2), np.asarray(x), rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(y2), -np.asarray(y), rtol=0, atol=1e-9)


def _sky_transit_times(guess, planet, h=1e-3, iters=4):
    """Mid-transit (x.v = 0 on the sky) on nbody_xyz's positions: Newton steps with central
    differences of x^2 + y^2 (step h [d])."""
    t = np.asarray(guess, float)
    rows = np.arange(len(t))
    for _ in range(iters):
        x, y, _ = nbody_xyz(np.stack([t - h, t, t + h]), **K51)
        d2 = np.asarray(x**2 + y**2)[:, rows, planet]
        t = t - h * (d2[2] - d2[0]) / (2.0 * (d2[2] - 2.0 * d2[1] + d2[0]))
    return t


def test_kepler51_transit_times_match_rebound():
    """Every Kepler-51 transit over the Kepler baseline (60) within 0.005 min of REBOUND's IAS15 (measured:
    0.0004 min), from a linear-ephemeris guess up to hours off (the TTVs)."""
    ref = _read("kepler51_rebound_transits.csv")
    planet = np.array([NAMES.index(p) for p in ref["planet"]])
    guess = K51_TIC[planet] + ref["epoch"] * K51_PERIOD[planet]
    tc = _sky_transit_times(guess, planet)
    for j, name in enumerate(NAMES):
        err = 1440 * np.abs(tc - ref["tc"])[planet == j].max()
        assert err < 0.005, f"Kepler-51 {name}: {err:.4f} min from REBOUND"
    assert 1440 * np.abs(guess - ref["tc"]).max() > 30  # the guesses were far off: the TTVs are real


def test_kepler51_positions_match_rebound():
    """Positions at 170 times (random, before the epoch, off mid-transit) within 2e-5 R* of REBOUND's
    (measured: 3.6e-6 R*); r is the planet's radius exactly where REBOUND has it in front (z > 0)."""
    ref = _read("kepler51_rebound_positions.csv")
    t = ref["t"][::3]
    xyz = np.stack([ref["x"], ref["y"], ref["z"]], -1).reshape(len(t), 3, 3) / (K51["star_radius"] * R_SUN_AU)
    assert np.all(ref["planet"].reshape(len(t), 3) == np.array(NAMES))
    radii = np.array([0.07, 0.08, 0.09])
    x, y, r = nbody_positions(t, radii=radii, **K51)
    _, _, z = nbody_xyz(t, **K51)
    err = np.sqrt((np.asarray(x) + xyz[..., 0])**2 + (np.asarray(y) - xyz[..., 1])**2
                  + (np.asarray(z) - xyz[..., 2])**2)
    assert err.max() < 2e-5, f"{err.max():.2e} R* from REBOUND"
    assert (t < K51["epoch"]).sum() == 10 and err[t < K51["epoch"]].max() < 2e-5
    np.testing.assert_array_equal(np.asarray(r), np.where(xyz[..., 2] > 0, radii, 0.0))
    near = (np.abs(np.asarray(x)) < 1.5) & (xyz[..., 2] > 0)  # on or next to the disk, off mid-transit
    assert near.sum() >= 30 and np.all(np.abs(np.asarray(x)[near]) > 0.1)


def test_jit_and_derivative_finite_and_match_finite_differences():
    """Under jax.jit with traced times (t_range), masses and elements: the derivative of a loss on the
    positions along a direction that moves every mass and element (forward mode, jax.jvp) is finite and
    equals central differences along it.

    Reverse mode (jax.grad, what NUTS uses) gives the same numbers; its XLA compilation takes 20-35 s on a
    2-core CPU (as for jnkepler's own gradients), too long for this suite: benchmarks/nbody_vs_rebound.py
    runs jax.grad with respect to every mass and element and prints its agreement with jax.jacfwd."""
    t = _read("kepler51_rebound_positions.csv")["t"][::3]
    span = (float(t.min()), float(t.max()))
    names = ("masses", "periods", "eccs", "omegas", "incs", "lnodes", "tics")

    def loss(t, *values):
        # traced periods: dt given (the default's value, P_b / 40)
        x, y, _ = nbody_xyz(t, t_range=span, dt=float(np.min(K51_PERIOD)) / 40, **{**K51, **dict(zip(names, values))})
        return jnp.sum(x * jnp.sin(t)[:, None]) + jnp.sum(y)

    values = tuple(jnp.asarray(K51[n], float) for n in names)
    values = values[:4] + (jnp.array([89.9, 89.8, 90.1]), jnp.array([0.0, 1.0, -2.0])) + values[6:]
    # a step of each: 1 % of the masses, 1e-6 d, 1e-4, 1e-3 deg (omega, i, Omega), 1e-5 d
    steps = (0.01 * K51_MASS, 1e-6, 1e-4, 1e-3, 1e-3, 1e-3, 1e-5)
    direction = tuple(s * jnp.array([1.0, -0.7, 0.4]) for s in steps)
    _, deriv = jax.jit(lambda t, *v: jax.jvp(lambda *v: loss(t, *v), v, direction))(t, *values)
    assert np.isfinite(float(deriv)) and float(deriv) != 0.0
    up = loss(t, *(v + d for v, d in zip(values, direction)))
    down = loss(t, *(v - d for v, d in zip(values, direction)))
    fd = float(up - down) / 2
    assert abs(float(deriv) - fd) < 1e-4 * abs(fd), (float(deriv), fd)


def test_float64_setting_kept():
    """jnkepler turns float64 on when imported; jaxppo puts the user's setting back (a fresh process)."""
    code = ("import jax; jax.config.update('jax_enable_x64', False); "
            "from jaxppo.model._nbody import _jnkepler; _jnkepler(); print(jax.config.jax_enable_x64)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr


def test_bad_inputs():
    """Traced times need t_range; element arrays of different lengths and a step <= 0 are refused."""
    kw = {**K51, "radii": np.full(3, 0.05)}
    with pytest.raises(ValueError, match="t_range"):
        jax.jit(lambda t: nbody_positions(t, dt=1.0, **kw))(jnp.array([200.0]))
    with pytest.raises(ValueError, match="1D of one length"):
        nbody_positions([200.0], **{**kw, "tics": K51_TIC[:2]})
    with pytest.raises(ValueError, match="dt must be > 0"):
        nbody_positions([200.0], dt=0.0, **kw)
